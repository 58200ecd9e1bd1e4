// The rigid pose's parameters, matrix and camera (registration/pose.h), and the target error.
#include <fvr/core/registration/pose.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fvr/core/errors.h>

namespace fvr::core {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

glm::dvec3 transformPoint(const glm::dmat4& T, const glm::dvec3& x) {
    return glm::dvec3(T * glm::dvec4(x, 1.0));
}

glm::dvec3 transformDirection(const glm::dmat4& T, const glm::dvec3& d) {
    return glm::dvec3(T * glm::dvec4(d, 0.0));
}

} // namespace

std::vector<double> Pose::parameters() const {
    return {rotationDeg.x,   rotationDeg.y,   rotationDeg.z,
            translationMm.x, translationMm.y, translationMm.z};
}

Pose Pose::fromParameters(const double* p) {
    Pose pose;
    pose.rotationDeg = {p[0], p[1], p[2]};
    pose.translationMm = {p[3], p[4], p[5]};
    return pose;
}

glm::dmat3 rotationMatrix(const glm::dvec3& rotationDeg) {
    const double cx = std::cos(rotationDeg.x * kDeg), sx = std::sin(rotationDeg.x * kDeg);
    const double cy = std::cos(rotationDeg.y * kDeg), sy = std::sin(rotationDeg.y * kDeg);
    const double cz = std::cos(rotationDeg.z * kDeg), sz = std::sin(rotationDeg.z * kDeg);
    // GLM is column-major: m[c][r]. Rx, Ry, Rz written by columns.
    const glm::dmat3 rx(1, 0, 0, 0, cx, sx, 0, -sx, cx);
    const glm::dmat3 ry(cy, 0, -sy, 0, 1, 0, sy, 0, cy);
    const glm::dmat3 rz(cz, sz, 0, -sz, cz, 0, 0, 0, 1);
    return rz * ry * rx;
}

glm::dmat4 poseMatrix(const Pose& pose, const glm::dvec3& centre) {
    const glm::dmat3 r = rotationMatrix(pose.rotationDeg);
    glm::dmat4 t(r);
    t[3] = glm::dvec4(centre - r * centre + pose.translationMm, 1.0);
    return t;
}

void validateRigid(const glm::dmat4& T) {
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            if (!std::isfinite(T[c][r]))
                throw SettingsError("pose: the matrix holds a value that is not a finite number");
    if (std::abs(T[0][3]) > 1e-9 || std::abs(T[1][3]) > 1e-9 || std::abs(T[2][3]) > 1e-9 ||
        std::abs(T[3][3] - 1.0) > 1e-9)
        throw SettingsError("pose: the matrix's last row is not 0 0 0 1 (not a rigid transform)");
    const glm::dmat3 r(T);
    const glm::dmat3 rtr = glm::transpose(r) * r;
    for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k)
            if (std::abs(rtr[c][k] - (c == k ? 1.0 : 0.0)) > 1e-6)
                throw SettingsError("pose: the matrix's 3x3 part is not a rotation (R^T R differs "
                                    "from the identity by more than 1e-6: a scale or a shear)");
    if (glm::determinant(r) < 0.0)
        throw SettingsError("pose: the matrix's 3x3 part is a reflection (determinant -1), not a "
                            "rotation");
}

Pose poseFromMatrix(const glm::dmat4& T, const glm::dvec3& centre) {
    validateRigid(T);
    const glm::dmat3 r(T);
    // R = Rz Ry Rx: R[0][2] (row 2, column 0) = -sin(ry); R[1][2] = cy sx, R[2][2] = cy cx;
    // R[0][1] = cy sz, R[0][0] = cy cz.
    Pose pose;
    const double sy = std::clamp(-r[0][2], -1.0, 1.0);
    pose.rotationDeg.y = std::asin(sy) / kDeg;
    if (std::abs(sy) < 1.0 - 1e-12) {
        pose.rotationDeg.x = std::atan2(r[1][2], r[2][2]) / kDeg;
        pose.rotationDeg.z = std::atan2(r[0][1], r[0][0]) / kDeg;
    } else { // gimbal lock: only rx -+ rz is defined; put it all in rx
        pose.rotationDeg.z = 0.0;
        pose.rotationDeg.x = std::atan2(-r[2][1], r[1][1]) / kDeg;
    }
    pose.translationMm = glm::dvec3(T[3]) - centre + r * centre;
    return pose;
}

ConeCamera posedCamera(const ConeCamera& camera, const glm::dmat4& T) {
    validateRigid(T);
    const glm::dmat4 inv = glm::inverse(T);
    ConeCamera c = camera;
    c.source = transformPoint(inv, camera.source);
    c.detectorCentre = transformPoint(inv, camera.detectorCentre);
    c.u = glm::normalize(transformDirection(inv, camera.u));
    c.v = glm::normalize(transformDirection(inv, camera.v));
    return c;
}

double meanTargetError(const glm::dmat4& truth, const glm::dmat4& found,
                       const std::vector<glm::dvec3>& targets) {
    if (targets.empty()) throw SettingsError("target registration error: no target points");
    double sum = 0.0;
    for (const glm::dvec3& x : targets)
        sum += glm::length(transformPoint(truth, x) - transformPoint(found, x));
    return sum / double(targets.size());
}

std::vector<glm::dvec3> cubeCorners(const glm::dvec3& centre, double side) {
    std::vector<glm::dvec3> corners;
    const double h = side / 2.0;
    for (int k = 0; k < 8; ++k)
        corners.push_back(centre + glm::dvec3(k & 1 ? h : -h, k & 2 ? h : -h, k & 4 ? h : -h));
    return corners;
}

} // namespace fvr::core
