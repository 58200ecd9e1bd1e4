#include <fvr/ui/main_window.h>

#include <fvr/ui/pacs_dialog.h>
#include <fvr/ui/pacs_service.h>

#include <QCloseEvent>
#include <QDockWidget>
#include <QDragEnterEvent>
#include <QInputDialog>
#include <QLabel>
#include <QLayout>
#include <QMessageBox>
#include <QMimeData>
#include <QProgressBar>
#include <QPushButton>
#include <QScreen>
#include <QScrollArea>
#include <QSettings>
#include <QStatusBar>
#include <QStyle>
#include <QUndoStack>

#include <algorithm>
#include <cmath>

#include <fvr/core/xray/display_window.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/accuracy_readout.h>
#include <fvr/ui/app_info.h>
#include <fvr/ui/materials_controller.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/geometry_panel.h>
#include <fvr/ui/panels/messages_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/study_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_keys.h>
#include <fvr/ui/settings_model.h>

namespace fvr::ui {

MainWindow::MainWindow(QWidget* parent)
    : QMainWindow(parent), m_study(std::make_unique<StudyController>()),
      m_materials(std::make_unique<MaterialsController>()),
      m_accuracy(std::make_unique<AccuracyReadout>()) {
    m_model = new SettingsModel(this);
    setWindowTitle(QString::fromUtf8(applicationName()));
    setAcceptDrops(true);
    setDockNestingEnabled(true);
    // View 1 takes the Rendering settings (restorePanels); views 2-4 of compare mode start
    // with kernels to compare it with.
    m_viewSettings.assign(4, ViewSettings{});
    const core::Kernel compareKernels[3] = {core::Kernel::CatmullRom, core::Kernel::Nearest,
                                            core::Kernel::Sinc4};
    for (int i = 1; i < 4; ++i) m_viewSettings[i].kernel = compareKernels[i - 1];
    buildViews();
    buildDocks();
    buildMenus();
    connectStudy();
    connectMaterials();
    connect(m_accuracy.get(), &AccuracyReadout::message, this, &MainWindow::message);
    connect(m_accuracy.get(), &AccuracyReadout::measured, this, &MainWindow::accuracyMeasured);

    QSettings settings;
    restoreGeometry(settings.value(keys::kWindowGeometry).toByteArray());
    restoreState(settings.value(keys::kWindowState).toByteArray());
    if (!settings.contains(keys::kWindowGeometry)) resize(defaultWindowSize(screen()));
    // A small screen (a laptop's, or 1920 x 1080 at QT_SCALE_FACTOR=2, 960 x 540 in the
    // window's units): the panels as tabs, the window within it. From 1200 x 800 on the
    // layout stays as it was.
    if (const QScreen* s = screen();
        s && (s->availableGeometry().height() < 800 || s->availableGeometry().width() < 1200))
        fitInto(s->availableGeometry().size());
    rebuildRecentMenu();
    // The keys (1-6, R, F...) act at once: view 1 holds the focus, not the first spin box of a
    // panel, which would take the digits and letters for itself.
    if (!m_views.empty()) m_views[0]->setFocus(Qt::OtherFocusReason);
}

QSize MainWindow::defaultWindowSize(const QScreen* screen) {
    QSize size(1400, 900);
    // A small screen, or a high scale factor (QT_SCALE_FACTOR=2 makes 1920 x 1080 a 960 x 540
    // screen in the window's units): most of the screen's free area, never more.
    if (screen) size = size.boundedTo(screen->availableGeometry().size() * 0.95);
    return size;
}

void MainWindow::fitInto(const QSize& available) {
    // The right column's panels one above the other are taller than a small screen (or a
    // 1920 x 1080 one at QT_SCALE_FACTOR=2): then they become tabs of one group, and the
    // Messages panel joins them, so the window is as tall as its tallest panel.
    auto dockNamed = [this](const char* name) { return findChild<QDockWidget*>(name); };
    QDockWidget* display = dockNamed("dock.display");
    const auto tooBig = [&] {
        const QSize m = minimumSizeHint().expandedTo(minimumSize());
        return m.height() > available.height() || m.width() > available.width();
    };
    if (display && tooBig()) {
        for (const char* name : {"dock.study", "dock.rendering", "dock.messages"})
            if (QDockWidget* d = dockNamed(name); d && !tabifiedDockWidgets(display).contains(d))
                tabifyDockWidget(display, d);
        display->raise();
        if (layout()) layout()->activate(); // the new, smaller minimum before the resize
    }
    resize(size().boundedTo(available));
}

MainWindow::~MainWindow() {
    // The undo stack empties itself as it goes, after the Edit menu's actions went.
    if (m_undo) m_undo->disconnect(this);
    delete m_pacsDialog.data(); // its retrieve ends before the store and listener go
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
            [this](const StudySource& src, const QStringList& keys, const QStringList& labels,
                   const QString& prompt) {
                showProgress(false);
                if (!m_askForSeries) { // scripted: the default series, as fvr-render
                    message(tr("%1 holds several series: opening the default one (%2)")
                                .arg(src.path, labels.first()));
                    StudySource chosen = src;
                    chosen.seriesKey = keys.first();
                    return openStudy(chosen);
                }
                bool ok = false;
                const QString pick = QInputDialog::getItem(this, tr("Choose a series"), prompt,
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
    m_geometry = new GeometryPanel(this);
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
    // The C-arm beside the X-ray look: one tab group, so the column is no taller.
    QDockWidget* geometryDock =
        dock(tr("Geometry"), "dock.geometry", m_geometry, Qt::RightDockWidgetArea);
    tabifyDockWidget(xrayDock, geometryDock);
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
    m_backend->setContentsMargins(8, 0, 4, 0);
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

void MainWindow::applyWindowFromPanel() {
    if (m_syncing || m_views.empty()) return;
    const core::DisplayWindow w = m_display->window(currentTransmission());
    m_syncing = true;
    for (std::size_t i = 0; i < m_views.size(); ++i)
        if (i == 0 || (!m_difference && sameQuantity(*m_views[i], *m_views[0])))
            m_views[i]->setWindow(w);
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

void MainWindow::onStudyLoaded(const QString& name) {
    setWindowTitle(QStringLiteral("%1 — %2").arg(QString::fromUtf8(applicationName()), name));
    message(tr("Opened %1").arg(name));
    if (m_study->source().kind != StudySource::Kind::Phantom) addRecent(m_study->source().path);
    if (m_prior) closePrior(); // the prior was the last study's
    assignSpectra();
    const core::ViewFrame start =
        core::patientViewFrame(*m_study->volume(), core::RenderSettings{}.view);
    for (auto* v : m_views) v->setViewFrame(start);
    showCArmAngles(start);
    updateStudyInfo();
    startStudyHistory();
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
    // The status bar draws its message up to the renderer label: elided ("…") with a gap before
    // it, so that the two never run together (the Messages panel keeps the whole text).
    const int room = m_backend->isVisible() ? m_backend->x() - 16 : statusBar()->width() - 16;
    statusBar()->showMessage(
        statusBar()->fontMetrics().elidedText(text, Qt::ElideRight, std::max(room, 40)),
        error ? 10000 : 4000);
}

void MainWindow::closeEvent(QCloseEvent* e) {
    if (!confirmQuitDuringRetrieves()) {
        e->ignore();
        return;
    }
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
