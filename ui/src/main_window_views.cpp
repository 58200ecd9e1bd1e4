// The main window's views: one, or 2/4 side by side to compare kernels, synchronised (view frame,
// window, interaction), with differences to view 1.
#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/display_panel.h>

#include <QGridLayout>
#include <QLabel>

#include <fvr/ui/panels/rendering_panel.h>

namespace fvr::ui {

void MainWindow::buildViews() {
    m_viewHost = new QWidget(this);
    m_viewGrid = new QGridLayout(m_viewHost);
    m_viewGrid->setContentsMargins(0, 0, 0, 0);
    m_viewGrid->setSpacing(2);
    setCentralWidget(m_viewHost);
    setCompareCount(1);
}

void MainWindow::setCompareCount(int n) {
    n = (n >= 4) ? 4 : (n >= 2 ? 2 : 1);
    if (n > 1 && m_rendering && m_rendering->values().deapodize) {
        // A deapodized spectrum serves one kernel; the comparison needs them all.
        message(tr("Compare mode: gridding correction turned off so that each view can use its own "
                   "kernel."));
        RenderingPanel::Values r = m_rendering->values();
        r.deapodize = false;
        m_rendering->setValues(r);
        applySpectrumSettings();
    }
    const core::ViewFrame frame = m_views.empty()
                                      ? core::ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0})
                                      : m_views[0]->viewFrame();
    const std::optional<core::DisplayWindow> window =
        m_views.empty() ? std::nullopt : std::optional<core::DisplayWindow>(m_views[0]->window());
    if (m_compareCount == 1 && !m_views.empty()) {
        m_viewSettings[0] = m_views[0]->settings();
        // The other views start with the other kernels, so the comparison shows something.
        const core::Kernel order[] = {core::Kernel::Linear, core::Kernel::Nearest,
                                      core::Kernel::Sinc4, core::Kernel::CatmullRom,
                                      core::Kernel::BSpline};
        int slot = 1;
        for (core::Kernel k : order)
            if (k != m_viewSettings[0].kernel && slot < 4)
                m_viewSettings[slot++] = {k, m_viewSettings[0].size, m_viewSettings[0].voxelModel};
    }
    for (auto* v : m_views) v->deleteLater();
    m_views.clear();
    m_compareCount = n;
    for (int i = 0; i < n; ++i) {
        ProjectionView* v = addView(i, n, frame);
        // After setStudy (a new view's first study would reset the window to an auto window
        // computed whenever it first paints, possibly after the user changed the output).
        if (window) v->setWindow(*window);
        connectView(v);
        m_views.push_back(v);
    }
    setDifferenceMode(m_difference);
    if (m_rendering) m_rendering->setViewCount(n);
}

ProjectionView* MainWindow::addView(int index, int count, const core::ViewFrame& frame) {
    auto* v = new ProjectionView(m_viewHost);
    const ViewSettings s = m_viewSettings[count == 1 ? 0 : index];
    v->setSettings(s);
    v->setViewFrame(frame);
    v->setOverlayVisible(m_overlayAction ? m_overlayAction->isChecked() : true);
    if (m_xray) v->setEffects(currentEffects());
    if (m_rendering) v->setTargetFps(m_difference ? 0 : m_rendering->values().targetFps);
    connect(v, &ProjectionView::interactionChanged, this, [this, v](bool on) {
        for (auto* o : m_views)
            if (o != v) o->setInteracting(on); // synchronised views follow at their own level
    });
    if (count > 1) v->setTitle(viewTitle(index, s));
    m_viewGrid->addWidget(v, index / 2, index % 2);
    if (m_study->spectrum()) v->setStudy(m_study->volume(), m_study->spectrum());
    return v;
}

void MainWindow::connectView(ProjectionView* v) {
    connect(v, &ProjectionView::viewFrameChanged, this, [this, v](const core::ViewFrame& f) {
        if (m_syncing) return;
        m_syncing = true;
        for (auto* o : m_views)
            if (o != v) o->setViewFrame(f);
        m_syncing = false;
    });
    connect(v, &ProjectionView::windowChanged, this,
            [this, v](const core::DisplayWindow& w, bool byHand) {
                if (m_syncing) return;
                m_syncing = true;
                if (v == m_views.front() || !m_difference) {
                    for (auto* o : m_views)
                        if (o != v && !(m_difference && o != m_views.front())) o->setWindow(w);
                    syncWindowToPanel(w, byHand ? WindowPreset::Custom : WindowPreset::Auto);
                }
                m_syncing = false;
            });
    connect(v, &ProjectionView::backendChanged, this, [this](bool gpu, const QString& notice) {
        if (m_backend) m_backend->setText(gpu ? tr("Renderer: GPU") : tr("Renderer: CPU"));
        if (!notice.isEmpty()) message(notice, true);
    });
}

void MainWindow::setDifferenceMode(bool on) {
    m_difference = on;
    for (std::size_t i = 1; i < m_views.size(); ++i)
        m_views[i]->setDifferenceReference(on ? m_views[0] : nullptr);
    // Differences compare full-quality frames: no progressive levels while they are shown.
    for (auto* v : m_views)
        v->setTargetFps(on || !m_rendering ? 0 : m_rendering->values().targetFps);
    // Back from differences: the views take view 1's window again (transmission included).
    if (!on && !m_views.empty())
        for (std::size_t i = 1; i < m_views.size(); ++i)
            m_views[i]->setWindow(m_views[0]->window());
}

QString MainWindow::viewTitle(int index, const ViewSettings& s) const {
    // Short enough to clear the orientation label above the image; the overlay's first line
    // names the voxel model.
    return tr("View %1: %2 %3×%3")
        .arg(index + 1)
        .arg(QString::fromUtf8(core::kernelName(s.kernel)))
        .arg(s.size);
}

void MainWindow::showPatientView(core::PatientView pv) {
    if (!m_study->volume() || m_views.empty()) return;
    const auto f = core::patientViewFrame(*m_study->volume(), pv);
    for (auto* v : m_views) v->setViewFrame(f);
}

} // namespace fvr::ui
