#include <fvr/core/render/image_metrics.h>

#include <algorithm>
#include <cmath>

namespace fvr::core {

ImageComparison compareImages(const std::vector<float>& image,
                              const std::vector<float>& reference) {
    ImageComparison c;
    double e2 = 0, r2 = 0;
    for (std::size_t i = 0; i < reference.size(); ++i) {
        const double e = double(image[i]) - reference[i];
        c.peak = std::max(c.peak, std::abs(double(reference[i])));
        c.maxAbsError = std::max(c.maxAbsError, std::abs(e));
        e2 += e * e;
        r2 += double(reference[i]) * reference[i];
    }
    const double n = double(reference.size());
    c.rmse = std::sqrt(e2 / n);
    c.relRmse = r2 > 0 ? std::sqrt(e2 / r2) : 0;
    c.psnr = c.rmse > 0 ? 20.0 * std::log10(c.peak / c.rmse) : 300.0;
    return c;
}

double mostNegativeFraction(const std::vector<float>& pixels) {
    float lo = 0.0f, hi = 0.0f;
    for (float x : pixels) {
        lo = std::min(lo, x);
        hi = std::max(hi, x);
    }
    return hi > 0.0f ? double(lo) / double(hi) : 0.0;
}

} // namespace fvr::core
