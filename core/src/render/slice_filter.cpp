#include <fvr/core/render/slice_filter.h>

#include <cmath>

#include <fvr/core/render/voxel_model.h>

namespace fvr::core {

SliceFilterTable::SliceFilterTable(const SliceFilter& f, bool pixelAperture, int M, double d)
    : on(f.active() || pixelAperture), aperture(pixelAperture) {
    if (f.sharpenAmount > 0.0) amount = float(f.sharpenAmount);
    if (f.bandLimitLpMm > 0.0) invCut2 = float(1.0 / std::pow(f.bandLimitLpMm * M * d, 2));
    axis.assign(2 * std::size_t(M / 2 + 1), 1.0f);
    for (int j = 0; j <= M / 2; ++j) {
        if (amount > 0.0f) axis[2 * std::size_t(j)] = float(f.blur(j / (M * d)));
        if (pixelAperture)
            axis[2 * std::size_t(j) + 1] = float(pixelApertureResponse(double(j) / M));
    }
}

} // namespace fvr::core
