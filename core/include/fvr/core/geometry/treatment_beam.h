#pragma once
/** A radiotherapy treatment beam as a cone-beam camera, in the coordinate systems of IEC 61217
 *  (as DICOM RT uses them, PS3.3 C.8.8.14 and C.8.8.25.6): every rotation is right-handed,
 *  "clockwise when viewed in the positive direction of the axis of rotation".
 *   - IEC FIXED (f): origin at the isocentre, +Zf up, +Yf along the couch toward the gantry,
 *     +Xf to the right of an observer at the couch's foot facing the gantry.
 *   - IEC GANTRY (g): the fixed system turned by the gantry angle about Yf; the source lies on
 *     +Zg at SAD from the isocentre. Gantry 0: the source above the couch; gantry 90: at +Xf.
 *   - IEC BEAM LIMITING DEVICE (b): the gantry system turned by the collimator angle about Zg.
 *   - IEC PATIENT SUPPORT (s): the fixed system turned by the couch (patient support) angle
 *     about Zf; the patient lies on it as PatientPosition (0018,5100) says.
 *  So a point p_b of the beam-limiting-device system lies in the patient support system at
 *  Rz(couch)^T Ry(gantry) Rz(collimator) p_b (SlicerRT's IEC transform chain has the same
 *  signs: gantry RotateY(+g), collimator RotateZ(+c), patient support RotateZ(+couch)), and in
 *  patient LPS at I + M(position) (that), with M the patient's axes in the support system: HFS
 *  (head first supine) has the patient's left along +Xs, the head along +Ys and the anterior
 *  along +Zs, so gantry 0 is an AP beam (source anterior), gantry 90 a left lateral, 180 PA,
 *  270 right lateral.
 *
 *  The imager (a kV or MV panel opposite the source, SID from it) lies in the beam-limiting-
 *  device system: its centre at Zb = SAD - SID, its columns along +Xb and its rows along -Yb,
 *  seen from the source, as an RT Image's pixels are (the beam's eye view; RT Image Position is
 *  the top-left pixel at -x, +y of the IEC X-RAY IMAGE RECEPTOR plane). At gantry 0, collimator 0
 *  and couch 0 for HFS the columns run to the patient's left and the rows to the feet. The imager
 *  turns with the collimator (a beam's-eye view); a real gantry-mounted panel does not, so give
 *  collimator 0 for a portal or kV image. This is also how plastimatch's `drr` orients its image
 *  (rows along -vup, columns along vup x nrm), whose own gantry angle is not IEC's: it places the
 *  source at isocentre + SAD (cos a, -sin a, 0), so a = 90 - gantry for HFS (tests). */
#include <string>

#include <glm/glm.hpp>

#include <fvr/core/geometry/camera.h>

namespace fvr::core {

/** DICOM Patient Position (0018,5100) of a patient on the treatment couch. */
enum class PatientPosition { HFS, HFP, FFS, FFP, HFDL, HFDR, FFDL, FFDR };

/** "HFS", "HFP", ... */
const char* patientPositionName(PatientPosition p);
/** The DICOM code (case and surrounding spaces ignored); throws SettingsError naming the
 *  accepted codes for any other (the sitting and standing positions, AFDR etc., are refused:
 *  a treatment couch has none of them). */
PatientPosition parsePatientPosition(const std::string& code);

/** The rotation from IEC PATIENT SUPPORT coordinates to patient LPS for a position (the columns
 *  are Xs, Ys, Zs in LPS). HFS: Xs = L (1, 0, 0), Ys = S (0, 0, 1), Zs = A (0, -1, 0). */
glm::dmat3 patientSupportToLps(PatientPosition p);

struct TreatmentBeam {
    double gantryDeg = 0.0; ///< IEC gantry angle
    double couchDeg = 0.0; ///< IEC patient support angle
    double collimatorDeg = 0.0; ///< IEC beam limiting device angle
    double sad = 1000.0; ///< source to axis (isocentre), mm
    double sid = 1500.0; ///< source to the imager plane, mm
    glm::dvec3 isocentre{0.0}; ///< patient LPS, mm
    PatientPosition position = PatientPosition::HFS;
};

/** The beam-limiting-device axes in patient LPS: the columns Xb, Yb, Zb (Zb toward the source). */
glm::dmat3 beamLimitingDeviceToLps(const TreatmentBeam& beam);

/** The beam's imager as a camera: W x H pixels of pitch pu x pv, the principal point offset by
 *  `principalOffset` pixels (ConeCamera's convention). Throws SettingsError naming the value for
 *  angles or distances that are not finite, SAD not > 0, SID not > SAD (the imager beyond the
 *  isocentre), and for a bad detector (ConeCamera::validate). */
ConeCamera treatmentBeamCamera(const TreatmentBeam& beam, int width, int height, double pitchU,
                               double pitchV, glm::dvec2 principalOffset = glm::dvec2(0.0));

} // namespace fvr::core
