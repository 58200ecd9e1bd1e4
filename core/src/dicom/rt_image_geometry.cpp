// An RT Image's treatment beam and imager read into cameras (rt_image.h, xray_geometry.h).
#include "rt_image_internal.h"

#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include <fvr/core/errors.h>

#include "dicom_internal.h"

namespace fvr::core::dicom_detail {

namespace {

/** The values of a numeric element (numbersOf): empty when absent or empty; throws naming the
 *  file and the tag when they are not `count` of them. */
std::vector<double> numbersOf(DcmItem* item, const DcmTagKey& tag, std::size_t count,
                              const fs::path& file) {
    std::vector<double> out = dicom_detail::numbersOf(item, tag, file);
    if (!out.empty() && out.size() != count)
        fail(file, tagText(tag) + " holds " + std::to_string(out.size()) + " values, expected " +
                       std::to_string(count));
    return out;
}

/** One number, or `fallback` with a warning that names the tag and says what it means. */
double numberOr(XrayGeometry& g, DcmItem* ds, const DcmTagKey& tag, double fallback,
                const std::string& meaning) {
    const std::vector<double> v = numbersOf(ds, tag, 1, g.file);
    if (!v.empty()) return v[0];
    g.warnings.push_back(tagText(tag) + " missing: assumed " + num(fallback) + " " + meaning);
    return fallback;
}

/** The beam (IEC 61217 angles, SAD, SID, patient position, isocentre) the file states. */
TreatmentBeam beamOf(XrayGeometry& g, DcmDataset* ds) {
    TreatmentBeam b;
    const std::vector<double> sid = numbersOf(ds, DCM_RTImageSID, 1, g.file);
    if (sid.empty())
        fail(g.file, "RTImageSID (3002,0026) missing: the distance from the source to the "
                     "image plane (IEC 61217) is needed to place the RT Image's imager");
    b.sid = sid[0];
    b.sad = numberOr(g, ds, DCM_RadiationMachineSAD, 1000.0, "mm (a linac's)");
    if (!(b.sad > 0.0) || !(b.sid > b.sad))
        fail(g.file, "RadiationMachineSAD (3002,0022) " + num(b.sad) +
                         " mm and RTImageSID (3002,0026) " + num(b.sid) +
                         " mm: expected 0 < SAD < SID (an image plane beyond the isocentre)");
    b.gantryDeg = numberOr(g, ds, DCM_GantryAngle, 0.0, "deg");
    b.collimatorDeg = numberOr(g, ds, DCM_BeamLimitingDeviceAngle, 0.0, "deg");
    b.couchDeg = numberOr(g, ds, DCM_PatientSupportAngle, 0.0, "deg");
    const std::string position = stringOf(ds, DCM_PatientPosition);
    if (position.empty()) {
        g.warnings.push_back("PatientPosition (0018,5100) missing: assumed HFS (head first "
                             "supine)");
    } else {
        try {
            b.position = parsePatientPosition(position);
        } catch (const SettingsError& e) {
            fail(g.file, std::string("PatientPosition (0018,5100): ") + e.what());
        }
    }
    const std::vector<double> iso = numbersOf(ds, DCM_IsocenterPosition, 3, g.file);
    g.isocentreStated = !iso.empty();
    if (g.isocentreStated) b.isocentre = glm::dvec3(iso[0], iso[1], iso[2]);
    return b;
}

/** The imager's camera about the beam's isocentre (PS3.3 C.8.8.2.7: rows along +Xr, columns
 *  along -Yr unless RT Image Orientation says otherwise; RT Image Position the first pixel's
 *  centre in the receptor's x, y; the receptor's origin at XRayImageReceptorTranslation in
 *  IEC GANTRY, turned by XRayImageReceptorAngle about Zg). */
ConeCamera imagerOf(XrayGeometry& g, DcmDataset* ds, const TreatmentBeam& b) {
    const std::string plane = stringOf(ds, DCM_RTImagePlane);
    if (!plane.empty() && plane != "NORMAL")
        fail(g.file, "RTImagePlane (3002,000C) '" + plane +
                         "': only an image plane normal to the beam axis (NORMAL) is read");
    const double angle =
        numberOr(g, ds, DCM_XRayImageReceptorAngle, 0.0, "deg (the receptor not rotated)");
    std::vector<double> t = numbersOf(ds, DCM_XRayImageReceptorTranslation, 3, g.file);
    if (t.empty()) t = {0.0, 0.0, b.sad - b.sid};
    if (std::abs(t[2] - (b.sad - b.sid)) > 1e-3)
        g.warnings.push_back("XRayImageReceptorTranslation (3002,000D) z " + num(t[2]) +
                             " mm is not RadiationMachineSAD - RTImageSID = " + num(b.sad - b.sid) +
                             " mm: the image plane is placed at RTImageSID");
    std::vector<double> sp = numbersOf(ds, DCM_ImagePlanePixelSpacing, 2, g.file);
    if (sp.empty()) {
        sp = {1.0, 1.0};
        g.warnings.push_back("ImagePlanePixelSpacing (3002,0011) missing: assumed 1 x 1 mm");
    }
    if (!(sp[0] > 0.0) || !(sp[1] > 0.0))
        fail(g.file, "ImagePlanePixelSpacing (3002,0011): expected two spacings > 0, found " +
                         num(sp[0]) + " \\ " + num(sp[1]));
    g.pitchV = sp[0]; // between rows
    g.pitchU = sp[1]; // between columns
    std::vector<double> pos = numbersOf(ds, DCM_RTImagePosition, 2, g.file);
    if (pos.empty()) {
        pos = {-0.5 * (g.width - 1) * g.pitchU, 0.5 * (g.height - 1) * g.pitchV};
        g.warnings.push_back("RTImagePosition (3002,0012) missing: the image assumed centred "
                             "on the receptor's origin");
    }
    std::vector<double> o = numbersOf(ds, DCM_RTImageOrientation, 6, g.file);
    if (o.empty()) o = {1.0, 0.0, 0.0, 0.0, -1.0, 0.0};
    const glm::dvec3 ro(o[0], o[1], o[2]), co(o[3], o[4], o[5]);
    if (std::abs(o[2]) > 1e-6 || std::abs(o[5]) > 1e-6 || std::abs(glm::length(ro) - 1) > 1e-4 ||
        std::abs(glm::length(co) - 1) > 1e-4 || std::abs(glm::dot(ro, co)) > 1e-4)
        fail(g.file, "RTImageOrientation (3002,0010): expected two orthonormal directions in "
                     "the receptor's plane (z = 0)");
    TreatmentBeam gantry = b, receptor = b;
    gantry.collimatorDeg = 0.0;
    receptor.collimatorDeg = angle;
    const glm::dmat3 G = beamLimitingDeviceToLps(gantry), R = beamLimitingDeviceToLps(receptor);
    const glm::dvec3 source = b.isocentre + b.sad * R[2];
    const glm::dvec3 origin = b.isocentre + G * glm::dvec3(t[0], t[1], b.sad - b.sid);
    const glm::dvec3 u = glm::normalize(R[0] * o[0] + R[1] * o[1]);
    const glm::dvec3 v = glm::normalize(R[0] * o[3] + R[1] * o[4]);
    const glm::dvec3 first = origin + R[0] * pos[0] + R[1] * pos[1];
    const glm::dvec3 foot = source - R[2] * glm::dot(source - first, R[2]);
    g.principalOffset = {glm::dot(first - foot, u) / g.pitchU + 0.5 * (g.width - 1),
                         glm::dot(first - foot, v) / g.pitchV + 0.5 * (g.height - 1)};
    try {
        return coneCamera(source, foot, u, v, g.width, g.height, g.pitchU, g.pitchV,
                          g.principalOffset);
    } catch (const SettingsError& e) {
        fail(g.file, std::string("the RT Image's imager: ") + e.what());
    }
}

} // namespace

void readRtImageGeometry(XrayGeometry& g, DcmDataset* ds, std::int64_t frames) {
    const TreatmentBeam beam = beamOf(g, ds);
    if (const std::vector<double> a = numbersOf(ds, DCM_XRayImageReceptorAngle, 1, g.file);
        !a.empty() && std::abs(a[0] - beam.collimatorDeg) > 1e-9)
        g.warnings.push_back("XRayImageReceptorAngle (3002,000E) " + num(a[0]) +
                             " deg is not BeamLimitingDeviceAngle (300A,0120) " +
                             num(beam.collimatorDeg) +
                             " deg: the image is oriented by the receptor's angle");
    const ConeCamera camera = imagerOf(g, ds, beam);
    for (std::int64_t k = 0; k < frames; ++k) { // one geometry for every frame
        g.beams.push_back(beam);
        g.beamCameras.push_back(camera);
    }
}

} // namespace fvr::core::dicom_detail
