// A treatment beam (IEC 61217 gantry, couch and collimator angles) as a cone-beam camera
// (treatment_beam.h).
#include <fvr/core/geometry/treatment_beam.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <numbers>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>

namespace fvr::core {
namespace {

struct PositionAxes {
    PatientPosition position;
    const char* name;
    /** The patient's head (superior) and anterior directions in IEC PATIENT SUPPORT axes. */
    glm::dvec3 head, anterior;
};

// Supine: anterior up (+Zs); prone: anterior down (-Zs); decubitus left (right): lying on the
// left (right) side, the patient's left down (up), so that left = head x anterior = -Zs (+Zs).
const std::array<PositionAxes, 8> kPositions{{
    {PatientPosition::HFS, "HFS", {0, 1, 0}, {0, 0, 1}},
    {PatientPosition::HFP, "HFP", {0, 1, 0}, {0, 0, -1}},
    {PatientPosition::FFS, "FFS", {0, -1, 0}, {0, 0, 1}},
    {PatientPosition::FFP, "FFP", {0, -1, 0}, {0, 0, -1}},
    {PatientPosition::HFDL, "HFDL", {0, 1, 0}, {1, 0, 0}},
    {PatientPosition::HFDR, "HFDR", {0, 1, 0}, {-1, 0, 0}},
    {PatientPosition::FFDL, "FFDL", {0, -1, 0}, {-1, 0, 0}},
    {PatientPosition::FFDR, "FFDR", {0, -1, 0}, {1, 0, 0}},
}};

const PositionAxes& axesOf(PatientPosition p) {
    return *std::find_if(kPositions.begin(), kPositions.end(),
                         [p](const PositionAxes& a) { return a.position == p; });
}

/** cos and sin of an angle in degrees, exact at multiples of 90 (so that gantry 90 puts the
 *  source exactly on an axis). */
glm::dvec2 cosSin(double deg) {
    const double r = std::fmod(deg, 360.0) + (deg < 0 ? 360.0 : 0.0);
    if (r == 0.0 || r == 360.0) return {1.0, 0.0};
    if (r == 90.0) return {0.0, 1.0};
    if (r == 180.0) return {-1.0, 0.0};
    if (r == 270.0) return {0.0, -1.0};
    const double a = deg * std::numbers::pi / 180.0;
    return {std::cos(a), std::sin(a)};
}

/** Right-handed rotations about z and y (GLM matrices are column-major: m[col][row]). */
glm::dmat3 rotZ(double deg) {
    const glm::dvec2 cs = cosSin(deg);
    return glm::dmat3(glm::dvec3(cs.x, cs.y, 0), glm::dvec3(-cs.y, cs.x, 0), glm::dvec3(0, 0, 1));
}

glm::dmat3 rotY(double deg) {
    const glm::dvec2 cs = cosSin(deg);
    return glm::dmat3(glm::dvec3(cs.x, 0, -cs.y), glm::dvec3(0, 1, 0), glm::dvec3(cs.y, 0, cs.x));
}

} // namespace

const char* patientPositionName(PatientPosition p) { return axesOf(p).name; }

PatientPosition parsePatientPosition(const std::string& code) {
    std::string c;
    for (const char ch : code)
        if (!std::isspace(static_cast<unsigned char>(ch)))
            c += char(std::toupper(static_cast<unsigned char>(ch)));
    for (const PositionAxes& a : kPositions)
        if (c == a.name) return a.position;
    throw SettingsError("patient position " + quotedWithEscapes(code) +
                        ": expected one of HFS, HFP, FFS, FFP, HFDL, HFDR, FFDL, FFDR (a patient "
                        "lying on the treatment couch; DICOM PatientPosition (0018,5100))");
}

glm::dmat3 patientSupportToLps(PatientPosition p) {
    // The columns of LPS -> support are the patient's L, P and S directions in support axes;
    // support -> LPS is its inverse, a rotation's transpose.
    const PositionAxes& a = axesOf(p);
    const glm::dvec3 left = glm::cross(a.head, a.anterior); // L = H x A (HFS: Ys x Zs = Xs)
    return glm::transpose(glm::dmat3(left, -a.anterior, a.head));
}

glm::dmat3 beamLimitingDeviceToLps(const TreatmentBeam& beam) {
    // b -> g: Rz(collimator); g -> f: Ry(gantry); f -> s: Rz(couch)^T; s -> LPS: M(position).
    return patientSupportToLps(beam.position) * glm::transpose(rotZ(beam.couchDeg)) *
           rotY(beam.gantryDeg) * rotZ(beam.collimatorDeg);
}

ConeCamera treatmentBeamCamera(const TreatmentBeam& beam, int width, int height, double pitchU,
                               double pitchV, glm::dvec2 principalOffset) {
    for (const auto& [name, v] :
         {std::pair{"gantry angle", beam.gantryDeg}, std::pair{"couch angle", beam.couchDeg},
          std::pair{"collimator angle", beam.collimatorDeg}})
        if (!std::isfinite(v))
            throw SettingsError(std::string("treatment beam: the ") + name +
                                " must be finite, found " + formatNumber(v));
    if (!std::isfinite(beam.isocentre.x) || !std::isfinite(beam.isocentre.y) ||
        !std::isfinite(beam.isocentre.z))
        throw SettingsError("treatment beam: the isocentre must be finite");
    if (!(beam.sad > 0.0) || !(beam.sid > beam.sad) || !std::isfinite(beam.sid))
        throw SettingsError("treatment beam: expected 0 < SAD < SID (the imager beyond the "
                            "isocentre), found SAD " +
                            formatNumber(beam.sad) + " mm, SID " + formatNumber(beam.sid) + " mm");
    const glm::dmat3 b = beamLimitingDeviceToLps(beam);
    // Columns along +Xb, rows along -Yb (row 0 toward +Yb, seen from the source).
    return coneCamera(beam.isocentre + beam.sad * b[2],
                      beam.isocentre + (beam.sad - beam.sid) * b[2], b[0], -b[1], width, height,
                      pitchU, pitchV, principalOffset);
}

} // namespace fvr::core
