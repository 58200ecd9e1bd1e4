#pragma once
/** The cone-beam camera contract, in patient LPS millimetres and double precision (GLM): a point
 *  source, a flat detector of W x H pixels of pitch pu x pv whose columns run along u and rows
 *  along v, and the 3x4 projection matrix P with [w col, w row, w]^T = P [x, y, z, 1]^T, pixel
 *  centres at integer 0-based (col, row). A C-arm builds one from its DICOM positioner angles
 *  (PS3.3 C.8.7.5.1.2: the primary angle in the transaxial plane, 0 perpendicular to the
 *  patient's chest, +90 at the patient's left (LAO); the secondary angle in the sagittal plane,
 *  +90 cranial; at 0/0 the patient faces the detector). No renderer uses it yet. */
#include <glm/glm.hpp>

namespace fvr::core {

/** P as three rows of four: [w col, w row, w] = P [x, y, z, 1]. */
struct ProjectionMatrix {
    glm::dvec4 rows[3];
    /** (col, row) of a point, and w (its depth along the detector normal from the source, mm;
     *  > 0 in front of the source). */
    glm::dvec3 apply(const glm::dvec3& x) const;
};

struct ConeCamera {
    glm::dvec3 source{0.0};
    glm::dvec3 detectorCentre{0.0}; ///< where the principal ray of a centred detector lands
    glm::dvec3 u{1.0, 0.0, 0.0}; ///< unit, along increasing columns
    glm::dvec3 v{0.0, 0.0, -1.0}; ///< unit, along increasing rows
    int width = 0; ///< W, columns
    int height = 0; ///< H, rows
    double pitchU = 1.0; ///< mm between column centres
    double pitchV = 1.0; ///< mm between row centres
    /** The principal point's offset (du, dv) in pixels: pixel (i, j) lies at detectorCentre +
     *  (i - (W-1)/2 + du) pu u + (j - (H-1)/2 + dv) pv v. */
    glm::dvec2 principalOffset{0.0};

    /** Where the centre of pixel (col, row) lies (fractional indices allowed). */
    glm::dvec3 pixelCentre(double col, double row) const;
    /** Source to detector plane along its normal (SID for a C-arm). */
    double sourceToDetector() const;
    ProjectionMatrix matrix() const;
    /** Throws SettingsError naming what is wrong: a size outside 16..4096, a pitch not > 0 and
     *  finite, u and v not orthonormal, a detector plane through the source. */
    void validate() const;
};

/** A camera from its parts: a source, a detector centre, unit column and row directions u and v,
 *  W x H pixels of pitch pu x pv and a principal offset; checked (ConeCamera::validate). */
ConeCamera coneCamera(const glm::dvec3& source, const glm::dvec3& detectorCentre,
                      const glm::dvec3& u, const glm::dvec3& v, int width, int height,
                      double pitchU, double pitchV, glm::dvec2 principalOffset = glm::dvec2(0.0));

/** A C-arm: positioner angles in degrees (DICOM's signs), source-to-detector (SID) and
 *  source-to-isocentre (SOD) distances in mm, and the isocentre. */
struct CArm {
    double primaryDeg = 0.0; ///< LAO +, RAO -
    double secondaryDeg = 0.0; ///< cranial +, caudal -
    double sid = 1000.0;
    double sod = 750.0;
    glm::dvec3 isocentre{0.0};
};

/** The camera of a C-arm with a W x H detector of pitch pu x pv:
 *  d = (sin a cos b, -cos a cos b, sin b) points from the isocentre to the detector, source =
 *  I - SOD d, detector centre = I + (SID - SOD) d, u = (cos a, sin a, 0), v = u x d. At 0/0 the
 *  source is posterior, the columns run to the patient's left and the rows to the feet, as a
 *  radiograph is read. Throws SettingsError for SOD not in (0, SID) or a bad detector. */
ConeCamera cArmCamera(const CArm& arm, int width, int height, double pitchU, double pitchV,
                      glm::dvec2 principalOffset = glm::dvec2(0.0));

} // namespace fvr::core
