#include <fvr/core/volume.h>

#include <cmath>
#include <sstream>

#include <fvr/core/errors.h>

namespace fvr::core {

const char* unitsName(ValueUnits u) {
    switch (u) {
    case ValueUnits::Unknown: return "unknown";
    case ValueUnits::HounsfieldUnits: return "HU";
    case ValueUnits::LinearAttenuationRelWater: return "mu/mu_water";
    case ValueUnits::Intensity: return "intensity";
    }
    return "unknown";
}

std::pair<float, float> Volume::valueRange() const {
    // NaNs are skipped (both comparisons are false for them); an all-NaN volume gives (0, 0).
    float lo = INFINITY;
    float hi = -INFINITY;
    for (const float v : voxels) {
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
    }
    if (lo > hi) return {0.0f, 0.0f};
    return {lo, hi};
}

void validateGeometry(const Dims3& dims, const Vec3& spacing, const std::string& source) {
    for (int a = 0; a < 3; ++a) {
        if (dims[a] < 1 || dims[a] > kMaxDimPerAxis) {
            std::ostringstream os;
            os << source << ": dimensions: expected 1.." << kMaxDimPerAxis
               << " voxels per axis, found " << dims[0] << " x " << dims[1] << " x " << dims[2];
            throw LoadError(os.str());
        }
    }
    // Each factor is <= 2^14, so the product cannot overflow.
    const std::int64_t total = dims[0] * dims[1] * dims[2];
    if (total > kMaxVoxels) {
        std::ostringstream os;
        os << source << ": dimensions: expected at most " << kMaxVoxels << " voxels, found "
           << dims[0] << " x " << dims[1] << " x " << dims[2] << " = " << total;
        throw LoadError(os.str());
    }
    for (int a = 0; a < 3; ++a) {
        if (!(spacing[a] > 0.0) || !std::isfinite(spacing[a])) {
            std::ostringstream os;
            os << source << ": spacing: expected finite values > 0 mm, found " << spacing[0] << " "
               << spacing[1] << " " << spacing[2];
            throw LoadError(os.str());
        }
    }
}

} // namespace fvr::core
