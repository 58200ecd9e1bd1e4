#include <fvr/ui/study.h>

#include <fvr/core/xray/xray.h>

#include <QDate>
#include <QDir>
#include <QFileInfo>

#include <chrono>

#include <fvr/core/errors.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/ui/panels/rendering_panel.h>

namespace fvr::ui {

QString StudySource::displayName() const {
    switch (kind) {
    case Kind::Phantom:
        return (phantomKind == core::PhantomKind::Chest
                    ? QStringLiteral("Chest phantom %1 (built-in)")
                    : QStringLiteral("Shepp-Logan phantom %1 "
                                     "(built-in)"))
            .arg(QString::number(phantomSize) + QStringLiteral("³"));
    case Kind::VolumeFile:
    case Kind::DicomFile: return QFileInfo(path).fileName();
    case Kind::DicomFolder:
        return QDir(path).dirName() +
               (seriesKey.isEmpty() ? QString() : QStringLiteral(" (series)"));
    }
    return {};
}

StudySource StudySource::phantom(int n) {
    StudySource s;
    s.kind = Kind::Phantom;
    s.phantomSize = n;
    s.phantomKind = core::PhantomKind::SheppLogan;
    return s;
}

StudySource StudySource::chest(int n) {
    StudySource s = phantom(n);
    s.phantomKind = core::PhantomKind::Chest;
    return s;
}

StudySource StudySource::fromPath(const QString& path) {
    StudySource s;
    s.path = path;
    try {
        const core::InputSource in = core::classifyInput(path.toStdString());
        s.path = QString::fromStdString(in.path.string());
        s.phantomSize = in.phantomSize;
        s.phantomKind = in.phantom;
        switch (in.kind) {
        case core::InputKind::Phantom: s.kind = Kind::Phantom; break;
        case core::InputKind::DicomFolder: s.kind = Kind::DicomFolder; break;
        case core::InputKind::DicomFile: s.kind = Kind::DicomFile; break;
        case core::InputKind::VolumeFile: s.kind = Kind::VolumeFile; break;
        }
    } catch (const std::exception&) {
        s.kind = QFileInfo(path).isDir() ? Kind::DicomFolder : Kind::VolumeFile; // reported on open
    }
    return s;
}

core::InputSource StudySource::toCore() const {
    if (kind == Kind::Phantom) return {core::InputKind::Phantom, {}, phantomSize, phantomKind};
    return core::classifyInput(path.toStdString()); // throws for a path that vanished
}

QString StudyController::title() const {
    if (!m_series) return m_source.displayName();
    QStringList parts;
    if (!m_series->description.empty()) parts << QString::fromStdString(m_series->description);
    if (!m_series->patientName.empty()) parts << personName(m_series->patientName);
    return parts.isEmpty() ? m_source.displayName() : parts.join(QStringLiteral(" — "));
}

QString personName(const std::string& dicomName) {
    return QString::fromStdString(dicomName).replace('^', ' ').simplified();
}

QString countOf(int n, const QString& one, const QString& many) {
    return n == 1 ? one : QString(many).arg(n);
}

QString dicomDate(const std::string& date) {
    const QString text = QString::fromStdString(date);
    const QDate day = QDate::fromString(text, QStringLiteral("yyyyMMdd"));
    return day.isValid() ? day.toString(Qt::ISODate) : text;
}

SpectrumSettings workstationSpectrumDefaults() {
    const RenderingPanel::Values defaults;
    return RenderingPanel::spectrumSettings(defaults, defaults.kernel);
}

StudyController::StudyController(QObject* parent) : QObject(parent) {
    m_timer.setInterval(50);
    connect(&m_timer, &QTimer::timeout, this, &StudyController::poll);
}

StudyController::~StudyController() {
    // Before the members the jobs use go (m_jobs would do the same as the last member).
    m_jobs.cancelAll();
    m_jobs.wait();
}

double StudyController::estimatedSpectrumMiB(const SpectrumSettings& s) const {
    if (!m_volume) return 0.0;
    return double(core::spectrumBytes(core::paddedDimsFor(m_volume->dims, s))) / (1 << 20);
}

void StudyController::report(double fraction, std::string_view stage) {
    m_fraction.store(fraction);
    std::lock_guard lock(m_stageMutex);
    m_stage = QString::fromUtf8(stage.data(), int(stage.size()));
}

void StudyController::poll() {
    // The result (or error) is on its way, or already handled (a job counts as running until
    // its outcome is posted): no stale progress after it.
    if (!m_jobs.running() || m_finishedJob >= m_jobsStarted) {
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

void StudyController::markFinished(std::uint64_t id) {
    m_finishedJob = std::max(m_finishedJob, id);
    QMetaObject::invokeMethod(
        this,
        [this] {
            if (m_finishedJob >= m_jobsStarted) emit idle();
        },
        Qt::QueuedConnection);
}

void StudyController::cancel() {
    if (m_cancel) m_cancel->cancel();
    // The user's cancel of a compare job stops the preparation of the others too, even when
    // this one ends before it sees the cancel.
    if (m_finishedJob < m_jobsStarted && m_compareJob.id == m_jobsStarted)
        m_compareJob.cancelledByUser = true;
}

void StudyController::waitIdle() { m_jobs.wait(); }

void StudyController::startJob(JobWork work, JobFailed failed) {
    // One job at a time: the running one stops at its next check.
    m_jobs.cancelAll();
    m_jobs.wait();
    m_fraction.store(0.0);
    report(0.0, "starting");
    const std::uint64_t id = ++m_jobsStarted;
    if (!failed) failed = [this](const JobError& e, std::uint64_t job) { jobFailed(e, job); };
    m_cancel = m_jobs.run(
        [work = std::move(work), id](core::CancelToken& token) { return work(token, id); },
        [](const GuiStep& step) {
            if (step) step();
        },
        [failed = std::move(failed), id](const JobError& e) { failed(e, id); });
    m_timer.start();
}

void StudyController::jobFailed(const JobError& e, std::uint64_t id) {
    switch (e.kind) {
    case JobError::Kind::Cancelled:
        // A job cancelled because a newer one replaced it is not the user's cancel.
        if (id != m_jobsStarted) return;
        markFinished(id);
        revertRequestToSettingsInEffect();
        declinePendingCompare(e.message); // the user stopped the work
        emit cancelled();
        return;
    case JobError::Kind::OutOfMemory:
        markFinished(id);
        m_target = m_settings;
        declinePendingCompare(e.message);
        emit failed(tr("Out of memory"), tr("The study or its spectrum does not fit in memory. "
                                            "Try a smaller oversampling."));
        return;
    case JobError::Kind::Failed:
        markFinished(id);
        m_target = m_settings;
        prepareCompareSpectra(); // the study in use still wants them
        emit failed(tr("Could not open the study"), e.message);
        return;
    }
}

void StudyController::open(const StudySource& source) {
    const SpectrumSettings settings = m_requested;
    auto cached = (source.kind == StudySource::Kind::DicomFolder && source.path == m_scanFolder)
                      ? m_scan
                      : nullptr;
    startJob([this, source, settings, cached](core::CancelToken& token, std::uint64_t id) {
        core::OpenOptions options;
        options.seriesKey = source.seriesKey.toStdString();
        core::ProgressFn progress = [this](double f, std::string_view st) { report(0.5 * f, st); };
        if (source.kind == StudySource::Kind::DicomFolder) {
            options.scan = scanFolder(source, cached, token);
            if (GuiStep choose = seriesChoice(source, *options.scan, id)) return choose;
            progress = [this](double f, std::string_view st) { report(0.2 + 0.3 * f, st); };
        }
        return finishOpen(source, settings,
                          core::openStudy(source.toCore(), options, progress, &token), token, id);
    });
}

std::shared_ptr<const core::DicomScanResult> StudyController::scanFolder(
    const StudySource& source, std::shared_ptr<const core::DicomScanResult> cached,
    core::CancelToken& token) {
    if (cached) return cached;
    auto scan = std::make_shared<const core::DicomScanResult>(core::scanDicomFolder(
        source.path.toStdString(), [this](double f, std::string_view st) { report(f * 0.2, st); },
        &token));
    m_jobs.post([this, scan, folder = source.path] {
        m_scan = scan;
        m_scanFolder = folder;
    });
    return scan;
}

namespace {
/** " — default" for the default series, and why a series cannot be loaded. */
QString seriesNote(bool isDefault, const core::DicomSeriesInfo& s) {
    QString note = isDefault ? StudyController::tr(" — default") : QString();
    if (!s.loadable())
        note += StudyController::tr(" — cannot be loaded: %1")
                    .arg(QString::fromStdString(s.unloadableReason));
    return note;
}
} // namespace

namespace {
/** "NAME (ID)", or what is known of them. */
QString patientText(const core::DicomSeriesInfo& s) {
    const QString name = QString::fromStdString(s.patientName).replace('^', ' ').trimmed();
    const QString id = QString::fromStdString(s.patientId);
    if (name.isEmpty() && id.isEmpty()) return StudyController::tr("unnamed patient");
    if (id.isEmpty()) return name;
    return name.isEmpty() ? StudyController::tr("patient %1").arg(id)
                          : QStringLiteral("%1 (%2)").arg(name, id);
}
} // namespace

QString StudyController::seriesChoiceLabel(const core::DicomSeriesInfo& s) {
    const QString modality =
        s.modality.empty() ? tr("unknown modality") : QString::fromStdString(s.modality);
    const QString number = s.seriesNumber.empty()
                               ? tr("series (no number)")
                               : tr("series %1").arg(QString::fromStdString(s.seriesNumber));
    // Without a description: what a reader tells series apart by, not the UID.
    const QString what = s.description.empty()
                             ? tr("%1, %2 slices").arg(number).arg(s.frameCount)
                             : tr("%1: %2").arg(number, QString::fromStdString(s.description));
    return QStringLiteral("%1 — %2 %3 — %4 (%5 images, %6×%7×%8)")
        .arg(patientText(s), modality, QString::fromStdString(s.studyDate), what)
        .arg(s.imageCount)
        .arg(s.dims[0])
        .arg(s.dims[1])
        .arg(s.dims[2]);
}

QString StudyController::seriesChoicePrompt(const QString& folder,
                                            const core::DicomScanResult& scan) {
    QStringList patients;
    for (const auto& s : scan.series)
        if (!patients.contains(patientText(s))) patients << patientText(s);
    if (patients.size() <= 1)
        return tr("%1 holds several series of %2:")
            .arg(folder, patients.isEmpty() ? tr("unnamed patient") : patients.first());
    return tr("%1 holds series of %2 different patients (%3). Warning: this folder mixes "
              "patients; check the patient of the series you choose:")
        .arg(folder)
        .arg(patients.size())
        .arg(patients.join(QStringLiteral(", ")));
}

StudyController::GuiStep StudyController::seriesChoice(const StudySource& source,
                                                       const core::DicomScanResult& scan,
                                                       std::uint64_t id) {
    if (!source.seriesKey.isEmpty() || scan.series.size() <= 1) return {};
    const std::size_t first = core::defaultSeriesIndex(scan);
    QStringList keys, labels;
    for (std::size_t n = 0; n < scan.series.size(); ++n) {
        const auto& s = scan.series[n == 0 ? first : (n <= first ? n - 1 : n)];
        keys << QString::fromStdString(s.key);
        labels << seriesChoiceLabel(s) + seriesNote(n == 0, s);
    }
    const QString prompt = seriesChoicePrompt(source.path, scan);
    return [this, source, keys, labels, prompt, id] {
        markFinished(id);
        prepareCompareSpectra(); // the study in use still wants them
        emit seriesChoiceNeeded(source, keys, labels, prompt);
    };
}

StudyController::GuiStep StudyController::finishOpen(const StudySource& source,
                                                     const SpectrumSettings& settings,
                                                     core::OpenedStudy opened,
                                                     core::CancelToken& token, std::uint64_t id) {
    token.check();
    auto vol = std::make_shared<core::Volume>(std::move(opened.volume));
    QStringList warnings;
    for (const auto& w : opened.warnings) warnings << QString::fromStdString(w);
    const SpectrumSettings used = settingsForStudy(settings, *vol, &warnings);
    auto spectrum = core::preprocess(
        *vol, used, [this](double f, std::string_view st) { report(0.5 + 0.5 * f, st); }, &token);
    std::shared_ptr<const core::Volume> cvol = vol;
    return [this, source, cvol, spectrum, warnings, used, series = std::move(opened.series), id] {
        m_resultJob = id;
        markFinished(id);
        if (id == m_jobsStarted) m_target = used;
        m_source = source;
        m_series = series;
        m_volume = cvol;
        m_spectrum = spectrum;
        m_settings = used;
        m_warnings = warnings;
        m_compareDeclined.clear();
        pruneCompareSpectra();
        emit warningsChanged(m_warnings);
        emit studyLoaded(title());
        emit spectrumReady();
        prepareCompareSpectra();
    };
}

SpectrumSettings StudyController::settingsForStudy(const SpectrumSettings& requested,
                                                   const core::Volume& volume,
                                                   QStringList* warnings) {
    // core's rule: mu = 1 + HU/1000 only means something for Hounsfield units.
    core::RenderSettings asked;
    asked.values = requested.mapping;
    std::string note;
    SpectrumSettings used = requested;
    used.mapping = asked.forVolume(volume, &note).values;
    if (warnings && !note.empty()) {
        QString text = QString::fromStdString(note) + QLatin1Char('.');
        text[0] = text[0].toUpper();
        *warnings << text;
    }
    return used;
}

void StudyController::revertRequestToSettingsInEffect() {
    // A cancelled change is not asked for any more; a mapping the study could not have (raw in
    // effect for attenuation asked of non-HU data) stays asked for the next study.
    const bool keepMapping =
        m_volume && settingsForStudy(m_requested, *m_volume, nullptr).mapping == m_settings.mapping;
    const core::ValueMapping mapping = keepMapping ? m_requested.mapping : m_settings.mapping;
    m_requested = m_settings;
    m_requested.mapping = mapping;
    m_target = m_settings;
}

void StudyController::setSpectrumSettings(const SpectrumSettings& asked) {
    const core::ValueMapping requestedMapping =
        (m_volume && asked.mapping == m_settings.mapping) ? m_requested.mapping : asked.mapping;
    m_requested = asked;
    m_requested.mapping = requestedMapping;
    if (!m_volume) {
        m_settings = m_target = asked;
        return;
    }
    const SpectrumSettings settings = settingsForStudy(m_requested, *m_volume, nullptr);
    // Compared with what the running job will give (else a change back to the settings in use
    // while another change runs would be dropped, and that job's spectrum would stay).
    if (settings == m_target && m_spectrum) return;
    m_target = settings;
    auto vol = m_volume;
    startJob([this, vol, settings](core::CancelToken& token, std::uint64_t id) {
        auto spectrum = core::preprocess(
            *vol, settings, [this](double f, std::string_view st) { report(f, st); }, &token);
        return [this, spectrum, settings, vol, id] {
            markFinished(id);
            if (vol != m_volume) return; // a newer study replaced it meanwhile
            m_resultJob = id;
            m_spectrum = spectrum;
            m_settings = settings;
            m_compareDeclined.clear();
            pruneCompareSpectra();
            emit spectrumReady();
            prepareCompareSpectra();
        };
    });
}

SpectrumSettings StudyController::settingsFor(core::Kernel kernel) const {
    SpectrumSettings s = m_settings;
    s.deapodizeFor = m_compareGridding && core::griddingCorrectionHelps(kernel)
                         ? std::optional<core::Kernel>(kernel)
                         : std::nullopt;
    return s;
}

std::shared_ptr<const core::Spectrum> StudyController::spectrumFor(core::Kernel kernel) const {
    if (!m_spectrum) return nullptr;
    if (settingsFor(kernel) == m_settings) return m_spectrum;
    const auto it = m_compare.find(kernel);
    return it == m_compare.end() ? nullptr : it->second.spectrum;
}

QString StudyController::spectrumPendingReason(core::Kernel kernel) const {
    const QString name = QString::fromUtf8(core::kernelName(kernel));
    const QString what = settingsFor(kernel).deapodizeFor
                             ? tr("the gridding-corrected spectrum for %1").arg(name)
                             : tr("the spectrum for %1").arg(name);
    if (const auto it = m_compareDeclined.find(kernel); it != m_compareDeclined.end())
        return tr("Not prepared: %1 (%2). View ▸ Compare again to retry.").arg(what, it->second);
    return tr("Preparing %1…").arg(what);
}

std::optional<QString> StudyController::compareDeclined(core::Kernel kernel) const {
    const auto it = m_compareDeclined.find(kernel);
    return it == m_compareDeclined.end() ? std::nullopt : std::optional(it->second);
}

void StudyController::setCompareKernels(const std::vector<core::Kernel>& kernels, bool gridding,
                                        bool retry) {
    if (retry || kernels != m_compareKernels || gridding != m_compareGridding)
        m_compareDeclined.clear();
    m_compareKernels = kernels;
    m_compareGridding = gridding;
    // A compare job whose spectrum is no longer wanted stops (not the user's cancel).
    const bool running = m_finishedJob < m_jobsStarted && m_compareJob.id == m_jobsStarted;
    if (running &&
        !(std::find(kernels.begin(), kernels.end(), m_compareJob.kernel) != kernels.end() &&
          settingsFor(m_compareJob.kernel) == m_compareJob.settings)) {
        m_compareJob.dropped = true;
        if (m_cancel) m_cancel->cancel();
    }
    pruneCompareSpectra();
    prepareCompareSpectra();
}

bool StudyController::wantedCompareSpectrum(core::Kernel kernel,
                                            const SpectrumSettings& settings) const {
    return std::find(m_compareKernels.begin(), m_compareKernels.end(), kernel) !=
               m_compareKernels.end() &&
           settings == settingsFor(kernel) && !(settings == m_settings);
}

void StudyController::pruneCompareSpectra() {
    // Kept: a listed kernel's spectrum at the settings in effect, unless the main spectrum is
    // that one (view 1 switched to a compare view's kernel).
    std::erase_if(m_compare, [this](const auto& entry) {
        const auto& [kernel, c] = entry;
        return c.volume != m_volume || !wantedCompareSpectrum(kernel, c.settings);
    });
}

void StudyController::declinePendingCompare(const QString& reason) {
    for (const core::Kernel k : m_compareKernels)
        if (!spectrumFor(k)) m_compareDeclined.emplace(k, reason);
}

double StudyController::spectraMiB() const {
    double bytes = m_spectrum ? double(m_spectrum->bytes()) : 0.0;
    for (const auto& [kernel, c] : m_compare) bytes += double(c.spectrum->bytes());
    return bytes / (1 << 20);
}

int StudyController::spectrumCount() const { return (m_spectrum ? 1 : 0) + int(m_compare.size()); }

void StudyController::prepareCompareSpectra() {
    if (!m_volume || !m_spectrum || m_finishedJob < m_jobsStarted) return; // a job runs
    for (const core::Kernel k : m_compareKernels)
        if (!spectrumFor(k) && !m_compareDeclined.count(k)) return startCompareJob(k);
}

void StudyController::startCompareJob(core::Kernel k) {
    const SpectrumSettings settings = settingsFor(k);
    auto vol = m_volume;
    const QString stage = tr("spectrum for %1: ").arg(QString::fromUtf8(core::kernelName(k)));
    startJob(
        [this, vol, settings, k, stage](core::CancelToken& token, std::uint64_t id) -> GuiStep {
            for (int waited = 0; waited < m_simulatedCompareDelayMs.load(); waited += 10) {
                token.check();
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
            }
            auto spectrum = core::preprocess(
                *vol, settings,
                [this, stage](double f, std::string_view st) {
                    report(f, (stage + QString::fromUtf8(st.data(), int(st.size()))).toStdString());
                },
                &token);
            return [this, id, k, vol, settings, spectrum] {
                compareJobDone(id, k, vol, settings, spectrum, QString());
            };
        },
        // Cancelled, out of memory or an error: this kernel's spectrum alone is not prepared.
        [this, vol, settings, k](const JobError& e, std::uint64_t id) {
            compareJobDone(id, k, vol, settings, nullptr, e.message);
        });
    m_compareJob = {m_jobsStarted, k, settings, false};
}

void StudyController::compareJobDone(std::uint64_t id, core::Kernel k,
                                     const std::shared_ptr<const core::Volume>& vol,
                                     const SpectrumSettings& settings,
                                     std::shared_ptr<const core::Spectrum> spectrum,
                                     const QString& failure) {
    markFinished(id);
    const bool replaced = id != m_jobsStarted; // a newer job cancelled this one
    const bool dropped = m_compareJob.id == id && m_compareJob.dropped;
    const bool userCancel = m_compareJob.id == id && m_compareJob.cancelledByUser;
    if (!replaced) m_resultJob = id; // the views and the progress bar take this result
    if (spectrum && vol == m_volume && wantedCompareSpectrum(k, settings))
        m_compare[k] = {settings, vol, std::move(spectrum)};
    else if (!failure.isEmpty() && !replaced && !dropped && !userCancel)
        m_compareDeclined[k] = failure; // out of memory or an error: this kernel's
    // The user's cancel stops the preparation of every missing spectrum.
    if (userCancel && !replaced) declinePendingCompare(tr("cancelled"));
    if (!replaced) emit spectrumReady(); // the views show their spectra or say why not
    prepareCompareSpectra();
}

} // namespace fvr::ui
