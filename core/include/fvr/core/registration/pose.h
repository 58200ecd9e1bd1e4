#pragma once
/** The rigid pose of a CT in an X-ray's geometry (2D/3D registration).
 *
 *  Contract: the 4x4 pose T maps a point X of the CT (its own patient LPS, mm) to the same
 *  anatomy in the X-ray geometry's frame, so the X-ray shows CT point X at pixel P T X, where P is
 *  the X-ray's camera (geometry/camera.h). The identity is the geometry as the X-ray records it.
 *
 *  Parameters: three rotations in degrees about the LPS axes x (patient left), y (posterior),
 *  z (superior) through a centre c (the isocentre), applied x first, then y, then z
 *  (R = Rz Ry Rx, each right-handed: +z turns x towards y), then a translation t in mm (LPS):
 *      T X = R (X - c) + c + t.
 *  The same T has other angles and translations about another centre, so a pose file records c
 *  with them. */
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <fvr/core/geometry/camera.h>

namespace fvr::core {

struct Pose {
    glm::dvec3 rotationDeg{0.0}; ///< about x (L), y (P), z (S) through the centre, x first
    glm::dvec3 translationMm{0.0}; ///< LPS mm

    /** The six parameters in the order rx, ry, rz, tx, ty, tz. */
    std::vector<double> parameters() const;
    static Pose fromParameters(const double* p);
};

/** R = Rz(rz) Ry(ry) Rx(rx), degrees. */
glm::dmat3 rotationMatrix(const glm::dvec3& rotationDeg);
/** T X = R (X - c) + c + t as a 4x4 (column-major, GLM: T[3] is the translation column). */
glm::dmat4 poseMatrix(const Pose& pose, const glm::dvec3& centre);
/** The parameters of a rigid T about `centre` (ry in [-90, 90]); SettingsError when T is not
 *  rigid (its 3x3 not a rotation to 1e-6, or its last row not 0 0 0 1). */
Pose poseFromMatrix(const glm::dmat4& T, const glm::dvec3& centre);
/** SettingsError naming what is wrong when T is not a proper rigid transform. */
void validateRigid(const glm::dmat4& T);

/** The camera that shows X where `camera` shows T X: P' = P T (source, detector and its axes
 *  mapped by T's inverse). Rendering the CT with it gives the DRR of the CT at pose T. */
ConeCamera posedCamera(const ConeCamera& camera, const glm::dmat4& T);

/** The mean target registration error: the mean of |T_truth X - T_found X| over the targets
 *  (mm). Throws SettingsError for no targets. */
double meanTargetError(const glm::dmat4& truth, const glm::dmat4& found,
                       const std::vector<glm::dvec3>& targets);
/** The 8 corners of an LPS-aligned cube of side `side` mm centred on `centre`: the default
 *  targets. */
std::vector<glm::dvec3> cubeCorners(const glm::dvec3& centre, double side = 100.0);

} // namespace fvr::core
