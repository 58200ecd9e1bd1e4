#include <fvr/ui/study.h>

#include <fvr/core/xray/xray.h>

#include <QDir>
#include <QFileInfo>

#include <fvr/core/errors.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/io/volume_io.h>

namespace fvr::ui {

QString StudySource::displayName() const {
    switch (kind) {
    case Kind::Phantom: return QStringLiteral("Shepp-Logan phantom %1 (built-in)").arg(QString::number(phantomSize) + QStringLiteral("³"));
    case Kind::VolumeFile: return QFileInfo(path).fileName();
    case Kind::DicomFolder: return QDir(path).dirName() + (seriesKey.isEmpty() ? QString() : QStringLiteral(" (series)"));
    }
    return {};
}

StudySource StudySource::phantom(int n) {
    StudySource s;
    s.kind = Kind::Phantom;
    s.phantomSize = n;
    return s;
}

StudySource StudySource::fromPath(const QString& path) {
    StudySource s;
    s.path = path;
    s.kind = QFileInfo(path).isDir() ? Kind::DicomFolder : Kind::VolumeFile;
    return s;
}

StudyController::StudyController(QObject* parent) : QObject(parent) {
    m_timer.setInterval(50);
    connect(&m_timer, &QTimer::timeout, this, &StudyController::poll);
}

StudyController::~StudyController() {
    if (m_cancel) m_cancel->cancel();
    if (m_worker.joinable()) m_worker.join();
}

double StudyController::estimatedSpectrumMiB(const SpectrumSettings& s) const {
    if (!m_volume) return 0.0;
    core::PreprocessOptions o;
    o.oversampling = s.oversampling;
    return double(core::spectrumBytes(core::paddedDimsFor(m_volume->dims, o))) / (1 << 20);
}

void StudyController::report(double fraction, std::string_view stage) {
    m_fraction.store(fraction);
    std::lock_guard lock(m_stageMutex);
    m_stage = QString::fromUtf8(stage.data(), int(stage.size()));
}

void StudyController::poll() {
    if (m_done.load()) { // the result (or error) is already on its way: no stale progress after it
        m_timer.stop();
        return;
    }
    QString stage;
    {
        std::lock_guard lock(m_stageMutex);
        stage = m_stage;
    }
    emit progress(m_fraction.load(), stage);
}

void StudyController::cancel() {
    if (m_cancel) m_cancel->cancel();
}

void StudyController::waitIdle() {
    if (m_worker.joinable()) m_worker.join();
}

void StudyController::startJob(std::function<void(core::CancelToken&)> job) {
    if (m_cancel) m_cancel->cancel();
    if (m_worker.joinable()) m_worker.join();
    m_cancel = std::make_shared<core::CancelToken>();
    m_done.store(false);
    m_fraction.store(0.0);
    report(0.0, "starting");
    m_worker = std::thread([this, job = std::move(job), token = m_cancel] {
        try {
            job(*token);
        } catch (const core::Cancelled&) {
            QMetaObject::invokeMethod(this, [this] { emit cancelled(); }, Qt::QueuedConnection);
        } catch (const std::bad_alloc&) {
            QMetaObject::invokeMethod(
                this, [this] { emit failed(tr("Out of memory"), tr("The study or its spectrum does not fit in memory. "
                                                                   "Try a smaller oversampling.")); },
                Qt::QueuedConnection);
        } catch (const std::exception& e) {
            const QString what = QString::fromStdString(e.what());
            QMetaObject::invokeMethod(this, [this, what] { emit failed(tr("Could not open the study"), what); },
                                      Qt::QueuedConnection);
        }
        m_done.store(true);
    });
    m_timer.start();
}

void StudyController::open(const StudySource& source) {
    const SpectrumSettings settings = m_settings;
    auto scan = (source.kind == StudySource::Kind::DicomFolder && source.path == m_scanFolder) ? m_scan : nullptr;
    startJob([this, source, settings, scan](core::CancelToken& token) {
        auto vol = std::make_shared<core::Volume>();
        QStringList warnings;
        switch (source.kind) {
        case StudySource::Kind::Phantom:
            report(0.05, "building phantom");
            *vol = core::makeSheppLoganVolume(source.phantomSize);
            break;
        case StudySource::Kind::VolumeFile:
            report(0.05, "reading file");
            *vol = core::loadVolume(source.path.toStdString());
            break;
        case StudySource::Kind::DicomFolder: {
            auto result = scan;
            if (!result) {
                result = std::make_shared<const core::DicomScanResult>(core::scanDicomFolder(
                    source.path.toStdString(), [this](double f, std::string_view st) { report(f * 0.2, st); },
                    &token));
                QMetaObject::invokeMethod(this, [this, result, folder = source.path] {
                    m_scan = result;
                    m_scanFolder = folder;
                }, Qt::QueuedConnection);
            }
            const core::DicomSeriesInfo* chosen = nullptr;
            if (!source.seriesKey.isEmpty()) {
                for (const auto& s : result->series)
                    if (QString::fromStdString(s.key) == source.seriesKey ||
                        QString::fromStdString(s.seriesUid) == source.seriesKey)
                        chosen = &s;
                if (!chosen) throw core::LoadError(source.path.toStdString() + ": series " +
                                                   source.seriesKey.toStdString() + " not found");
            } else if (result->series.size() == 1) {
                chosen = &result->series.front();
            } else {
                QStringList keys, labels;
                for (const auto& s : result->series) {
                    keys << QString::fromStdString(s.key);
                    labels << QStringLiteral("%1 %2 — %3 (%4 images, %5×%6×%7)")
                                  .arg(QString::fromStdString(s.modality), QString::fromStdString(s.studyDate),
                                       QString::fromStdString(s.description.empty() ? s.seriesUid : s.description))
                                  .arg(s.imageCount)
                                  .arg(s.dims[0])
                                  .arg(s.dims[1])
                                  .arg(s.dims[2]);
                }
                QMetaObject::invokeMethod(this, [this, source, keys, labels] {
                    emit seriesChoiceNeeded(source, keys, labels);
                }, Qt::QueuedConnection);
                return;
            }
            auto loaded = core::loadDicomSeries(
                *chosen, [this](double f, std::string_view st) { report(0.2 + f * 0.3, st); }, &token);
            *vol = std::move(loaded.volume);
            for (const auto& w : loaded.warnings) warnings << QString::fromStdString(w);
            for (const auto& w : chosen->warnings)
                if (!warnings.contains(QString::fromStdString(w))) warnings << QString::fromStdString(w);
            break;
        }
        }
        token.check();
        if (vol->units == core::ValueUnits::Unknown) {
            // Files without units (NIfTI, MetaImage) that hold CT: air near -1000, tissue above.
            const auto [lo, hi] = vol->valueRange();
            if (lo <= -900.0f && lo >= -3100.0f && hi >= 200.0f) {
                vol->units = core::ValueUnits::HounsfieldUnits;
                warnings << tr("The file states no units; its values (%1 … %2) look like Hounsfield units and are "
                               "treated as such.").arg(lo).arg(hi);
            }
        }
        SpectrumSettings used = settings;
        if (core::isAttenuation(used.mapping) && vol->units != core::ValueUnits::HounsfieldUnits) {
            // mu = 1 + HU/1000 only means something for Hounsfield units.
            used.mapping = core::ValueMapping::Raw;
            warnings << tr("The values are not Hounsfield units (%1): integrating the raw values instead of "
                           "attenuation.").arg(QString::fromUtf8(core::unitsName(vol->units)));
        }
        core::PreprocessOptions o;
        o.mapping = used.mapping;
        o.transform = settings.transform;
        o.oversampling = settings.oversampling;
        o.deapodizeFor = settings.deapodizeFor;
        auto spectrum = core::preprocess(*vol, o, [this](double f, std::string_view st) { report(0.5 + 0.5 * f, st); },
                                         &token);
        std::shared_ptr<const core::Volume> cvol = vol;
        QMetaObject::invokeMethod(this, [this, source, cvol, spectrum, warnings, used] {
            m_source = source;
            m_volume = cvol;
            m_spectrum = spectrum;
            m_settings = used;
            m_warnings = warnings;
            emit warningsChanged(m_warnings);
            emit studyLoaded(source.displayName());
            emit spectrumReady();
        }, Qt::QueuedConnection);
    });
}

void StudyController::setSpectrumSettings(const SpectrumSettings& settings) {
    if (settings == m_settings && m_spectrum) return;
    if (!m_volume) {
        m_settings = settings;
        return;
    }
    auto vol = m_volume;
    startJob([this, vol, settings](core::CancelToken& token) {
        core::PreprocessOptions o;
        o.mapping = settings.mapping;
        o.transform = settings.transform;
        o.oversampling = settings.oversampling;
        o.deapodizeFor = settings.deapodizeFor;
        auto spectrum = core::preprocess(*vol, o, [this](double f, std::string_view st) { report(f, st); }, &token);
        QMetaObject::invokeMethod(this, [this, spectrum, settings, vol] {
            if (vol != m_volume) return; // a newer study replaced it meanwhile
            m_spectrum = spectrum;
            m_settings = settings;
            emit spectrumReady();
        }, Qt::QueuedConnection);
    });
}

} // namespace fvr::ui
