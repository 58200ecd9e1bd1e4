// The reader's tools on a view (measure_layer.h): what they measure and how they are drawn. The
// mouse and key handling is in measure_input.cpp.
#include <fvr/ui/measure_layer.h>

#include <QSettings>
#include <QTimer>

#include <algorithm>
#include <cmath>

#include <fvr/core/xray/display_window.h>
#include <fvr/ui/projection_view.h>

namespace fvr::ui {

using measure::Point;

MeasureLayer::MeasureLayer(ProjectionView* view) : QObject(view), m_view(view) {
    view->installEventFilter(this);
    view->setMouseTracking(true); // the value under the cursor
    // ROI statistics and the scale bar read the frame: fetched once a new frame is on screen.
    connect(view, &ProjectionView::rendered, this, [this] { refreshSoon(); });
}

void MeasureLayer::setTool(MeasureTool tool) {
    m_tool = tool;
    if (m_angleSecondArm) remove(int(m_items.size()) - 1); // an angle left half drawn (Esc)
    m_angleSecondArm = false;
    m_dragItem = m_dragPoint = -1;
    m_view->setCursor(tool == MeasureTool::Pointer ? Qt::ArrowCursor : Qt::CrossCursor);
}

void MeasureLayer::add(Annotation a) {
    m_items.push_back(std::move(a));
    refreshSoon();
    emit changed();
    m_view->update();
}

void MeasureLayer::select(int index) {
    m_selected = index >= 0 && index < int(m_items.size()) ? index : -1;
    m_view->update();
}

void MeasureLayer::clear() {
    m_items.clear();
    m_selected = m_dragItem = m_dragPoint = -1;
    m_angleSecondArm = false;
    emit changed();
    m_view->update();
}

void MeasureLayer::remove(int index) {
    if (index < 0 || index >= int(m_items.size())) return;
    m_items.erase(m_items.begin() + index);
    m_selected = m_dragItem = m_dragPoint = -1;
    m_angleSecondArm = false;
    emit changed();
    m_view->update();
}

bool MeasureLayer::imageCurrent() const {
    const core::Transmission t = m_view->window().transmission;
    return m_image && m_imageFrame == m_view->framesRendered() &&
           t.muWaterPerMm == m_imageTransmission.muWaterPerMm &&
           t.exposure == m_imageTransmission.exposure;
}

bool MeasureLayer::needsFrame() const {
    for (const Annotation& a : m_items)
        if (a.kind == Annotation::Kind::Rectangle || a.kind == Annotation::Kind::Ellipse)
            return true; // statistics of the values on screen
    // The scale bar and the rulers need the pixel size, which only the settings change.
    return !m_image || !(m_imageSettings == m_view->settings());
}

const std::optional<core::ProjectionImage>& MeasureLayer::image() {
    if (m_painting) { // inside paintGL: the frame at hand, a new one comes after
        if (!imageCurrent()) refreshSoon();
        return m_image;
    }
    if (!imageCurrent()) {
        m_image = m_view->projection(); // may render: the frame count is read after it
        m_imageSettings = m_view->settings();
        m_imageTransmission = m_view->window().transmission;
        if (ProjectionView* ref = m_view->differenceReference(); ref && ref != m_view) {
            // A difference view shows its projection minus the reference's, as it subtracts.
            const auto r = ref->projection();
            if (m_image && r && r->width == m_image->width && r->height == m_image->height)
                for (std::size_t i = 0; i < m_image->pixels.size(); ++i)
                    m_image->pixels[i] -= r->pixels[i];
            else
                m_image.reset();
        } else if (m_image && m_imageTransmission.active()) {
            // The values as shown: transmitted intensities in Beer-Lambert mode.
            core::applyTransmission(m_image->pixels, m_imageTransmission);
        }
        m_imageFrame = m_view->framesRendered();
    }
    return m_image;
}

void MeasureLayer::refreshSoon() {
    if (m_refreshQueued) return;
    m_refreshQueued = true;
    // Not inside paintGL (projection() makes the context current and releases it), and only
    // for a frame at rest that something on screen needs (a read-back from the GPU each time).
    QTimer::singleShot(0, this, [this] {
        m_refreshQueued = false;
        if (!m_view->volume() || !m_view->showsCurrentFrame()) return;
        if (imageCurrent() || !needsFrame()) return;
        image();
        m_view->update();
    });
}

double MeasureLayer::pixelMm() {
    const auto& img = image();
    return img ? img->pixelSize : 0.0;
}

bool MeasureLayer::atIsocentre() const {
    return m_view->settings().projection == ProjectionKind::Cone;
}

int MeasureLayer::imageSide() const {
    if (m_image && m_image->width > 0) return m_image->width;
    return std::max(1, m_view->settings().size);
}

Point MeasureLayer::toFraction(Point px) const {
    const double s = imageSide();
    return {px.x / s, px.y / s};
}

Point MeasureLayer::toPixels(Point f) const {
    const double s = imageSide();
    return {f.x * s, f.y * s};
}

QPointF MeasureLayer::toWidget(Point px) const {
    const QRectF r = m_view->imageRectInWidget();
    const double s = imageSide();
    return {r.left() + px.x / s * r.width(), r.top() + px.y / s * r.height()};
}

Point MeasureLayer::toImage(QPointF w) const {
    const QRectF r = m_view->imageRectInWidget();
    const double s = imageSide();
    return {(w.x() - r.left()) / r.width() * s, (w.y() - r.top()) / r.height() * s};
}

std::optional<double> MeasureLayer::lengthMm(int i) {
    if (i < 0 || i >= int(m_items.size()) || m_items[i].kind != Annotation::Kind::Ruler)
        return std::nullopt;
    const double d = pixelMm();
    if (d <= 0) return std::nullopt;
    const auto& p = m_items[i].points;
    return measure::distanceMm(toPixels(p[0]), toPixels(p[1]), d);
}

std::optional<double> MeasureLayer::angleDeg(int i) const {
    if (i < 0 || i >= int(m_items.size()) || m_items[i].kind != Annotation::Kind::Angle)
        return std::nullopt;
    const auto& p = m_items[i].points; // fractions of a square: angles as in pixels
    return measure::angleDeg(p[0], p[1], p[2]);
}

std::optional<measure::RoiStats> MeasureLayer::roiStats(int i) {
    if (i < 0 || i >= int(m_items.size())) return std::nullopt;
    const Annotation& a = m_items[i];
    if (a.kind != Annotation::Kind::Rectangle && a.kind != Annotation::Kind::Ellipse)
        return std::nullopt;
    const auto& img = image();
    if (!img) return std::nullopt;
    const auto shape = a.kind == Annotation::Kind::Rectangle ? measure::RoiShape::Rectangle
                                                             : measure::RoiShape::Ellipse;
    return measure::roiStats(img->pixels, img->width, img->height, shape, toPixels(a.points[0]),
                             toPixels(a.points[1]), img->pixelSize);
}

QString MeasureLayer::units() const {
    const ProjectionView* ref = m_view->differenceReference();
    if (ref && ref != m_view) return tr("%1 (difference)").arg(m_view->valueUnits());
    if (m_view->window().transmission.active()) return QStringLiteral("I/I0");
    return m_view->valueUnits();
}

std::optional<double> MeasureLayer::shownValue(Point px) {
    const auto& img = image();
    if (!img) return std::nullopt;
    const int c = int(std::floor(px.x)), r = int(std::floor(px.y));
    if (c < 0 || r < 0 || c >= img->width || r >= img->height) return std::nullopt;
    return img->at(c, r);
}

QString MeasureLayer::readoutAt(QPointF widgetPos) {
    // Hovering renders nothing: a frame still coming (a drag, a change) has no readout yet.
    if (!imageCurrent() && !m_view->showsCurrentFrame()) return {};
    const Point px = toImage(widgetPos);
    const auto v = shownValue(px);
    if (!v) return {};
    return tr("x %1  y %2   %3 %4")
        .arg(int(std::floor(px.x)))
        .arg(int(std::floor(px.y)))
        .arg(*v, 0, 'g', 5)
        .arg(units());
}

QString MeasureLayer::label(int i) {
    if (i < 0 || i >= int(m_items.size())) return {};
    const QString iso = atIsocentre() ? tr(" at isocentre") : QString();
    const Annotation& a = m_items[i];
    switch (a.kind) {
    case Annotation::Kind::Ruler:
        if (const auto mm = lengthMm(i)) return tr("%1 mm").arg(*mm, 0, 'f', 1) + iso;
        return {};
    case Annotation::Kind::Angle:
        return m_angleSecondArm && i == int(m_items.size()) - 1
                   ? QString()
                   : tr("%1°").arg(*angleDeg(i), 0, 'f', 1);
    case Annotation::Kind::Rectangle:
    case Annotation::Kind::Ellipse: {
        const auto s = roiStats(i);
        if (!s || s->count == 0) return {};
        return tr("mean %1  SD %2  %3\nmin %4  max %5\narea %6 mm² (%7 px)%8")
            .arg(s->mean, 0, 'g', 4)
            .arg(s->sd, 0, 'g', 3)
            .arg(units())
            .arg(s->min, 0, 'g', 4)
            .arg(s->max, 0, 'g', 4)
            .arg(s->areaMm2, 0, 'f', 1)
            .arg(s->count)
            .arg(iso);
    }
    case Annotation::Kind::Arrow: return {};
    case Annotation::Kind::Text: return a.text;
    }
    return {};
}

double MeasureLayer::scaleBarMm() {
    const double d = m_image ? m_image->pixelSize : 0.0; // the cached frame: no render here
    const QRectF r = m_view->imageRectInWidget();
    if (d <= 0 || r.width() <= 0) return 0.0;
    const double shownPx = std::min<double>(r.width(), m_view->width());
    return measure::roundScaleLength(0.25 * shownPx / r.width() * imageSide() * d);
}

QString MeasureLayer::scaleBarLabel() {
    const double mm = scaleBarMm();
    if (mm <= 0) return {};
    return tr("%1 mm").arg(mm, 0, 'g', 4) + (atIsocentre() ? tr(" at isocentre") : QString());
}

void MeasureLayer::turn(measure::Turn t) {
    for (Annotation& a : m_items)
        for (Point& p : a.points) p = toFraction(measure::turned(toPixels(p), t, imageSide() + 1));
    emit changed();
    m_view->update();
}

namespace {
constexpr std::pair<Annotation::Kind, const char*> kKinds[] = {
    {Annotation::Kind::Ruler, "ruler"},         {Annotation::Kind::Angle, "angle"},
    {Annotation::Kind::Rectangle, "rectangle"}, {Annotation::Kind::Ellipse, "ellipse"},
    {Annotation::Kind::Arrow, "arrow"},         {Annotation::Kind::Text, "text"}};

std::size_t pointCount(Annotation::Kind k) {
    if (k == Annotation::Kind::Angle) return 3;
    return k == Annotation::Kind::Text ? 1 : 2;
}
} // namespace

void saveAnnotations(QSettings& s, const std::vector<Annotation>& items) {
    s.beginWriteArray("annotations", int(items.size()));
    for (int i = 0; i < int(items.size()); ++i) {
        s.setArrayIndex(i);
        const Annotation& a = items[i];
        for (const auto& [k, name] : kKinds)
            if (k == a.kind) s.setValue("kind", QString::fromLatin1(name));
        QStringList xy;
        for (const Point& p : a.points)
            xy << QString::number(p.x, 'g', 17) << QString::number(p.y, 'g', 17);
        s.setValue("points", xy.join(' '));
        if (!a.text.isEmpty()) s.setValue("text", a.text);
    }
    s.endArray();
}

std::vector<Annotation> loadAnnotations(QSettings& s) {
    std::vector<Annotation> out;
    const int n = s.beginReadArray("annotations");
    for (int i = 0; i < n; ++i) {
        s.setArrayIndex(i);
        Annotation a;
        bool known = false;
        for (const auto& [k, name] : kKinds)
            if (s.value("kind").toString() == QLatin1String(name)) a.kind = k, known = true;
        const QStringList xy = s.value("points").toString().split(' ', Qt::SkipEmptyParts);
        bool ok = known && xy.size() == 2 * int(pointCount(a.kind));
        for (int j = 0; ok && j + 1 < xy.size(); j += 2) {
            bool okx = false, oky = false;
            a.points.push_back({xy[j].toDouble(&okx), xy[j + 1].toDouble(&oky)});
            ok = okx && oky;
        }
        a.text = s.value("text").toString();
        if (ok) out.push_back(std::move(a));
    }
    s.endArray();
    return out;
}

} // namespace fvr::ui
