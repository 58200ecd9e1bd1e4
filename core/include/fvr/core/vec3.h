#pragma once
/** The 3-vector of the physical frame (mm or unit directions) and the few operations on it that
 *  the loaders, the DICOM geometry and the view frames need. One set, used everywhere. */
#include <array>
#include <cmath>
#include <optional>

namespace fvr::core {

using Vec3 = std::array<double, 3>;

inline Vec3 add(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 scale(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
inline double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
/** Euclidean length. */
inline double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
/** `v` divided by its length; nullopt when the length is not finite or not above `minNorm`. */
inline std::optional<Vec3> normalized(const Vec3& v, double minNorm = 1e-12) {
    const double n = norm(v);
    if (!std::isfinite(n) || !(n > minNorm)) return std::nullopt;
    return Vec3{v[0] / n, v[1] / n, v[2] / n};
}

} // namespace fvr::core
