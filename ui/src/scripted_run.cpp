#include <fvr/ui/scripted_run.h>

#include <QBuffer>
#include <QCoreApplication>
#include <QDir>
#include <QImage>
#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>

#include <chrono>
#include <cstdio>
#include <cstdlib>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/main_window.h>

namespace fvr::ui {

namespace {

QJsonArray vec(const core::Vec3& v) { return {v[0], v[1], v[2]}; }

QJsonObject windowJson(const core::DisplayWindow& w) {
    QJsonObject o{{"low", w.low}, {"high", w.high}, {"invert", w.invert}};
    if (w.transmission.active())
        o["transmission"] = QJsonObject{{"muWaterPerMm", w.transmission.muWaterPerMm},
                                        {"exposure", w.transmission.exposure}};
    return o;
}

QJsonObject spectrumJson(const SpectrumSettings& s) {
    return {{"values", core::valueMappingName(s.mapping)},
            {"transform", core::transformName(s.transform)},
            {"oversampling", s.oversampling},
            {"deapodizedFor", s.deapodizeFor ? QJsonValue(core::kernelName(*s.deapodizeFor))
                                             : QJsonValue(QJsonValue::Null)}};
}

/** What a view's .npy holds: the transmitted intensity, the polychromatic quantity with its
 *  tube (once the view's material spectra have come) or the line integrals. */
QString npyValues(const ProjectionView& v, bool transmission) {
    if (transmission) return QStringLiteral("transmitted intensity");
    const auto& poly = v.polychromatic();
    if (!poly || poly->spectra.empty()) return QStringLiteral("line integrals");
    return QStringLiteral("polychromatic %1, %2")
        .arg(ViewOverlay::polychromaticQuantity(poly->show),
             ViewOverlay::polychromaticBeam(poly->kvp, poly->filtrationAlMm, poly->filtrationCuMm));
}

/** The spectrum one view renders from (compare views each have their kernel's): its values,
 *  transform, oversampling (the study's: every spectrum of a study shares it), padded size and
 *  whether it is gridding corrected for the view's kernel. */
QJsonValue viewSpectrumJson(const ProjectionView& v, const SpectrumSettings& study) {
    const auto& sp = v.spectrum();
    if (!sp) return QJsonValue::Null;
    const bool corrected = sp->deapodizedFor && *sp->deapodizedFor == v.settings().kernel;
    return QJsonObject{
        {"values", core::valueMappingName(sp->mapping)},
        {"transform", core::transformName(sp->kind)},
        {"oversampling", study.oversampling},
        {"paddedDims",
         QJsonArray{qint64(sp->padded[0]), qint64(sp->padded[1]), qint64(sp->padded[2])}},
        {"griddingCorrection", corrected},
        {"deapodizedFor", sp->deapodizedFor ? QJsonValue(core::kernelName(*sp->deapodizedFor))
                                            : QJsonValue(QJsonValue::Null)}};
}

/** One view's entry of views.json. */
QJsonObject viewJson(int index, ProjectionView& v, const core::ProjectionImage& p,
                     bool transmission, const SpectrumSettings& study) {
    const QString stem = QStringLiteral("view%1").arg(index + 1);
    return {{"index", index + 1},
            {"spectrum", viewSpectrumJson(v, study)},
            {"npy", stem + ".npy"},
            {"png", stem + ".png"},
            {"kernel", core::kernelName(v.settings().kernel)},
            {"size", p.width}, // the views render squares
            {"pixelSizeMm", p.pixelSize},
            {"voxelModel", core::voxelModelName(v.settings().voxelModel)},
            {"npyValues", npyValues(v, transmission)},
            {"window", windowJson(v.window())},
            {"viewFrame", QJsonObject{{"dir", vec(v.viewFrame().d)},
                                      {"up", vec(v.viewFrame().u)},
                                      {"right", vec(v.viewFrame().r)}}},
            {"backend", v.usingGpu() ? "gpu" : "cpu"}};
}

} // namespace

ScriptedRun::ScriptedRun(MainWindow& window, ScriptedRunOptions options, QObject* parent)
    : QObject(parent), m_window(window), m_options(std::move(options)) {
    StudyController& study = m_window.study();
    m_window.setAskForSeries(false); // nobody to ask: the default series, as fvr-render
    // Connected after the main window's own handlers: the views already hold the new spectrum.
    connect(&study, &StudyController::spectrumReady, this, &ScriptedRun::onSpectrumReady);
    connect(&study, &StudyController::failed, this,
            [this](const QString& title, const QString& details) {
                finish(kScriptedFailed, title + ": " + details);
            });
    connect(&study, &StudyController::cancelled, this,
            [this] { finish(kScriptedFailed, tr("the study's preprocessing was cancelled")); });
    connect(&m_poll, &QTimer::timeout, this, &ScriptedRun::poll);
    m_poll.start(50);
    m_timeout.setSingleShot(true);
    connect(&m_timeout, &QTimer::timeout, this, [this] {
        finish(kScriptedTimeout,
               tr("the views were not ready within %1 s (--script-timeout); nothing written")
                   .arg(m_options.timeoutSeconds));
    });
    m_timeout.start(m_options.timeoutSeconds * 1000);
    if (m_options.quit)
        m_watchdog =
            std::thread([this, s = m_options.timeoutSeconds + kWatchdogGraceSeconds] { watch(s); });
}

ScriptedRun::~ScriptedRun() {
    {
        const std::lock_guard lock(m_watchMutex);
        m_watchStop = true;
    }
    m_watchWake.notify_all();
    if (m_watchdog.joinable()) m_watchdog.join();
}

void ScriptedRun::watch(int seconds) {
    std::unique_lock lock(m_watchMutex);
    if (m_watchWake.wait_for(lock, std::chrono::seconds(seconds), [this] { return m_watchStop; }))
        return;
    // The GUI thread did not get to its own timeout (it is blocked): end the process here.
    std::fprintf(stderr,
                 "fvr-workstation: the views were not ready within %d s (--script-timeout) and "
                 "the application does not respond; nothing written\n",
                 m_options.timeoutSeconds);
    std::fflush(stderr);
    std::_Exit(kScriptedTimeout);
}

void ScriptedRun::onSpectrumReady() {
    // A study is in: from now on every view must show its current full-quality frame (after
    // any view, kernel or window change made in the same handlers; compare views wait for
    // their kernels' spectra).
    m_armed = true;
    m_readyTicks = 0;
}

bool ScriptedRun::ready() {
    const StudyController& study = m_window.study();
    if (!m_armed || !study.spectrum() || study.newerJobStarted() || study.busy()) return false;
    const auto& views = m_window.views();
    if (views.empty()) return false;
    for (const ProjectionView* v : views)
        if (!v->isVisible() || !v->showsCurrentFrame()) return false;
    return true;
}

void ScriptedRun::poll() {
    if (m_finished) return;
    // A view that cannot show its image (its spectrum was not prepared, or rendering failed)
    // ends the run with the reason rather than at the timeout.
    if (const QString why = viewFailure(); !why.isEmpty()) return finish(kScriptedFailed, why);
    // Ready on two polls in a row: a frame rendered for an export (projection()) is on screen
    // by the next paint.
    m_readyTicks = ready() ? m_readyTicks + 1 : 0;
    if (m_readyTicks < 2) return;
    try {
        writeOutputs();
    } catch (const std::exception& e) {
        finish(kScriptedFailed, QString::fromUtf8(e.what()));
        return;
    }
    finish(kScriptedOk, {});
}

QString ScriptedRun::viewFailure() const {
    const StudyController& study = m_window.study();
    if (!m_armed || study.busy()) return {};
    for (const ProjectionView* v : m_window.views()) {
        if (!v->renderError().isEmpty()) return v->renderError();
        if (!v->spectrum() && v->pendingFailed()) return v->pendingText();
    }
    return {};
}

void ScriptedRun::writeOutputs() {
    if (!m_options.exportDir.isEmpty()) writeViews(m_options.exportDir);
    if (!m_options.screenshotFile.isEmpty()) {
        const QImage shot = m_window.grabWithViews(&m_window);
        QByteArray bytes;
        QBuffer buffer(&bytes);
        buffer.open(QIODevice::WriteOnly);
        const std::string path = m_options.screenshotFile.toStdString();
        if (shot.isNull() || !shot.save(&buffer, "PNG"))
            throw core::WriteError(path + ": the window could not be captured");
        core::writeFileAtomic(path, bytes.toStdString());
    }
}

void ScriptedRun::writeViews(const QString& dir) {
    if (!QDir().mkpath(dir))
        throw core::WriteError(dir.toStdString() + ": cannot create the folder");
    const QDir out(dir);
    const core::Transmission t = m_window.currentTransmission();
    QJsonArray views;
    for (std::size_t i = 0; i < m_window.views().size(); ++i) {
        ProjectionView& v = *m_window.views()[i];
        const auto p = v.projection();
        const QString stem = QStringLiteral("view%1").arg(i + 1);
        if (!p) throw core::WriteError(out.filePath(stem).toStdString() + ": view has no image");
        // As File ▸ Export projection: the float image the display windows (the transmitted
        // intensity in Beer-Lambert mode); the PNG is the line integrals through the view's
        // window, the mapping the display shader applies (row 0 at the top, as on screen).
        std::vector<float> values = p->pixels;
        if (t.active()) core::applyTransmission(values, t);
        core::writeNpy(out.filePath(stem + ".npy").toStdString(), values.data(), p->height,
                       p->width);
        core::writePng(out.filePath(stem + ".png").toStdString(), p->pixels.data(), p->height,
                       p->width, v.window(), 8);
        views.append(viewJson(int(i), v, *p, t.active(), m_window.study().spectrumSettings()));
    }
    const StudyController& study = m_window.study();
    const QJsonObject doc{{"study", study.title()},
                          {"source", study.source().path.isEmpty() ? study.source().displayName()
                                                                   : study.source().path},
                          {"spectrum", spectrumJson(study.spectrumSettings())},
                          {"windowSize", QJsonArray{m_window.width(), m_window.height()}},
                          {"views", views}};
    core::writeFileAtomic(out.filePath("views.json").toStdString(),
                          QJsonDocument(doc).toJson().toStdString());
}

void ScriptedRun::finish(int exitCode, const QString& message) {
    if (m_finished) return;
    m_finished = true;
    m_poll.stop();
    m_timeout.stop();
    {
        const std::lock_guard lock(m_watchMutex);
        m_watchStop = true;
    }
    m_watchWake.notify_all();
    if (!message.isEmpty()) std::fprintf(stderr, "fvr-workstation: %s\n", qPrintable(message));
    emit done(exitCode, message);
    if (m_options.quit && exitCode == kScriptedTimeout) {
        // A load may still run, blocked in a read that no cancel reaches; leaving through the
        // event loop would wait for it (the study's worker is joined on the way out). Nothing
        // was written, so the process ends here.
        std::fflush(stdout);
        std::fflush(stderr);
        std::_Exit(exitCode);
    }
    if (m_options.quit) QCoreApplication::exit(exitCode);
}

} // namespace fvr::ui
