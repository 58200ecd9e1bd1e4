// The reader's tools on a view: the mouse and keys that draw and edit the annotations, and their
// painting on the view and on exported images (measure_layer.h).
#include <fvr/ui/measure_layer.h>

#include <QInputDialog>
#include <QKeyEvent>
#include <QMouseEvent>
#include <QPainter>

#include <algorithm>
#include <cmath>

#include <fvr/ui/projection_view.h>

namespace fvr::ui {

using measure::Point;

namespace {
const QColor kInk(255, 214, 64); // annotations: yellow, as readers know them from other viewers
const QColor kSelected(90, 200, 255);
constexpr double kReach = 7.0; ///< widget pixels within which a handle is grabbed

Annotation::Kind kindOf(MeasureTool t) {
    switch (t) {
    case MeasureTool::Angle: return Annotation::Kind::Angle;
    case MeasureTool::Rectangle: return Annotation::Kind::Rectangle;
    case MeasureTool::Ellipse: return Annotation::Kind::Ellipse;
    case MeasureTool::Arrow: return Annotation::Kind::Arrow;
    case MeasureTool::Text: return Annotation::Kind::Text;
    default: return Annotation::Kind::Ruler;
    }
}

/** The label's box with its top-left at `at`, kept inside `bounds` where it fits. */
QRectF labelBox(const QFontMetricsF& fm, const QString& text, QPointF at, const QRectF& bounds) {
    QRectF box = fm.boundingRect(QRectF(0, 0, 4000, 4000), Qt::AlignLeft | Qt::AlignTop, text);
    box.moveTopLeft(at);
    if (box.right() > bounds.right()) box.moveRight(bounds.right());
    if (box.bottom() > bounds.bottom()) box.moveBottom(bounds.bottom());
    if (box.left() < bounds.left()) box.moveLeft(bounds.left());
    if (box.top() < bounds.top()) box.moveTop(bounds.top());
    return box;
}

void drawArrowHead(QPainter& p, QPointF head, QPointF tail, double len) {
    const double dx = tail.x() - head.x(), dy = tail.y() - head.y();
    const double n = std::hypot(dx, dy);
    if (n <= 0) return;
    const double ux = dx / n, uy = dy / n;
    const double c = std::cos(0.45), s = std::sin(0.45); // 26° either side of the shaft
    QPolygonF tip;
    tip << head << head + QPointF(len * (c * ux - s * uy), len * (s * ux + c * uy))
        << head + QPointF(len * (c * ux + s * uy), len * (-s * ux + c * uy));
    p.setBrush(p.pen().color());
    p.drawPolygon(tip);
    p.setBrush(Qt::NoBrush);
}
} // namespace

bool MeasureLayer::eventFilter(QObject* watched, QEvent* event) {
    if (watched != m_view) return false;
    switch (event->type()) {
    case QEvent::MouseButtonPress: {
        auto* e = static_cast<QMouseEvent*>(event);
        return e->button() == Qt::LeftButton && mousePress(e->position(), e->modifiers());
    }
    case QEvent::MouseMove: {
        auto* e = static_cast<QMouseEvent*>(event);
        return mouseMove(e->position(), e->buttons());
    }
    case QEvent::MouseButtonRelease: {
        auto* e = static_cast<QMouseEvent*>(event);
        return e->button() == Qt::LeftButton && mouseRelease(e->position());
    }
    case QEvent::Leave: emit readout({}); return false;
    case QEvent::KeyPress: {
        auto* e = static_cast<QKeyEvent*>(event);
        if ((e->key() == Qt::Key_Delete || e->key() == Qt::Key_Backspace) && m_selected >= 0) {
            remove(m_selected);
            return true;
        }
        if (e->key() == Qt::Key_Escape && (m_angleSecondArm || m_dragItem >= 0)) {
            remove(int(m_items.size()) - 1); // the annotation being drawn
            return true;
        }
        return false;
    }
    default: return false;
    }
}

std::optional<std::pair<int, int>> MeasureLayer::handleAt(QPointF pos) const {
    for (int i = int(m_items.size()) - 1; i >= 0; --i) // the topmost first
        for (int k = 0; k < int(m_items[i].points.size()); ++k) {
            const QPointF h = toWidget(toPixels(m_items[i].points[k]));
            if (std::hypot(h.x() - pos.x(), h.y() - pos.y()) <= kReach) return std::pair{i, k};
        }
    return std::nullopt;
}

bool MeasureLayer::mousePress(QPointF pos, Qt::KeyboardModifiers mods) {
    if (!m_view->volume()) return false;
    if (m_angleSecondArm) { // the angle's second arm ends here
        m_items.back().points[2] = toFraction(toImage(pos));
        m_angleSecondArm = false;
        emit changed();
        m_view->update();
        return true;
    }
    if (mods & Qt::ControlModifier) return false; // Ctrl+drag: the window, as before
    if (const auto h = handleAt(pos)) { // any tool: move the handle
        m_selected = m_dragItem = h->first;
        m_dragPoint = h->second;
        m_view->update();
        return true;
    }
    if (m_tool == MeasureTool::Pointer) {
        if (m_selected >= 0) {
            m_selected = -1;
            m_view->update();
        }
        return false; // rotation, as before
    }
    const Point at = toFraction(toImage(pos));
    Annotation a;
    a.kind = kindOf(m_tool);
    if (a.kind == Annotation::Kind::Text) {
        bool ok = false;
        a.text = QInputDialog::getText(m_view, tr("Text annotation"), tr("Text:"),
                                       QLineEdit::Normal, {}, &ok);
        if (!ok || a.text.trimmed().isEmpty()) return true;
        a.points = {at};
        add(std::move(a));
        m_selected = int(m_items.size()) - 1; // Delete removes it again
        return true;
    }
    a.points.assign(a.kind == Annotation::Kind::Angle ? 3 : 2, at);
    m_items.push_back(std::move(a));
    m_selected = m_dragItem = int(m_items.size()) - 1;
    m_dragPoint = 1; // the second point follows the mouse
    m_view->update();
    return true;
}

bool MeasureLayer::mouseMove(QPointF pos, Qt::MouseButtons buttons) {
    if (m_angleSecondArm) {
        m_items.back().points[2] = toFraction(toImage(pos));
        m_view->update();
        return true;
    }
    if (m_dragItem >= 0 && (buttons & Qt::LeftButton)) {
        Annotation& a = m_items[m_dragItem];
        a.points[m_dragPoint] = toFraction(toImage(pos));
        m_view->update();
        return true;
    }
    if (buttons == Qt::NoButton) emit readout(readoutAt(pos));
    return false;
}

bool MeasureLayer::mouseRelease(QPointF pos) {
    if (m_dragItem < 0) return false;
    const int item = m_dragItem;
    Annotation& a = m_items[item];
    a.points[m_dragPoint] = toFraction(toImage(pos));
    const bool drawing = item == int(m_items.size()) - 1 && m_dragPoint == 1;
    m_dragItem = m_dragPoint = -1;
    const QPointF p0 = toWidget(toPixels(a.points[0])), p1 = toWidget(toPixels(a.points[1]));
    if (drawing && std::hypot(p1.x() - p0.x(), p1.y() - p0.y()) < 3.0 && a.points.size() == 2 &&
        a.kind != Annotation::Kind::Angle) {
        remove(item); // a click, not a drag: nothing drawn
        return true;
    }
    if (drawing && a.kind == Annotation::Kind::Angle && a.points[2].x == a.points[0].x &&
        a.points[2].y == a.points[0].y) {
        a.points[2] = a.points[1]; // the second arm follows the mouse until the next click
        m_angleSecondArm = true;
    }
    refreshSoon();
    emit changed();
    m_view->update();
    return true;
}

void MeasureLayer::paintItem(QPainter& p, int i, const std::function<QPointF(Point)>& map,
                             double scale, bool handles) {
    const Annotation& a = m_items[i];
    std::vector<QPointF> q;
    for (const Point& f : a.points) q.push_back(map(toPixels(f)));
    QPen pen(handles && i == m_selected ? kSelected : kInk, std::max(1.0, 1.5 * scale));
    p.setPen(pen);
    p.setBrush(Qt::NoBrush);
    QPointF labelAt = q.back() + QPointF(6 * scale, 4 * scale);
    switch (a.kind) {
    case Annotation::Kind::Ruler: p.drawLine(q[0], q[1]); break;
    case Annotation::Kind::Angle:
        p.drawPolyline(q.data(), 3);
        labelAt = q[1] + QPointF(8 * scale, 4 * scale);
        break;
    case Annotation::Kind::Rectangle:
        p.drawRect(QRectF(q[0], q[1]).normalized());
        labelAt = QRectF(q[0], q[1]).normalized().bottomLeft() + QPointF(0, 4 * scale);
        break;
    case Annotation::Kind::Ellipse:
        p.drawEllipse(QRectF(q[0], q[1]).normalized());
        labelAt = QRectF(q[0], q[1]).normalized().bottomLeft() + QPointF(0, 4 * scale);
        break;
    case Annotation::Kind::Arrow:
        p.drawLine(q[0], q[1]);
        drawArrowHead(p, q[0], q[1], 12 * scale);
        break;
    case Annotation::Kind::Text: labelAt = q[0]; break;
    }
    if (handles && a.kind != Annotation::Kind::Text)
        for (const QPointF& h : q) p.drawRect(QRectF(h - QPointF(3, 3), QSizeF(6, 6)));
    const QString text = label(i);
    if (text.isEmpty()) return;
    const QRectF bounds = p.window();
    const QRectF box = labelBox(QFontMetricsF(p.font()), text, labelAt, bounds);
    if (handles) p.fillRect(box.adjusted(-3, -1, 3, 1), QColor(0, 0, 0, 150));
    p.drawText(box, Qt::AlignLeft | Qt::AlignTop, text);
}

void MeasureLayer::paint(QPainter& p) {
    if (!m_view->volume() || !m_view->spectrum()) return;
    m_painting = true;
    p.save();
    p.setRenderHint(QPainter::Antialiasing);
    p.setClipRect(m_view->imageRectInWidget().intersected(QRectF(m_view->rect())));
    const auto map = [this](Point px) { return toWidget(px); };
    for (int i = 0; i < int(m_items.size()); ++i) paintItem(p, i, map, 1.0, true);
    p.setClipping(false);
    // The scale bar: bottom right, a round length of about a quarter of the shown width; it
    // goes with the overlay (F: the image alone).
    if (const double mm = scaleBarMm(); mm > 0 && m_view->overlayVisible()) {
        const QRectF r = m_view->imageRectInWidget();
        const double len = mm / m_image->pixelSize / imageSide() * r.width();
        const QString text = scaleBarLabel();
        const QFontMetricsF fm(p.font());
        const double right = m_view->width() - 14, bottom = m_view->height() - 12;
        const QPointF a(right - len, bottom), b(right, bottom);
        p.setPen(QPen(Qt::black, 4));
        p.drawLine(a, b);
        p.setPen(QPen(Qt::white, 2));
        p.drawLine(a, b);
        p.drawLine(a, a - QPointF(0, 5));
        p.drawLine(b, b - QPointF(0, 5));
        p.drawText(QPointF(right - fm.horizontalAdvance(text), bottom - 8), text);
    }
    p.restore();
    m_painting = false;
}

QImage MeasureLayer::annotationMask(int side) {
    image(); // the statistics of the current frame
    QImage mask(side, side, QImage::Format_Grayscale8);
    mask.fill(0);
    QPainter p(&mask);
    // A scale of about one screen pixel per 256 image pixels of side: legible at 512 and 1024.
    const double scale = std::max(1.0, side / 512.0);
    QFont f = m_view->font();
    f.setPixelSize(int(std::lround(11 * scale)));
    p.setFont(f);
    const double s = imageSide();
    const auto map = [side, s](Point px) { return QPointF(px.x / s * side, px.y / s * side); };
    for (int i = 0; i < int(m_items.size()); ++i) {
        paintItem(p, i, map, scale, false);
    }
    p.end();
    // Everything drawn is "on": the ink's grey level (not black) marks it.
    for (int y = 0; y < side; ++y) {
        uchar* row = mask.scanLine(y);
        for (int x = 0; x < side; ++x) row[x] = row[x] ? 255 : 0;
    }
    return mask;
}

} // namespace fvr::ui
