// The main window's menus, toolbar and recent studies (the File menu's open dialogs).
#include <fvr/ui/main_window.h>

#include <QAction>
#include <QFileDialog>
#include <QFileInfo>
#include <QMenuBar>
#include <QSettings>
#include <QSignalBlocker>
#include <QToolBar>

#include <fvr/ui/pacs_service.h>
#include <fvr/ui/settings_keys.h>
#include <fvr/ui/settings_model.h>
#include <fvr/ui/xray_match.h>
#include <fvr/ui/xray_register.h>

namespace fvr::ui {

namespace {
constexpr int kMaxRecent = 8;
} // namespace

void MainWindow::buildMenus() {
    QMenu* file = menuBar()->addMenu(tr("&File"));
    QAction* openFolder =
        file->addAction(tr("Open DICOM &folder…"), this, &MainWindow::openFolderDialog);
    openFolder->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_D));
    QAction* openFile =
        file->addAction(tr("&Open volume file…"), this, &MainWindow::openFileDialog);
    openFile->setShortcut(QKeySequence::Open);
    // Short on the toolbar, whole in the menu and the tooltip: the main and Cine toolbars fit
    // side by side from about 1110 pixels on, their controls not hidden behind » at 1200.
    openFolder->setIconText(tr("Open folder"));
    openFile->setIconText(tr("Open file"));
    file->addAction(tr("Open built-in &chest phantom"), this,
                    [this] { openStudy(StudySource::chest()); });
    file->addAction(tr("Open built-in Shepp-&Logan phantom"), this,
                    [this] { openStudy(StudySource::phantom(128)); });
    m_recentMenu = file->addMenu(tr("&Recent studies"));
    QAction* prior =
        file->addAction(tr("Open p&rior beside it…"), this, &MainWindow::openPriorDialog);
    QAction* closePriorAction = file->addAction(tr("Close prior"), this, &MainWindow::closePrior);
    file->addSeparator();
    file->addAction(tr("Open &X-ray to match…"), this, &MainWindow::openXrayMatchDialog);
    file->addAction(tr("Re&gister to X-ray…"), this, &MainWindow::openRegisterDialog);
    file->addSeparator();
    QAction* shot =
        file->addAction(tr("Export &screenshot (PNG)…"), this, &MainWindow::exportScreenshotDialog);
    shot->setShortcut(QKeySequence::Save);
    QAction* projection = file->addAction(tr("Export &projection (16-bit PNG, .npy, .pfm, DICOM)…"),
                                          this, &MainWindow::exportProjectionDialog);
    QAction* sweep =
        file->addAction(tr("Export rotation s&weep…"), this, &MainWindow::exportSweepDialog);
    QAction* copy =
        file->addAction(tr("&Copy view to clipboard"), this, &MainWindow::copyToClipboard);
    copy->setShortcut(QKeySequence::Copy);
    file->addSeparator();
    QAction* saveSession =
        file->addAction(tr("Save sessio&n…"), this, &MainWindow::saveSessionDialog);
    saveSession->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_S));
    file->addAction(tr("Open sess&ion…"), this, &MainWindow::openSessionDialog);
    file->addSeparator();
    buildPacsMenu(file);
    // Nothing to export before a study is open: the items say so before any Save dialog.
    for (QAction* a : {shot, projection, sweep, copy, saveSession, prior, closePriorAction}) {
        a->setEnabled(false);
        connect(m_study.get(), &StudyController::studyLoaded, a, [a] { a->setEnabled(true); });
    }
    file->addSeparator();
    QAction* quit = file->addAction(tr("&Quit"), this, &QWidget::close);
    quit->setShortcut(QKeySequence::Quit);

    buildUndo();
    buildEditMenu();
    connectUserPresets();
    QMenu* view = menuBar()->addMenu(tr("&View"));
    QToolBar* tb = addToolBar(tr("Main"));
    tb->setObjectName("toolbar.main");
    tb->addAction(openFolder);
    tb->addAction(openFile);
    tb->addSeparator();
    buildViewMenu(view, tb);
    view->addSeparator();
    buildNavigation(view);
    buildReaderMenus(); // Cine and Study menus (cine_actions.cpp)
    buildMeasureMenu(); // Measure menu and toolbar (main_window_measure.cpp)
    buildPanelsMenu(view); // after every dock and toolbar exists
    buildHelpMenu();
}

void MainWindow::buildViewMenu(QMenu* view, QToolBar* tb) {
    const std::pair<core::PatientView, Qt::Key> views[] = {
        {core::PatientView::AP, Qt::Key_1},   {core::PatientView::PA, Qt::Key_2},
        {core::PatientView::Left, Qt::Key_3}, {core::PatientView::Right, Qt::Key_4},
        {core::PatientView::Head, Qt::Key_5}, {core::PatientView::Feet, Qt::Key_6}};
    for (const auto& [pv, key] : views) {
        QAction* a = view->addAction(QString::fromUtf8(core::patientViewName(pv)), this,
                                     [this, pv] { showPatientView(pv); });
        a->setShortcut(QKeySequence(key));
        a->setToolTip(tr("Patient view %1 (%2)")
                          .arg(QString::fromUtf8(core::patientViewName(pv)))
                          .arg(QKeySequence(key).toString()));
        tb->addAction(a);
    }
    QAction* reset = view->addAction(tr("&Reset view"), this, [this] {
        showPatientView(core::PatientView::AP);
        for (auto* v : m_views) v->resetPanZoom();
    });
    // R, and Shift+R (Caps Lock, or a user who types a capital R) the same.
    reset->setShortcuts({QKeySequence(Qt::Key_R), QKeySequence(Qt::SHIFT | Qt::Key_R)});
    reset->setIconText(tr("Reset"));
    tb->addAction(reset);
    view->addSeparator();
    tb->addSeparator();
    for (int n : {1, 2, 4}) {
        QAction* a = view->addAction(n == 1 ? tr("Single view") : tr("Compare %1 views").arg(n),
                                     this, [this, n] { setCompareCount(n); });
        a->setIconText(n == 1 ? tr("1 view") : tr("%1 views").arg(n));
        tb->addAction(a);
    }
    m_differenceAction = view->addAction(tr("&Difference to view 1"));
    m_differenceAction->setCheckable(true);
    connect(m_differenceAction, &QAction::toggled, this,
            [this](bool on) { setDifferenceMode(on); });
    view->addSeparator();
    m_overlayAction = view->addAction(tr("Performance &overlay"));
    m_overlayAction->setCheckable(true);
    m_overlayAction->setShortcut(QKeySequence(Qt::Key_F));
    m_overlayAction->setChecked(QSettings().value(keys::kViewOverlay, true).toBool());
    connect(m_overlayAction, &QAction::toggled, this, [this](bool on) {
        for (auto* v : m_views) v->setOverlayVisible(on);
    });
    for (auto* v : m_views) v->setOverlayVisible(m_overlayAction->isChecked());
    // A software OpenGL (llvmpipe …) is slower than the CPU renderer: the views use the CPU
    // there unless this is on. A hardware GPU is always used.
    m_softwareGpuAction = view->addAction(tr("Use a &software GPU (slower than the CPU)"));
    m_softwareGpuAction->setCheckable(true);
    m_softwareGpuAction->setChecked(m_model->rendering().softwareGpu);
    connect(m_softwareGpuAction, &QAction::toggled, this, [this](bool on) {
        RenderingPanel::Values r = m_model->rendering();
        r.softwareGpu = on;
        m_model->setRendering(r);
    });
    connect(m_model, &SettingsModel::renderingShown, m_softwareGpuAction,
            [this](const RenderingPanel::Values& r) {
                const QSignalBlocker block(m_softwareGpuAction);
                m_softwareGpuAction->setChecked(r.softwareGpu);
            });
    QAction* acc =
        view->addAction(tr("&Accuracy against ray casting"), this, &MainWindow::measureAccuracy);
    acc->setShortcut(QKeySequence(Qt::CTRL | Qt::Key_A));
    view->addAction(tr("Reset &zoom"), this, [this] {
        for (auto* v : m_views) v->resetPanZoom();
    });
}

void MainWindow::openStudy(const StudySource& source) {
    message(
        tr("Opening %1…")
            .arg(source.kind == StudySource::Kind::Phantom ? source.displayName() : source.path));
    // A retrieve asked before this no longer opens when it ends (it would replace this one).
    if (m_pacs) m_pacs->retrieves().studyOpened();
    m_study->open(source); // Recent studies get it once it opened (onStudyLoaded)
}

void MainWindow::addRecent(const QString& path) {
    QSettings s;
    QStringList recent = s.value(keys::kRecentStudies).toStringList();
    recent.removeAll(path);
    recent.prepend(path);
    while (recent.size() > kMaxRecent) recent.removeLast();
    s.setValue(keys::kRecentStudies, recent);
    s.setValue(keys::kLastFolder, QFileInfo(path).isDir() ? path : QFileInfo(path).absolutePath());
    rebuildRecentMenu();
}

void MainWindow::rebuildRecentMenu() {
    if (!m_recentMenu) return;
    m_recentMenu->clear();
    const QStringList recent = QSettings().value(keys::kRecentStudies).toStringList();
    for (const QString& p : recent)
        m_recentMenu->addAction(p, this, [this, p] { openStudy(StudySource::fromPath(p)); });
    m_recentMenu->setEnabled(!recent.isEmpty());
}

void MainWindow::openFileDialog() {
    const QString path = QFileDialog::getOpenFileName(
        this, tr("Open volume file"), QSettings().value(keys::kLastFolder).toString(),
        tr("Volumes and DICOM files (*.mhd *.mha *.nii *.nii.gz *.dcm *.dicom DICOMDIR);;"
           "All files (*)"));
    if (!path.isEmpty()) openStudy(StudySource::fromPath(path));
}

void MainWindow::openXrayMatchDialog() {
    const QString path = QFileDialog::getOpenFileName(
        this, tr("Open X-ray to match"), QSettings().value(keys::kLastFolder).toString(),
        tr("DICOM X-rays (XA, RF, DX, CR) (*.dcm *.dicom *);;All files (*)"));
    if (!path.isEmpty()) matchXray(path);
}

XrayMatchDialog* MainWindow::matchXray(const QString& path) {
    if (!m_xrayMatch) {
        m_xrayMatch = new XrayMatchDialog(this);
        connect(m_xrayMatch, &XrayMatchDialog::registerRequested, this,
                [this](const QString& p, int frame) { registerXray(p, frame); });
    }
    const auto volume = m_study->volume();
    const auto spectrum = m_study->spectrum();
    m_xrayMatch->setStudy(volume, spectrum ? spectrum->mapping : m_model->rendering().mapping);
    if (!m_xrayMatch->openXray(path))
        message(tr("X-ray %1: %2").arg(path, m_xrayMatch->errorText()));
    else
        message(tr("X-ray %1 matched: its C-arm, detector and pitch").arg(path));
    m_xrayMatch->show();
    m_xrayMatch->raise();
    return m_xrayMatch;
}

void MainWindow::openRegisterDialog() {
    if (m_xrayMatch && m_xrayMatch->isVisible() && m_xrayMatch->xray() && m_xrayMatch->drr()) {
        registerXray(QString::fromStdString(m_xrayMatch->xray()->file.string()),
                     m_xrayMatch->frame());
        return;
    }
    const QString path = QFileDialog::getOpenFileName(
        this, tr("Register to X-ray"), QSettings().value(keys::kLastFolder).toString(),
        tr("X-rays: DICOM XA, RF, DX, CR, RT Image; .npy, .pfm, .png with their JSON sidecar "
           "(*.dcm *.dicom *.npy *.pfm *.png *);;All files (*)"));
    if (!path.isEmpty()) registerXray(path);
}

XrayRegisterDialog* MainWindow::registerXray(const QString& path, int frame) {
    if (!m_register) {
        m_register = new XrayRegisterDialog(this);
        connect(m_register, &XrayRegisterDialog::message, this,
                [this](const QString& text, bool error) { message(text, error); });
    }
    const auto spectrum = m_study->spectrum();
    m_register->setStudy(m_study->volume(),
                         spectrum ? spectrum->mapping : m_model->rendering().mapping);
    if (!m_register->openXray(path, frame))
        message(tr("Register to X-ray %1: %2").arg(path, m_register->errorText()), true);
    m_register->show();
    m_register->raise();
    return m_register;
}

void MainWindow::openFolderDialog() {
    const QString path = QFileDialog::getExistingDirectory(
        this, tr("Open DICOM folder"), QSettings().value(keys::kLastFolder).toString());
    if (!path.isEmpty()) openStudy(StudySource::fromPath(path));
}

} // namespace fvr::ui
