#include <fvr/ui/main_window.h>

#include <fvr/ui/pacs_dialog.h>
#include <fvr/ui/pacs_service.h>

#include <QCloseEvent>
#include <QDockWidget>
#include <QDragEnterEvent>
#include <QInputDialog>
#include <QLabel>
#include <QMessageBox>
#include <QMimeData>
#include <QProgressBar>
#include <QPushButton>
#include <QScrollArea>
#include <QSettings>
#include <QStatusBar>
#include <QStyle>

#include <algorithm>
#include <cmath>

#include <fvr/core/xray/display_window.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/accuracy_readout.h>
#include <fvr/ui/app_info.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/messages_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/study_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_keys.h>
#include <fvr/ui/settings_model.h>

namespace fvr::ui {

MainWindow::MainWindow(QWidget* parent)
    : QMainWindow(parent), m_study(std::make_unique<StudyController>()),
      m_accuracy(std::make_unique<AccuracyReadout>()) {
    m_model = new SettingsModel(this);
    setWindowTitle(QString::fromUtf8(applicationName()));
    setAcceptDrops(true);
    setDockNestingEnabled(true);
    m_viewSettings.assign(4, ViewSettings{});
    const core::Kernel compareKernels[4] = {core::Kernel::Linear, core::Kernel::CatmullRom,
                                            core::Kernel::Nearest, core::Kernel::Sinc4};
    for (int i = 0; i < 4; ++i) m_viewSettings[i].kernel = compareKernels[i];
    buildViews();
    buildDocks();
    buildMenus();
    connectStudy();
    connect(m_accuracy.get(), &AccuracyReadout::message, this, &MainWindow::message);
    connect(m_accuracy.get(), &AccuracyReadout::measured, this, &MainWindow::accuracyMeasured);

    QSettings settings;
    restoreGeometry(settings.value(keys::kWindowGeometry).toByteArray());
    restoreState(settings.value(keys::kWindowState).toByteArray());
    if (!settings.contains(keys::kWindowGeometry)) resize(1400, 900);
    rebuildRecentMenu();
}

MainWindow::~MainWindow() {
    delete m_pacsDialog.data(); // its retrieve ends before the store and listener go
    if (m_polyCancel) m_polyCancel->cancel(); // the material job ends at its next check
}

void MainWindow::connectStudy() {
    connect(m_study.get(), &StudyController::progress, this,
            [this](double f, const QString& stage) {
                showProgress(true);
                m_progress->setValue(int(std::lround(f * 1000)));
                const bool cancelling = m_study->cancelling();
                m_progress->setFormat(cancelling ? tr("cancelling… (%1 ends first)").arg(stage)
                                                 : QStringLiteral("%1 %p%").arg(stage));
                m_cancel->setEnabled(!cancelling);
            });
    connect(m_study.get(), &StudyController::studyLoaded, this, &MainWindow::onStudyLoaded);
    connect(m_study.get(), &StudyController::spectrumReady, this, &MainWindow::onSpectrumReady);
    connect(m_study.get(), &StudyController::failed, this,
            [this](const QString& title, const QString& details) {
                showProgress(false);
                message(title + ": " + details, true);
                auto* box =
                    new QMessageBox(QMessageBox::Warning, title, details, QMessageBox::Ok, this);
                box->setAttribute(Qt::WA_DeleteOnClose);
                box->setTextInteractionFlags(Qt::TextSelectableByMouse);
                box->setModal(false);
                box->show();
            });
    connect(m_study.get(), &StudyController::cancelled, this, [this] {
        showProgress(false);
        showSpectrumSettingsInEffect(true);
        // A cancelled kernel change (gridding on): view 1 and the panel keep the kernel in use.
        const auto main = m_study->spectrum();
        if (!m_views.empty() && main && main->deapodizedFor &&
            *main->deapodizedFor != m_viewSettings[0].kernel) {
            m_viewSettings[0].kernel = *main->deapodizedFor;
            if (m_rendering->appliesTo() <= 1) showViewSettings(m_viewSettings[0]);
        }
        updateCompareKernels(); // the gridding correction in effect; views say what they wait for
        message(tr("Cancelled; the previous study and its settings stay."));
    });
    connect(m_study.get(), &StudyController::idle, this, [this] { showProgress(false); });
    connect(m_study.get(), &StudyController::warningsChanged, this, [this](const QStringList& w) {
        for (const auto& s : w) message(tr("Warning: %1").arg(s), true);
        updateStudyInfo();
    });
    connect(m_study.get(), &StudyController::seriesChoiceNeeded, this,
            [this](const StudySource& src, const QStringList& keys, const QStringList& labels) {
                showProgress(false);
                if (!m_askForSeries) { // scripted: the default series, as fvr-render
                    message(tr("%1 holds several series: opening the default one (%2)")
                                .arg(src.path, labels.first()));
                    StudySource chosen = src;
                    chosen.seriesKey = keys.first();
                    return openStudy(chosen);
                }
                bool ok = false;
                const QString pick = QInputDialog::getItem(
                    this, tr("Choose a series"), tr("%1 holds several series:").arg(src.path),
                    labels, 0, false, &ok);
                if (!ok) return;
                StudySource chosen = src;
                chosen.seriesKey = keys.at(labels.indexOf(pick));
                openStudy(chosen);
            });
}

void MainWindow::measureAccuracy() {
    if (m_views.empty()) return;
    m_accuracy->measure(*m_views[0], *m_study);
}

void MainWindow::buildDocks() {
    auto dock = [this](const QString& title, const char* name, QWidget* panel,
                       Qt::DockWidgetArea area) {
        auto* d = new QDockWidget(title, this);
        d->setObjectName(name);
        d->setWidget(panel);
        addDockWidget(area, d);
        return d;
    };
    m_studyPanel = new StudyPanel(this);
    m_rendering = new RenderingPanel(this);
    m_display = new DisplayPanel(this);
    m_xray = new XrayPanel(this);
    m_messages = new MessagesPanel(this);
    QDockWidget* studyDock = dock(tr("Study"), "dock.study", m_studyPanel, Qt::RightDockWidgetArea);
    QDockWidget* renderDock =
        dock(tr("Rendering"), "dock.rendering", m_rendering, Qt::RightDockWidgetArea);
    QDockWidget* displayDock =
        dock(tr("Display"), "dock.display", m_display, Qt::RightDockWidgetArea);
    // The X-ray panel (its polychromatic rows) scrolls where it is taller than the space, instead
    // of making the window taller than the screen; as wide as the panel needs.
    auto* xrayScroll = new QScrollArea(this);
    xrayScroll->setWidget(m_xray);
    xrayScroll->setWidgetResizable(true);
    xrayScroll->setFrameShape(QFrame::NoFrame);
    xrayScroll->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
    xrayScroll->setMinimumWidth(m_xray->minimumSizeHint().width() +
                                style()->pixelMetric(QStyle::PM_ScrollBarExtent));
    // Tall enough for the panel without its polychromatic rows (hidden until that output is
    // chosen): only those scroll.
    xrayScroll->setMinimumHeight(m_xray->minimumSizeHint().height());
    QDockWidget* xrayDock = dock(tr("X-ray"), "dock.xray", xrayScroll, Qt::RightDockWidgetArea);
    tabifyDockWidget(displayDock, xrayDock);
    displayDock->raise();
    QDockWidget* msgDock =
        dock(tr("Messages"), "dock.messages", m_messages, Qt::BottomDockWidgetArea);
    resizeDocks({msgDock}, {110}, Qt::Vertical);
    resizeDocks({studyDock, renderDock, displayDock}, {220, 260, 300}, Qt::Vertical);
    buildStatusBar();
    // The panels show the model (from the restored settings on); they write the user's edits
    // into it, and the window acts on the model's change signals, never on the widgets.
    connect(m_model, &SettingsModel::renderingShown, m_rendering, &RenderingPanel::setValues);
    connect(m_model, &SettingsModel::xrayShown, m_xray, &XrayPanel::setValues);
    restorePanels();
    connectPanels();
}

void MainWindow::buildStatusBar() {
    m_backend = new QLabel(tr("Renderer: —"), this);
    statusBar()->addPermanentWidget(m_backend);
    m_progress = new QProgressBar(this);
    m_progress->setRange(0, 1000);
    m_progress->setMinimumWidth(320);
    m_progress->setVisible(false);
    statusBar()->addPermanentWidget(m_progress);
    m_cancel = new QPushButton(tr("Cancel"), this);
    m_cancel->setVisible(false);
    statusBar()->addPermanentWidget(m_cancel);
    connect(m_cancel, &QPushButton::clicked, this, [this] {
        m_study->cancel();
        // At once: the job may take a moment to stop (FFTW's planner ends its plan first).
        if (m_study->cancelling()) {
            m_progress->setFormat(tr("cancelling…"));
            m_cancel->setEnabled(false);
        }
    });
}

void MainWindow::restorePanels() {
    const QSettings s;
    m_model->setRendering(RenderingPanel::load(s), SettingsModel::Notify::No);
    m_display->setValues(
        DisplayPanel::load(s, m_display->values())); // the window follows the image
    m_model->setXray(XrayPanel::load(s), SettingsModel::Notify::No);
    for (auto* v : m_views) {
        v->setEffects(currentEffects());
        v->setTargetFps(m_model->rendering().targetFps);
        v->setAllowSoftwareGpu(m_model->rendering().softwareGpu);
    }
    m_viewSettings[0] = m_model->viewSettings();
    if (!m_views.empty()) m_views[0]->setSettings(m_viewSettings[0]);
    m_study->setSpectrumSettings(spectrumSettingsFromPanel());
}

void MainWindow::connectPanels() {
    connect(m_rendering, &RenderingPanel::changed, m_model,
            [this] { m_model->setRendering(m_rendering->values()); });
    connect(m_xray, &XrayPanel::changed, m_model, [this] { m_model->setXray(m_xray->values()); });
    connect(m_rendering, &RenderingPanel::appliesToChanged, this, [this](int slot) {
        if (slot <= 0 || slot > int(m_views.size())) return;
        // What the view is set to (it may still wait for its kernel's spectrum).
        showViewSettings(m_viewSettings[std::size_t(slot - 1)]);
    });
    connect(m_display, &DisplayPanel::windowChanged, this, &MainWindow::applyWindowFromPanel);
    connect(m_display, &DisplayPanel::presetRequested, this, &MainWindow::applyPreset);
    connectSettings();
    if (isTransmission(m_model->xray().output) || isPolychromatic(m_model->xray().output))
        applyOutput(true);
}

void MainWindow::connectSettings() {
    connect(m_model, &SettingsModel::viewSettingsChanged, this, &MainWindow::applyRenderSettings);
    connect(m_model, &SettingsModel::voxelModelChanged, this, &MainWindow::applyVoxelModel);
    connect(m_model, &SettingsModel::spectrumSettingsChanged, this,
            &MainWindow::applySpectrumSettings);
    connect(m_model, &SettingsModel::valueMappingChanged, this, &MainWindow::applyValueMapping);
    connect(m_model, &SettingsModel::targetFpsChanged, this, [this](int fps) {
        for (auto* v : m_views) v->setTargetFps(m_difference ? 0 : fps);
        saveRenderingSettings();
    });
    connect(m_model, &SettingsModel::frameOptionsChanged, this, &MainWindow::applyEffects);
    connect(m_model, &SettingsModel::rendererChoiceChanged, this, [this] {
        for (auto* v : m_views) v->setAllowSoftwareGpu(m_model->rendering().softwareGpu);
        saveRenderingSettings();
    });
    connect(m_model, &SettingsModel::outputChanged, this, [this] { applyOutput(true); });
    connect(m_model, &SettingsModel::beamChanged, this, [this] { applyOutput(false); });
    connect(m_model, &SettingsModel::effectsChanged, this, &MainWindow::applyEffects);
    connect(m_model, &SettingsModel::polychromaticChanged, this, [this] {
        QSettings st;
        XrayPanel::save(st, m_model->xray());
        pushPolychromatic();
    });
}

void MainWindow::applyVoxelModel() {
    // Only the voxel model of the views "Applies to" names: their kernels and sizes stay (in
    // compare mode each view keeps its own). Same spectrum: nothing is preprocessed again.
    const core::VoxelModel model = m_model->rendering().voxelModel;
    const int slot = m_rendering->appliesTo();
    for (int i = 0; i < int(m_views.size()); ++i) {
        if (m_compareCount > 1 && slot > 0 && slot - 1 != i) continue;
        ViewSettings s = m_views[i]->settings();
        s.voxelModel = model;
        m_viewSettings[i].voxelModel = model;
        m_views[i]->setSettings(s);
    }
    saveRenderingSettings();
}

void MainWindow::saveRenderingSettings() {
    RenderingPanel::Values v = m_model->rendering();
    // The startup kernel, size and voxel model are view 1's (in compare mode the panel may be
    // showing another view's).
    v.kernel = m_viewSettings[0].kernel;
    v.size = m_viewSettings[0].size;
    if (!m_views.empty()) v.voxelModel = m_views[0]->settings().voxelModel;
    QSettings st;
    RenderingPanel::save(st, v);
}

void MainWindow::applyRenderSettings() {
    const ViewSettings s = m_model->viewSettings();
    const int slot = m_rendering->appliesTo();
    for (int i = 0; i < int(m_views.size()); ++i) {
        if (m_compareCount > 1 && slot > 0 && slot - 1 != i) continue;
        m_viewSettings[i] = s;
        if (m_compareCount > 1) m_views[i]->setTitle(viewTitle(i, s));
    }
    saveRenderingSettings();
    // A spectrum deapodized for another kernel cannot render this one: view 1's kernel is the
    // main spectrum's, the others get their own (assignSpectra switches each view when its
    // spectrum is ready).
    if (m_model->rendering().deapodize)
        applySpectrumSettings(); // also updateCompareKernels()
    else
        updateCompareKernels();
}

SpectrumSettings MainWindow::spectrumSettingsFromPanel() const {
    return RenderingPanel::spectrumSettings(m_model->rendering(), m_viewSettings[0].kernel);
}

void MainWindow::applySpectrumSettings() {
    const SpectrumSettings s = spectrumSettingsFromPanel();
    saveRenderingSettings();
    if (m_study->volume() && !(s == m_study->spectrumSettings()))
        message(tr("Preprocessing again (%1, oversampling %2, %3)…")
                    .arg(QString::fromUtf8(core::transformName(s.transform)))
                    .arg(s.oversampling)
                    .arg(QString::fromUtf8(core::valueMappingName(s.mapping))) +
                (s.deapodizeFor ? tr(", deapodized for %1")
                                      .arg(QString::fromUtf8(core::kernelName(*s.deapodizeFor)))
                                : QString()));
    m_study->setSpectrumSettings(s);
    updateCompareKernels(); // the gridding correction may have changed
    if (m_study->volume() && m_study->targetSettings().mapping != s.mapping) {
        // The study cannot have these values (attenuation of data that are not HU): the panel
        // shows what is in effect; the request stays for the next study.
        RenderingPanel::Values r = m_model->rendering();
        r.mapping = m_study->targetSettings().mapping;
        m_model->setRendering(r, SettingsModel::Notify::No);
        message(tr("This study's values are not Hounsfield units: they stay %1; studies in HU "
                   "open with %2.")
                    .arg(QString::fromUtf8(core::valueMappingName(r.mapping)),
                         QString::fromUtf8(core::valueMappingName(s.mapping))),
                true);
    }
}

void MainWindow::applyValueMapping() {
    if (isTransmission(m_model->xray().output) &&
        m_model->rendering().mapping == core::ValueMapping::Raw) {
        message(tr("Raw values have no transmission: the output is line integrals again."));
        showOutput(XrayOutput::LineIntegrals);
        applyOutput(true);
    }
    m_rewindow = true; // new values, new range: window again when the spectrum is ready
    applySpectrumSettings();
}

void MainWindow::applyWindowFromPanel() {
    if (m_syncing || m_views.empty()) return;
    const core::DisplayWindow w = m_display->window(currentTransmission());
    m_syncing = true;
    for (std::size_t i = 0; i < m_views.size(); ++i)
        if (i == 0 || !m_difference) m_views[i]->setWindow(w);
    m_syncing = false;
    QSettings st;
    DisplayPanel::save(st, m_display->values());
}

void MainWindow::syncWindowToPanel(const core::DisplayWindow& w, WindowPreset from) {
    m_display->showWindow(w, from);
}

void MainWindow::applyPreset(WindowPreset preset) {
    if (m_views.empty()) return;
    auto p = m_views[0]->projection();
    if (!p) return;
    const core::Transmission t = currentTransmission();
    // The window applies to what the film shows (the log exposure with transmission).
    const std::vector<float> values = core::windowedValues(std::move(p->pixels), t);
    syncWindowToPanel(presetWindow(preset, values, m_display->values().invert), preset);
    applyWindowFromPanel();
}

void MainWindow::showViewSettings(const ViewSettings& s) {
    RenderingPanel::Values r = m_model->rendering();
    r.kernel = s.kernel;
    r.size = s.size;
    r.voxelModel = s.voxelModel;
    m_model->setRendering(r, SettingsModel::Notify::No);
}

void MainWindow::showOutput(XrayOutput o) {
    XrayPanel::Values x = m_model->xray();
    x.output = o;
    m_model->setXray(x, SettingsModel::Notify::No); // the caller applies it
}

core::Transmission MainWindow::currentTransmission() const { return m_model->transmission(); }

FrameEffects MainWindow::currentEffects() const {
    FrameEffects e;
    const RenderingPanel::Values& r = m_model->rendering();
    e.depthCue = m_model->depthCue();
    e.filter = m_model->sliceFilter();
    e.clip = r.clip;
    e.nonNegative = r.nonNegative;
    e.pixelAperture = r.pixelAperture;
    return e;
}

void MainWindow::applyEffects() {
    const FrameEffects e = currentEffects();
    for (auto* v : m_views) v->setEffects(e);
    {
        QSettings st;
        XrayPanel::save(st, m_model->xray());
    }
    saveRenderingSettings();
    if (e.depthCue > 0 && std::any_of(m_views.begin(), m_views.end(), [](ProjectionView* v) {
            return v->settings().kernel == core::Kernel::Nearest;
        }))
        message(tr("Depth cueing needs the derivative of the interpolation kernel: views with "
                   "nearest neighbour "
                   "are not rendered until you choose linear or better."),
                true);
}

void MainWindow::applyOutput(bool resetWindow) {
    const bool transmission = isTransmission(m_model->xray().output);
    {
        QSettings st;
        XrayPanel::save(st, m_model->xray());
    }
    if (transmission && m_model->rendering().mapping == core::ValueMapping::Raw) {
        // Beer-Lambert needs attenuation: switch the values to mu (preprocesses again).
        const auto vol = m_study->volume();
        if (vol && vol->units != core::ValueUnits::HounsfieldUnits) {
            message(tr("Transmitted intensity needs attenuation values; this study's values are "
                       "not Hounsfield "
                       "units (%1), so the output stays line integrals.")
                        .arg(QString::fromUtf8(core::unitsName(vol->units))),
                    true);
            showOutput(XrayOutput::LineIntegrals);
            return applyOutput(true);
        }
        message(tr("Transmitted intensity needs attenuation values: switching the values to μ."));
        RenderingPanel::Values r = m_model->rendering();
        r.mapping = core::ValueMapping::Mu;
        m_model->setRendering(r, SettingsModel::Notify::No);
        applyValueMapping();
        m_rewindow = true; // the window follows the new spectrum's image (onSpectrumReady)
    }
    if (resetWindow) {
        // Film look (bone white) for transmission. The window from the image (log exposure for
        // transmission); before any image, the first three decades of exposure.
        syncWindowToPanel({-3.0, 0.0, transmission, currentTransmission()}, WindowPreset::Custom);
        applyWindowFromPanel();
        applyPreset(WindowPreset::Auto);
    } else {
        applyWindowFromPanel();
    }
    applyPolychromatic();
}

void MainWindow::onStudyLoaded(const QString& name) {
    setWindowTitle(QStringLiteral("%1 — %2").arg(QString::fromUtf8(applicationName()), name));
    message(tr("Opened %1").arg(name));
    if (m_study->source().kind != StudySource::Kind::Phantom) addRecent(m_study->source().path);
    assignSpectra();
    for (auto* v : m_views)
        v->setViewFrame(core::patientViewFrame(*m_study->volume(), core::PatientView::AP));
    updateStudyInfo();
}

void MainWindow::onSpectrumReady() {
    // A newer preprocessing started after this one (the user changed settings meanwhile): the
    // views show this spectrum, but the panel keeps the newer settings and the progress bar.
    const bool newer = m_study->newerJobStarted();
    if (!newer) {
        showProgress(false);
        // The controller may have adjusted the settings (e.g. raw values for non-HU data).
        showSpectrumSettingsInEffect(false);
    }
    if (!newer && isTransmission(m_model->xray().output) &&
        m_study->spectrumSettings().mapping == core::ValueMapping::Raw) {
        message(tr("This study integrates raw values (not Hounsfield units): no transmitted "
                   "intensity, the output "
                   "is line integrals."),
                true);
        showOutput(XrayOutput::LineIntegrals);
        applyOutput(true);
    }
    assignSpectra();
    if (m_rewindow && !newer) {
        m_rewindow = false;
        applyPreset(WindowPreset::Auto);
    }
    updateStudyInfo();
}

void MainWindow::showSpectrumSettingsInEffect(bool withGridding) {
    const SpectrumSettings& s = m_study->spectrumSettings();
    RenderingPanel::Values r = m_model->rendering();
    r.mapping = s.mapping;
    r.transform = s.transform;
    r.oversampling = s.oversampling;
    // The gridding correction shows in the spectrum only for a kernel it helps.
    if (withGridding && core::griddingCorrectionHelps(m_viewSettings[0].kernel))
        r.deapodize = s.deapodizeFor.has_value();
    m_model->setRendering(r, SettingsModel::Notify::No);
    updateSpectrumMemory();
}

void MainWindow::updateStudyInfo() {
    m_studyPanel->showStudy(*m_study);
    updateSpectrumMemory();
}

void MainWindow::updateSpectrumMemory() {
    if (!m_rendering || !m_study->spectrum()) return;
    // While a new main spectrum is prepared the panel shows its settings: say both.
    const SpectrumSettings& target = m_study->targetSettings();
    const bool preparing = !(target == m_study->spectrumSettings());
    m_rendering->setSpectrumMiB(
        m_study->spectraMiB(), m_study->spectrumCount(),
        preparing ? std::optional(m_study->estimatedSpectrumMiB(target) * m_study->spectrumCount())
                  : std::nullopt);
}

void MainWindow::showProgress(bool on) {
    m_progress->setVisible(on);
    m_cancel->setVisible(on);
}

void MainWindow::message(const QString& text, bool error) {
    m_messages->add(text);
    statusBar()->showMessage(text, error ? 10000 : 4000);
}

void MainWindow::closeEvent(QCloseEvent* e) {
    m_study->cancel();
    QSettings s;
    s.setValue(keys::kWindowGeometry, saveGeometry());
    s.setValue(keys::kWindowState, saveState());
    s.setValue(keys::kViewOverlay, m_overlayAction->isChecked());
    QMainWindow::closeEvent(e);
}

void MainWindow::dragEnterEvent(QDragEnterEvent* e) {
    if (e->mimeData()->hasUrls()) e->acceptProposedAction();
}

void MainWindow::dropEvent(QDropEvent* e) {
    for (const QUrl& u : e->mimeData()->urls())
        if (u.isLocalFile()) {
            openStudy(StudySource::fromPath(u.toLocalFile()));
            return;
        }
}

} // namespace fvr::ui
