#pragma once
/** The 3-vector of the physical frame (mm or unit directions): GLM's double-precision vector, so
 *  that the loaders, the DICOM geometry, the view frames and the cone-beam camera share one type
 *  and GLM's operations (v + w, v * s, glm::dot, glm::cross, glm::length, glm::normalize).
 *  `Vec3 v;` is not initialised (as GLM's own vectors): write `Vec3 v{}` for zeros. */
#include <cmath>
#include <optional>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace fvr::core {

using Vec3 = glm::dvec3;

/** `v` divided by its length; nullopt when the length is not finite or not above `minNorm`
 *  (glm::normalize would return NaN or infinities for a degenerate vector). */
inline std::optional<Vec3> normalized(const Vec3& v, double minNorm = 1e-12) {
    const double n = glm::length(v);
    if (!std::isfinite(n) || !(n > minNorm)) return std::nullopt;
    return v / n;
}

} // namespace fvr::core
