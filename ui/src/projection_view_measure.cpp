// The view's turns and mirrors (ProjectionView::turnImage): the displayed image turned by a
// quarter or mirrored, by turning the view itself, so that the orientation labels, exports and
// measurements stay true.
#include <fvr/ui/measure_layer.h>
#include <fvr/ui/projection_view.h>

namespace fvr::ui {

void ProjectionView::turnImage(measure::Turn t) {
    // Columns run along r, rows along -u, and r = d x u. A quarter turn clockwise on screen
    // brings the left edge (-r) to the top: u' = -r, r' = u, d unchanged. A mirror is the view
    // from the other side (d' = -d): left-right keeps u (r' = -r), top-bottom keeps r (u' = -u).
    // A parallel projection's line integrals do not depend on the ray's sense, so that view is
    // exactly the mirror image (about the centre pixel M/2, where the volume's centre projects).
    core::ViewFrame f = m_view;
    switch (t) {
    case measure::Turn::Clockwise:
        f.u = -m_view.r;
        f.r = m_view.u;
        break;
    case measure::Turn::CounterClockwise:
        f.u = m_view.r;
        f.r = -m_view.u;
        break;
    case measure::Turn::FlipHorizontal:
        f.d = -m_view.d;
        f.r = -m_view.r;
        break;
    case measure::Turn::FlipVertical:
        f.d = -m_view.d;
        f.u = -m_view.u;
        break;
    }
    m_measure->turn(t);
    setViewFrame(f);
    emit viewFrameChanged(m_view);
}

} // namespace fvr::ui
