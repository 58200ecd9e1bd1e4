// The workstation's state (workstation_state.h) on screen: read from and applied to the views
// and panels, undo/redo of the user's changes, and saved sessions.
#include <fvr/ui/main_window.h>

#include <QAction>
#include <QFileDialog>
#include <QFileInfo>
#include <QMenu>
#include <QMenuBar>
#include <QSettings>
#include <QSignalBlocker>
#include <QTimer>
#include <QUndoStack>

#include <fvr/core/errors.h>
#include <fvr/ui/app_info.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/geometry_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/settings_keys.h>
#include <fvr/ui/settings_model.h>

namespace fvr::ui {

namespace {

/** One change the user made: the state before and after it. Pushed once the change is made
 *  (its first redo does nothing). */
class StateCommand : public QUndoCommand {
public:
    StateCommand(MainWindow* window, WorkstationState before, WorkstationState after)
        : m_window(window), m_before(std::move(before)), m_after(std::move(after)) {
        setText(m_after.changeFrom(m_before));
    }
    void undo() override { m_window->applyState(m_before); }
    void redo() override {
        if (m_done) m_window->applyState(m_after);
        m_done = true;
    }

private:
    MainWindow* m_window;
    WorkstationState m_before, m_after;
    bool m_done = false;
};

constexpr int kSessionFormat = 1;

} // namespace

WorkstationState MainWindow::currentState() const {
    WorkstationState st;
    st.compareCount = m_compareCount;
    st.difference = m_difference;
    for (std::size_t i = 0; i < st.compareSlots.size() && i < m_viewSettings.size(); ++i)
        st.compareSlots[i] = m_viewSettings[i];
    if (!m_views.empty()) st.frame = m_views[0]->viewFrame();
    for (const ProjectionView* v : m_views) st.views.push_back({v->window(), v->zoom(), v->pan()});
    st.rendering = m_model->rendering();
    st.xray = m_model->xray();
    return st;
}

void MainWindow::applyState(const WorkstationState& st) {
    m_applyingState = true;
    if (st.compareCount != m_compareCount) setCompareCount(st.compareCount);
    m_rendering->setViewCount(m_compareCount); // "Applies to": all views
    // The render settings with view 1's kernel, size and voxel model (the panel's "All views");
    // then each slot its own.
    RenderingPanel::Values r = st.rendering;
    r.kernel = st.compareSlots[0].kernel;
    r.size = st.compareSlots[0].size;
    r.voxelModel = st.compareSlots[0].voxelModel;
    m_model->setRendering(r);
    m_model->setXray(st.xray);
    for (std::size_t i = 0; i < st.compareSlots.size(); ++i) m_viewSettings[i] = st.compareSlots[i];
    for (std::size_t i = 0; i < m_views.size(); ++i) {
        m_views[i]->setSettings(m_viewSettings[i]);
        if (m_compareCount > 1) m_views[i]->setTitle(viewTitle(int(i), m_viewSettings[i]));
    }
    m_geometry->setValues({st.compareSlots[0].projection, st.compareSlots[0].cone});
    saveRenderingSettings();
    updateCompareKernels();
    if (st.difference != m_difference) setDifferenceMode(st.difference);
    for (auto* v : m_views) v->setViewFrame(st.frame);
    showCArmAngles(st.frame);
    m_syncing = true;
    for (std::size_t i = 0; i < m_views.size() && i < st.views.size(); ++i) {
        core::DisplayWindow w = m_views[i]->window(); // keeps the output's transmission
        w.low = st.views[i].window.low;
        w.high = st.views[i].window.high;
        w.invert = st.views[i].window.invert;
        m_views[i]->setWindow(w);
        m_views[i]->setZoom(st.views[i].zoom);
        m_views[i]->setPan(st.views[i].pan);
    }
    m_syncing = false;
    if (!m_views.empty()) syncWindowToPanel(m_views[0]->window(), WindowPreset::Custom);
    // The windows are the state's: no automatic window when the new spectra arrive.
    m_rewindow = false;
    m_polyRewindow = false;
    m_applyingState = false;
    m_stateTimer->stop();
    m_userChange = false;
    m_recorded = currentState();
}

void MainWindow::noteStateChange(bool byUser, ChangeKind kind) {
    if (m_applyingState || !m_stateTimer) return; // (the first views come before the stack)
    if (byUser && m_userChange && m_stateTimer->isActive() && kind != m_pendingKind) {
        // The step before ends with its last change (this one is already on screen).
        if (!m_lastOfStep.sameAs(m_recorded))
            m_undo->push(new StateCommand(this, m_recorded, m_lastOfStep));
        m_recorded = m_lastOfStep;
        m_userChange = false;
    }
    if (byUser) m_pendingKind = kind;
    m_userChange = m_userChange || byUser;
    m_lastOfStep = currentState();
    m_stateTimer->start();
    emit stateChangeNoted();
}

void MainWindow::recordState() {
    m_stateTimer->stop();
    for (const ProjectionView* v : m_views)
        if (v->progressive().interacting()) { // a drag: one step when it ends
            m_stateTimer->start();
            return;
        }
    WorkstationState now = currentState();
    if (m_userChange && !now.sameAs(m_recorded))
        m_undo->push(new StateCommand(this, m_recorded, now));
    m_userChange = false;
    m_recorded = std::move(now); // what changed by itself (an automatic window) is absorbed
}

void MainWindow::buildUndo() {
    m_undo = new QUndoStack(this);
    m_stateTimer = new QTimer(this);
    m_stateTimer->setSingleShot(true);
    // A burst of changes (a drag, a spin box's steps, the wheel) becomes one undo step.
    m_stateTimer->setInterval(400);
    connect(m_stateTimer, &QTimer::timeout, this, &MainWindow::recordState);
    for (auto signal :
         {&SettingsModel::viewSettingsChanged, &SettingsModel::voxelModelChanged,
          &SettingsModel::spectrumSettingsChanged, &SettingsModel::valueMappingChanged,
          &SettingsModel::frameOptionsChanged, &SettingsModel::rendererChoiceChanged,
          &SettingsModel::outputChanged, &SettingsModel::beamChanged,
          &SettingsModel::effectsChanged, &SettingsModel::polychromaticChanged})
        connect(m_model, signal, this, [this] { noteStateChange(true, ChangeKind::Settings); });
    connect(m_model, &SettingsModel::targetFpsChanged, this,
            [this] { noteStateChange(true, ChangeKind::Settings); });
    connect(m_display, &DisplayPanel::windowChanged, this,
            [this] { noteStateChange(true, ChangeKind::Window); });
    connect(m_display, &DisplayPanel::presetRequested, this,
            [this] { noteStateChange(true, ChangeKind::Window); });
    connect(m_geometry, &GeometryPanel::changed, this,
            [this] { noteStateChange(true, ChangeKind::Settings); });
    connect(m_geometry, &GeometryPanel::anglesChanged, this,
            [this] { noteStateChange(true, ChangeKind::View); });
    m_recorded = currentState();
}

void MainWindow::flushStateChange() {
    if (m_stateTimer->isActive()) recordState();
}

void MainWindow::buildEditMenu() {
    QMenu* edit = menuBar()->addMenu(tr("&Edit"));
    // Own actions rather than QUndoStack's: a change still settling (within the 400 ms) is
    // recorded before it is undone, and Undo is offered for it.
    m_undoAction = edit->addAction(tr("&Undo"), this, &MainWindow::undo);
    m_undoAction->setShortcut(QKeySequence::Undo);
    m_redoAction = edit->addAction(tr("&Redo"), this, &MainWindow::redo);
    // The platform's redo keys (Ctrl+Shift+Z here), and Ctrl+Y as other viewers take it.
    QList<QKeySequence> redoKeys = QKeySequence::keyBindings(QKeySequence::Redo);
    if (!redoKeys.contains(QKeySequence(Qt::CTRL | Qt::Key_Y)))
        redoKeys.append(QKeySequence(Qt::CTRL | Qt::Key_Y));
    m_redoAction->setShortcuts(redoKeys);
    const auto update = [this] {
        const bool settling = m_userChange && m_stateTimer->isActive();
        m_undoAction->setEnabled(m_undo->canUndo() || settling);
        m_undoAction->setText(
            settling || !m_undo->canUndo() ? tr("&Undo") : tr("&Undo %1").arg(m_undo->undoText()));
        m_redoAction->setEnabled(m_undo->canRedo() && !settling);
        m_redoAction->setText(m_undo->canRedo() ? tr("&Redo %1").arg(m_undo->redoText())
                                                : tr("&Redo"));
    };
    connect(m_undo, &QUndoStack::indexChanged, this, update);
    connect(m_undo, &QUndoStack::cleanChanged, this, update);
    connect(m_stateTimer, &QTimer::timeout, this, update);
    connect(this, &MainWindow::stateChangeNoted, this, update);
    update();
}

void MainWindow::undo() {
    flushStateChange();
    m_undo->undo();
}

void MainWindow::redo() {
    flushStateChange();
    m_undo->redo();
}

bool MainWindow::saveSession(const QString& path) {
    if (!m_study->volume()) {
        message(tr("Save session: no study is open"), true);
        return false;
    }
    flushStateChange();
    {
        QSettings s(path, QSettings::IniFormat);
        s.clear();
        s.setValue("session/format", kSessionFormat);
        s.setValue("session/application", QString::fromUtf8(applicationName()));
        saveStudySource(s, m_study->source());
        fvr::ui::saveState(s, currentState());
        emit savingSession(s);
        s.sync();
        if (s.status() != QSettings::NoError) {
            message(tr("Save session %1: the file could not be written").arg(path), true);
            return false;
        }
    }
    message(tr("Session saved: %1").arg(path));
    return true;
}

bool MainWindow::openSession(const QString& path) {
    const QFileInfo info(path);
    if (!info.isFile() || !info.isReadable()) {
        message(tr("Open session %1: no such readable file").arg(path), true);
        return false;
    }
    QSettings s(path, QSettings::IniFormat);
    const int format = s.value("session/format", 0).toInt();
    if (s.status() != QSettings::NoError || format < 1) {
        message(tr("Open session %1: not a session file (no session/format)").arg(path), true);
        return false;
    }
    if (format > kSessionFormat)
        message(tr("Session %1 was written by a later version (format %2): what this version "
                   "does not know keeps its defaults")
                    .arg(path)
                    .arg(format),
                true);
    try {
        const StudySource source = loadStudySource(s);
        m_pendingSession = loadState(s, currentState());
        m_pendingSessionPath = path;
        openStudy(source);
    } catch (const std::exception& e) {
        message(tr("Open session %1: %2").arg(path, QString::fromUtf8(e.what())), true);
        return false;
    }
    return true;
}

void MainWindow::startStudyHistory() {
    applyPendingSession();
    m_undo->clear(); // a new study: nothing to undo into
    m_stateTimer->stop();
    m_userChange = false;
    m_recorded = currentState();
}

void MainWindow::applyPendingSession() {
    if (!m_pendingSession) return;
    const WorkstationState st = *m_pendingSession;
    m_pendingSession.reset();
    applyState(st);
    {
        QSettings s(m_pendingSessionPath, QSettings::IniFormat);
        emit sessionOpened(s);
    }
    message(tr("Session restored: %1").arg(m_pendingSessionPath));
    emit sessionRestored();
}

void MainWindow::saveSessionDialog() {
    const QString path = QFileDialog::getSaveFileName(
        this, tr("Save session"), exportFolder() + QStringLiteral("/session.fvrsession"),
        tr("FVR sessions (*.fvrsession)"));
    if (!path.isEmpty()) saveSession(path);
}

void MainWindow::openSessionDialog() {
    const QString path = QFileDialog::getOpenFileName(
        this, tr("Open session"), exportFolder(), tr("FVR sessions (*.fvrsession);;All files (*)"));
    if (!path.isEmpty()) openSession(path);
}

} // namespace fvr::ui
