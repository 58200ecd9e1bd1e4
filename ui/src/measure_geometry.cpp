// The reader's measurements without Qt (see measure_geometry.h): plain geometry on image pixels.
#include <fvr/ui/measure_geometry.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fvr::ui::measure {

double distanceMm(Point a, Point b, double pixelMm) {
    return std::hypot(b.x - a.x, b.y - a.y) * pixelMm;
}

double angleDeg(Point a, Point vertex, Point b) {
    const double ax = a.x - vertex.x, ay = a.y - vertex.y;
    const double bx = b.x - vertex.x, by = b.y - vertex.y;
    if (std::hypot(ax, ay) == 0.0 || std::hypot(bx, by) == 0.0) return 0.0;
    // atan2 of cross and dot: accurate near 0 and 180 degrees, unlike acos.
    const double rad = std::atan2(std::abs(ax * by - ay * bx), ax * bx + ay * by);
    return rad * 180.0 / std::numbers::pi;
}

bool insideRoi(RoiShape shape, Point a, Point b, int col, int row) {
    const double x = col + 0.5, y = row + 0.5;
    const double x0 = std::min(a.x, b.x), x1 = std::max(a.x, b.x);
    const double y0 = std::min(a.y, b.y), y1 = std::max(a.y, b.y);
    if (x < x0 || x > x1 || y < y0 || y > y1) return false;
    if (shape == RoiShape::Rectangle) return true;
    const double rx = (x1 - x0) / 2, ry = (y1 - y0) / 2;
    if (rx <= 0 || ry <= 0) return false;
    const double dx = (x - (x0 + rx)) / rx, dy = (y - (y0 + ry)) / ry;
    return dx * dx + dy * dy <= 1.0;
}

RoiStats roiStats(const std::vector<float>& pixels, int width, int height, RoiShape shape, Point a,
                  Point b, double pixelMm) {
    RoiStats s;
    if (width <= 0 || height <= 0 || pixels.size() < std::size_t(width) * height) return s;
    // Only the pixels of the bounding box can be inside.
    const int c0 = std::max(0, int(std::floor(std::min(a.x, b.x) - 0.5)));
    const int c1 = std::min(width - 1, int(std::ceil(std::max(a.x, b.x))));
    const int r0 = std::max(0, int(std::floor(std::min(a.y, b.y) - 0.5)));
    const int r1 = std::min(height - 1, int(std::ceil(std::max(a.y, b.y))));
    // Two passes (mean, then the squared deviations): no cancellation for large offsets.
    double sum = 0.0;
    for (int r = r0; r <= r1; ++r)
        for (int c = c0; c <= c1; ++c) {
            if (!insideRoi(shape, a, b, c, r)) continue;
            const double v = pixels[std::size_t(r) * width + c];
            if (s.count == 0) s.min = s.max = v;
            s.min = std::min(s.min, v);
            s.max = std::max(s.max, v);
            sum += v;
            ++s.count;
        }
    if (s.count == 0) return s;
    s.mean = sum / double(s.count);
    double sq = 0.0;
    for (int r = r0; r <= r1; ++r)
        for (int c = c0; c <= c1; ++c)
            if (insideRoi(shape, a, b, c, r)) {
                const double d = pixels[std::size_t(r) * width + c] - s.mean;
                sq += d * d;
            }
    s.sd = std::sqrt(sq / double(s.count));
    s.areaMm2 = double(s.count) * pixelMm * pixelMm;
    return s;
}

double roundScaleLength(double maxMm) {
    if (!(maxMm > 0.0)) return 0.0;
    double decade = std::pow(10.0, std::floor(std::log10(maxMm)));
    for (double m : {5.0, 2.0, 1.0})
        if (m * decade <= maxMm * (1 + 1e-12)) return m * decade;
    return decade / 2; // rounding at an exact power of ten
}

Point turned(Point p, Turn t, double side) {
    switch (t) {
    case Turn::Clockwise: return {side - p.y, p.x};
    case Turn::CounterClockwise: return {p.y, side - p.x};
    case Turn::FlipHorizontal: return {side - p.x, p.y};
    case Turn::FlipVertical: return {p.x, side - p.y};
    }
    return p;
}

} // namespace fvr::ui::measure
