#pragma once
// Image comparison metrics used by the accuracy tests and benchmarks.
#include <algorithm>
#include <cmath>
#include <vector>

namespace fvr::test {

struct Comparison {
    double peak = 0;        ///< max |reference|
    double maxAbsError = 0;
    double rmse = 0;
    double relRmse = 0;     ///< rmse / rms(reference)
    double psnr = 0;        ///< 20 log10(peak / rmse), dB
};

inline Comparison compare(const std::vector<float>& image, const std::vector<float>& reference) {
    Comparison c;
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

} // namespace fvr::test
