#include <fvr/core/xray/display_window.h>

#include <algorithm>
#include <cmath>

namespace fvr::core {

double DisplayWindow::map(double value) const {
    const double v = transmission.active() ? transmission.logExposure(value) : value;
    double t = (v - low) / (high > low ? high - low : 1.0);
    if (!std::isfinite(t)) t = 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return invert ? 1.0 - t : t;
}

DisplayWindow autoWindow(const std::vector<float>& pixels) {
    DisplayWindow w;
    if (pixels.empty()) return w;
    std::vector<float> v;
    v.reserve(pixels.size());
    for (float p : pixels)
        if (std::isfinite(p)) v.push_back(p);
    if (v.empty()) return w;
    const auto lo = v.begin() + std::ptrdiff_t(0.005 * (v.size() - 1));
    const auto hi = v.begin() + std::ptrdiff_t(0.995 * (v.size() - 1));
    std::nth_element(v.begin(), lo, v.end());
    w.low = *lo;
    std::nth_element(v.begin(), hi, v.end());
    w.high = *hi;
    if (!(w.high > w.low)) w.high = w.low + 1.0;
    return w;
}

std::vector<float> windowedValues(std::vector<float> lineIntegrals,
                                  const Transmission& transmission) {
    if (transmission.active()) applyLogExposure(lineIntegrals, transmission);
    return lineIntegrals;
}

DisplayWindow filmWindow(const std::vector<float>& lineIntegrals, const Transmission& transmission,
                         bool invert) {
    DisplayWindow w = autoWindow(windowedValues(lineIntegrals, transmission));
    w.invert = invert;
    w.transmission = transmission;
    return w;
}

} // namespace fvr::core
