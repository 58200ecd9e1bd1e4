// The cone-beam camera: pixel positions, the 3x4 projection matrix and the C-arm (camera.h).
#include <fvr/core/geometry/camera.h>

#include <cmath>
#include <numbers>
#include <string>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>

namespace fvr::core {
namespace {

bool finite(const glm::dvec3& x) {
    return std::isfinite(x.x) && std::isfinite(x.y) && std::isfinite(x.z);
}

/** The detector plane's unit normal, pointing from the source toward the detector. */
glm::dvec3 normalTowardDetector(const ConeCamera& c) {
    glm::dvec3 n = glm::normalize(glm::cross(c.u, c.v));
    return glm::dot(n, c.detectorCentre - c.source) < 0.0 ? -n : n;
}

glm::dvec2 centreIndex(const ConeCamera& c) {
    return {0.5 * (c.width - 1) - c.principalOffset.x, 0.5 * (c.height - 1) - c.principalOffset.y};
}

} // namespace

glm::dvec3 ProjectionMatrix::apply(const glm::dvec3& x) const {
    const glm::dvec4 h(x, 1.0);
    const double w = glm::dot(rows[2], h);
    return {glm::dot(rows[0], h) / w, glm::dot(rows[1], h) / w, w};
}

glm::dvec3 ConeCamera::pixelCentre(double col, double row) const {
    const glm::dvec2 c = centreIndex(*this);
    return detectorCentre + (col - c.x) * pitchU * u + (row - c.y) * pitchV * v;
}

double ConeCamera::sourceToDetector() const {
    return glm::dot(normalTowardDetector(*this), detectorCentre - source);
}

ProjectionMatrix ConeCamera::matrix() const {
    // A point X meets the detector plane at S + (X - S) f / (n.(X - S)), f = n.(C - S); its
    // column is u.(that - C) / pu + c_col, which times w = n.(X - S) is linear in X.
    const glm::dvec3 n = normalTowardDetector(*this);
    const glm::dvec3 cs = detectorCentre - source;
    const double f = glm::dot(n, cs);
    const glm::dvec2 c = centreIndex(*this);
    const glm::dvec3 a = (f / pitchU) * u + (c.x - glm::dot(u, cs) / pitchU) * n;
    const glm::dvec3 b = (f / pitchV) * v + (c.y - glm::dot(v, cs) / pitchV) * n;
    ProjectionMatrix p;
    p.rows[0] = glm::dvec4(a, -glm::dot(a, source));
    p.rows[1] = glm::dvec4(b, -glm::dot(b, source));
    p.rows[2] = glm::dvec4(n, -glm::dot(n, source));
    return p;
}

void ConeCamera::validate() const {
    auto fail = [](const std::string& what) { throw SettingsError("camera: " + what); };
    for (const auto& [name, n] : {std::pair{"width", width}, std::pair{"height", height}})
        if (n < 16 || n > 4096)
            fail(std::string("detector ") + name + ": expected 16..4096 pixels, found " +
                 std::to_string(n));
    for (const auto& [name, p] : {std::pair{"column", pitchU}, std::pair{"row", pitchV}})
        if (!(p > 0.0) || !std::isfinite(p))
            fail(std::string(name) + " pitch: expected a positive number of mm, found " +
                 formatNumber(p));
    if (!finite(source) || !finite(detectorCentre) || !finite(u) || !finite(v) ||
        !std::isfinite(principalOffset.x) || !std::isfinite(principalOffset.y))
        fail("a position or direction is not finite");
    if (std::abs(glm::length(u) - 1.0) > 1e-9 || std::abs(glm::length(v) - 1.0) > 1e-9 ||
        std::abs(glm::dot(u, v)) > 1e-9)
        fail("the detector's column and row directions must be orthonormal");
    if (!(std::abs(glm::dot(glm::cross(u, v), detectorCentre - source)) > 1e-6))
        fail("the detector plane passes through the source (it does not face it)");
}

ConeCamera coneCamera(const glm::dvec3& source, const glm::dvec3& detectorCentre,
                      const glm::dvec3& u, const glm::dvec3& v, int width, int height,
                      double pitchU, double pitchV, glm::dvec2 principalOffset) {
    ConeCamera c;
    c.source = source;
    c.detectorCentre = detectorCentre;
    c.u = u;
    c.v = v;
    c.width = width;
    c.height = height;
    c.pitchU = pitchU;
    c.pitchV = pitchV;
    c.principalOffset = principalOffset;
    c.validate();
    return c;
}

ConeCamera cArmCamera(const CArm& arm, int width, int height, double pitchU, double pitchV,
                      glm::dvec2 principalOffset) {
    if (!std::isfinite(arm.primaryDeg) || !std::isfinite(arm.secondaryDeg) ||
        !finite(arm.isocentre))
        throw SettingsError("C-arm: the angles and the isocentre must be finite");
    if (!(arm.sod > 0.0) || !(arm.sid > arm.sod) || !std::isfinite(arm.sid))
        throw SettingsError("C-arm: expected 0 < SOD < SID, found SOD " + formatNumber(arm.sod) +
                            " mm, SID " + formatNumber(arm.sid) + " mm");
    const double a = arm.primaryDeg * std::numbers::pi / 180.0;
    const double b = arm.secondaryDeg * std::numbers::pi / 180.0;
    const glm::dvec3 d(std::sin(a) * std::cos(b), -std::cos(a) * std::cos(b), std::sin(b));
    const glm::dvec3 u(std::cos(a), std::sin(a), 0.0);
    return coneCamera(arm.isocentre - arm.sod * d, arm.isocentre + (arm.sid - arm.sod) * d, u,
                      glm::cross(u, d), width, height, pitchU, pitchV, principalOffset);
}

} // namespace fvr::core
