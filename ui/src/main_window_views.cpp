// The main window's views: one, or 2/4 side by side to compare kernels, synchronised (view frame,
// window, interaction), with differences to view 1.
#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/display_panel.h>

#include <QGridLayout>
#include <QLabel>
#include <QSignalBlocker>

#include <algorithm>

#include <fvr/ui/panels/geometry_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/settings_model.h>

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
    if (n != m_compareCount) noteStateChange(true, ChangeKind::Mode);
    const core::ViewFrame frame = m_views.empty()
                                      ? core::ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0})
                                      : m_views[0]->viewFrame();
    const std::optional<core::DisplayWindow> window =
        m_views.empty() ? std::nullopt : std::optional<core::DisplayWindow>(m_views[0]->window());
    if (m_compareCount == 1 && !m_views.empty()) {
        // The other views start with the other kernels, so the comparison shows something.
        const core::Kernel order[] = {core::Kernel::Linear, core::Kernel::Nearest,
                                      core::Kernel::Sinc4, core::Kernel::CatmullRom,
                                      core::Kernel::BSpline};
        int slot = 1;
        for (core::Kernel k : order)
            if (k != m_viewSettings[0].kernel && slot < 4)
                m_viewSettings[slot++] = {k, m_viewSettings[0].size, m_viewSettings[0].voxelModel};
    }
    // View 1's annotations stay with view 1 (the others start without).
    const std::vector<Annotation> notes =
        m_views.empty() ? std::vector<Annotation>{} : m_views[0]->measure().annotations();
    for (auto* v : m_views) v->deleteLater();
    m_views.clear();
    m_compareCount = n;
    for (int i = 0; i < n; ++i) {
        ProjectionView* v = addView(i, n, frame);
        connectView(v);
        m_views.push_back(v);
    }
    if (m_rendering) {
        // "Applies to" starts at All views: the panels show view 1's settings, the ones in use
        // (not those of a view that was chosen before).
        m_rendering->setViewCount(n);
        showViewSettings(m_viewSettings[0]);
        if (m_geometry)
            m_geometry->setValues({m_viewSettings[0].projection, m_viewSettings[0].cone});
    }
    for (const Annotation& a : notes) m_views[0]->measure().add(a);
    updateCompareKernels(true); // Compare again: retries spectra that were not prepared
    // After setStudy (a new view's first study would reset the window to an auto window
    // computed whenever it first paints, losing the user's window or preset).
    if (window)
        for (auto* v : m_views)
            if (sameQuantity(*v, *m_views.front())) v->setWindow(*window); // a prior: its own
    setDifferenceMode(m_difference);
}

void MainWindow::updateCompareKernels(bool retry) {
    // A fair comparison: with gridding correction every kernel renders from its own corrected
    // spectrum (the controller prepares them in the background; views wait for theirs).
    std::vector<core::Kernel> kernels;
    for (std::size_t i = 1; i < m_views.size(); ++i) kernels.push_back(m_viewSettings[i].kernel);
    m_study->setCompareKernels(kernels, m_model->rendering().deapodize, retry);
    assignSpectra();
    updateSpectrumMemory();
}

void MainWindow::assignSpectra() {
    const auto volume = m_study->volume();
    if (!volume) return;
    const bool prior = assignPrior(); // view 2 shows the prior
    for (std::size_t i = 0; i < m_views.size(); ++i) {
        if (i == 1 && prior) continue;
        ProjectionView* v = m_views[i];
        const ViewSettings& s = m_viewSettings[i];
        // View 1 shows the main spectrum whenever it can render the kernel (while a new one is
        // prepared, the one in effect); the others show their kernel's.
        auto spectrum = m_study->spectrumFor(s.kernel);
        const auto main = m_study->spectrum();
        if (i == 0 && (!main->deapodizedFor || *main->deapodizedFor == s.kernel)) spectrum = main;
        // A cone-beam view ray casts the volume: any spectrum of the study's values will do
        // (it only says which values), so it never waits for its kernel's.
        if (s.projection == ProjectionKind::Cone && main) spectrum = main;
        if (spectrum) {
            v->setSettings(s);
            v->setStudy(volume, spectrum);
            v->setPendingText({});
            continue;
        }
        // Until its spectrum is ready a view keeps showing what it showed, if that is still
        // what the settings in effect give for its kernel (a kernel change in single view).
        const bool current = v->volume() == volume && v->spectrum() &&
                             v->spectrum() == m_study->spectrumFor(v->settings().kernel);
        if (current) continue;
        v->setStudy(volume, nullptr);
        v->setPendingText(m_study->spectrumPendingReason(s.kernel),
                          m_study->compareDeclined(s.kernel).has_value());
    }
    // The polychromatic output: each view's materials for its kernel (main_window_poly.cpp).
    if (isPolychromatic(m_model->xray().output)) applyPolychromatic();
}

ProjectionView* MainWindow::addView(int index, int count, const core::ViewFrame& frame) {
    auto* v = new ProjectionView(m_viewHost);
    const ViewSettings s = m_viewSettings[index];
    v->setSettings(s);
    v->setViewFrame(frame);
    v->setOverlayVisible(m_overlayAction ? m_overlayAction->isChecked() : true);
    if (m_xray) v->setEffects(currentEffects());
    v->setTargetFps(m_difference ? 0 : m_model->rendering().targetFps);
    v->setAllowSoftwareGpu(m_model->rendering().softwareGpu);
    connect(v, &ProjectionView::interactionChanged, this, [this, v](bool on) {
        for (auto* o : m_views)
            if (o != v) o->setInteracting(on); // synchronised views follow at their own level
    });
    if (count > 1) v->setTitle(viewTitle(index, s));
    attachMeasure(v);
    m_viewGrid->addWidget(v, index / 2, index % 2);
    return v;
}

void MainWindow::connectView(ProjectionView* v) {
    connect(v, &ProjectionView::panZoomChanged, this,
            [this] { noteStateChange(true, ChangeKind::View); });
    connect(v, &ProjectionView::viewFrameChanged, this, [this, v](const core::ViewFrame& f) {
        noteStateChange(true, ChangeKind::View); // a drag or the keys
        if (m_syncing) return;
        m_syncing = true;
        for (auto* o : m_views)
            if (o != v) o->setViewFrame(linkedFrame(v, o, f));
        showCArmAngles(m_views.front()->viewFrame());
        m_syncing = false;
    });
    connect(v, &ProjectionView::windowChanged, this,
            [this, v](const core::DisplayWindow& w, bool byHand) {
                noteStateChange(byHand, ChangeKind::Window);
                if (m_syncing) return;
                m_syncing = true;
                if (v == m_views.front() || !m_difference) {
                    for (auto* o : m_views)
                        if (o != v && !(m_difference && o != m_views.front()) &&
                            sameQuantity(*o, *v))
                            o->setWindow(w);
                    if (sameQuantity(*v, *m_views.front())) // not a prior's own window
                        syncWindowToPanel(w, byHand ? WindowPreset::Custom : WindowPreset::Auto);
                }
                m_syncing = false;
            });
    connect(v, &ProjectionView::backendChanged, this,
            [this, v](bool gpu, const QString& notice) { showBackend(*v, gpu, notice); });
    connect(v, &ProjectionView::differenceScaleChanged, this,
            &MainWindow::applySharedDifferenceScale);
}

void MainWindow::applySharedDifferenceScale() {
    if (!m_difference) return;
    double scale = 0;
    for (std::size_t i = 1; i < m_views.size(); ++i)
        scale = std::max(scale, m_views[i]->differenceMaxAbs());
    if (!(scale > 0)) return; // no difference yet, or none at all: the views keep their own
    for (std::size_t i = 1; i < m_views.size(); ++i) m_views[i]->setWindow({-scale, scale, false});
}

void MainWindow::showBackend(const ProjectionView& v, bool gpu, const QString& notice) {
    // Honest: a software OpenGL (llvmpipe …) is slower than the CPU renderer, so the views use
    // the CPU there unless the Rendering panel says otherwise; the status bar says which.
    const QString text =
        gpu ? (v.softwareGl() ? tr("Renderer: GPU (software OpenGL, slower than the CPU)")
                              : tr("Renderer: GPU"))
            : (v.softwareGl() && notice.isEmpty()
                   ? tr("Renderer: CPU (the OpenGL is software, slower; View ▸ Use a software "
                        "GPU)")
                   : tr("Renderer: CPU"));
    if (m_backend && m_backend->text() != text) {
        m_backend->setText(text);
        if (v.softwareGl() && !gpu) message(text.mid(text.indexOf('(') + 1).chopped(1));
    }
    if (!notice.isEmpty()) message(notice, true);
}

void MainWindow::setDifferenceMode(bool on) {
    if (on && m_prior && m_prior->volume()) {
        message(tr("Difference: view 2 shows a prior, another study on its own grid; close the "
                   "prior to compare kernels"),
                true);
        on = false;
    }
    if (m_differenceAction && m_differenceAction->isChecked() != on) {
        const QSignalBlocker block(m_differenceAction); // undo, a session
        m_differenceAction->setChecked(on);
    }
    if (on != m_difference) noteStateChange(true, ChangeKind::Mode);
    m_difference = on;
    for (std::size_t i = 1; i < m_views.size(); ++i)
        m_views[i]->setDifferenceReference(on ? m_views[0] : nullptr);
    // Differences compare full-quality frames: no progressive levels while they are shown, and
    // the overlays say so where a target frame rate is set.
    const int fps = m_model->rendering().targetFps;
    for (auto* v : m_views) {
        v->setTargetFps(on ? 0 : fps);
        v->setProgressiveOffReason(on && fps > 0 ? differenceProgressiveNote() : QString());
        v->setZoomRendering(!on); // differences compare frames of the slice resolution
    }
    // Back from differences: the views take view 1's window again (transmission included).
    if (!on && !m_views.empty())
        for (std::size_t i = 1; i < m_views.size(); ++i)
            if (sameQuantity(*m_views[i], *m_views[0])) m_views[i]->setWindow(m_views[0]->window());
}

QString MainWindow::differenceProgressiveNote() const {
    // Differences compare full-quality frames (short: it fits a view of four).
    return tr("in Difference mode");
}

QString MainWindow::viewTitle(int index, const ViewSettings& s) const {
    // Short enough to clear the orientation label above the image; the overlay's first line
    // names the voxel model.
    if (s.projection == ProjectionKind::Cone)
        return tr("View %1: cone beam %2×%2").arg(index + 1).arg(s.size);
    return tr("View %1: %2 %3×%3")
        .arg(index + 1)
        .arg(QString::fromUtf8(core::kernelName(s.kernel)))
        .arg(s.size);
}

void MainWindow::showPatientView(core::PatientView pv) {
    if (!m_study->volume() || m_views.empty()) return;
    const auto f = core::patientViewFrame(*m_study->volume(), pv);
    for (auto* v : m_views)
        v->setViewFrame(v->volume() ? core::patientViewFrame(*v->volume(), pv) : f);
    showCArmAngles(f);
    noteStateChange(true, ChangeKind::View);
}

} // namespace fvr::ui
