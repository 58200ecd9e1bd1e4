// The Geometry panel applied to the views: parallel or cone beam per view, the C-arm's
// distances and ray model, and its angles as the views' shared orientation.
#include <fvr/ui/main_window.h>

#include <QSettings>

#include <algorithm>

#include <fvr/core/render/cone_projector.h>
#include <fvr/ui/panels/geometry_panel.h>
#include <fvr/ui/panels/rendering_panel.h>

namespace fvr::ui {

void MainWindow::restoreGeometryPanel() {
    const GeometryPanel::Values g = GeometryPanel::load(QSettings());
    m_geometry->setValues(g);
    // The startup projection is view 1's (as its kernel is).
    m_viewSettings[0].projection = g.projection;
    m_viewSettings[0].cone = g.cone;
}

void MainWindow::connectGeometry() {
    connect(m_geometry, &GeometryPanel::changed, this, &MainWindow::applyGeometry);
    connect(m_geometry, &GeometryPanel::anglesChanged, this, &MainWindow::applyCArmAngles);
    // A view's own slot in compare mode: the panel shows that view's projection.
    connect(m_rendering, &RenderingPanel::appliesToChanged, this, [this](int slot) {
        if (slot < 0 || slot > int(m_views.size())) return;
        const ViewSettings& s = m_viewSettings[std::size_t(std::max(slot, 1) - 1)];
        m_geometry->setValues({s.projection, s.cone});
    });
}

void MainWindow::applyGeometry() {
    const GeometryPanel::Values g = m_geometry->values();
    const int slot = m_rendering->appliesTo();
    for (int i = 0; i < int(m_views.size()); ++i) {
        if (m_compareCount > 1 && slot > 0 && slot - 1 != i) continue;
        m_viewSettings[std::size_t(i)].projection = g.projection;
        m_viewSettings[std::size_t(i)].cone = g.cone;
        ViewSettings s = m_views[std::size_t(i)]->settings();
        s.projection = g.projection;
        s.cone = g.cone;
        m_views[std::size_t(i)]->setSettings(s);
        // The title from the settings in effect (a new size reaches the view with its spectrum).
        if (m_compareCount > 1)
            m_views[std::size_t(i)]->setTitle(viewTitle(i, m_viewSettings[std::size_t(i)]));
    }
    assignSpectra(); // a cone-beam view takes the study's spectrum, whatever its kernel
    // The startup setting is view 1's.
    QSettings st;
    GeometryPanel::save(st, {m_viewSettings[0].projection, m_viewSettings[0].cone});
}

void MainWindow::applyCArmAngles(double primaryDeg, double secondaryDeg) {
    const auto volume = m_study->volume();
    if (!volume) return;
    const core::ViewFrame f = core::cArmViewFrame(*volume, primaryDeg, secondaryDeg);
    for (auto* v : m_views) v->setViewFrame(f);
}

void MainWindow::showCArmAngles(const core::ViewFrame& frame) {
    const auto volume = m_study->volume();
    if (!volume || !m_geometry) return;
    const core::CArmAngles a = core::cArmAngles(*volume, frame);
    m_geometry->showAngles(a.primaryDeg, a.secondaryDeg);
}

} // namespace fvr::ui
