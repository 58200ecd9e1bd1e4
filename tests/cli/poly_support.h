#pragma once
// What the polychromatic fvr-render tests (parallel and cone beam) check alike: the written I/I0
// against the spectral sum of the written mass thicknesses, computed here with the exact sum.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <fvr/core/xray/polychromatic.h>

namespace fvr::test {

struct SpectralSumCheck {
    double worstLogError = 0.0; ///< max over pixels of |ln I - ln I_exact|
    double darkest = 1.0; ///< the smallest I/I0 written
};

/** `transmission`: n pixels of I/I0; `materials`: 3 planes of n mass thicknesses (g/cm^2). */
inline SpectralSumCheck checkSpectralSum(const std::vector<float>& transmission,
                                         const std::vector<float>& materials,
                                         const core::SpectralResponse& response) {
    SpectralSumCheck c;
    const std::size_t n = transmission.size();
    for (std::size_t p = 0; p < n; ++p) {
        const double rhoL[3] = {materials[p], materials[n + p], materials[2 * n + p]};
        c.worstLogError = std::max(c.worstLogError, std::abs(std::log(double(transmission[p])) -
                                                             std::log(response.exact(rhoL))));
        c.darkest = std::min(c.darkest, double(transmission[p]));
    }
    return c;
}

} // namespace fvr::test
