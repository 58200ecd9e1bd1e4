// fvr-render --geometry cone with DICOM X-rays: the camera of --geometry-from XRAY.dcm, and the
// C-arms that a .dcm output carries (cone.h).
#include <cmath>
#include <cstdio>
#include <string>

#include <fvr/core/errors.h>

#include "cone.h"

namespace fvr::cli {

using namespace fvr::core;

namespace {

std::string xyzText(const glm::dvec3& p) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "%g,%g,%g", p.x, p.y, p.z);
    return buf;
}

/** The frames --frame names: one, or every frame with --frame all. */
std::vector<std::size_t> framesOf(const Options& o, const XrayGeometry& g) {
    if (!o.cone.allFrames) return {std::size_t(o.cone.frame)};
    std::vector<std::size_t> all(g.frameCount());
    for (std::size_t k = 0; k < all.size(); ++k) all[k] = k;
    return all;
}

/** Where the views' isocentre comes from. */
const char* isocentreSource(const Options& o, const XrayGeometry& g) {
    if (g.isocentreStated) return "the file";
    return o.cone.isocentre ? "--isocenter" : "the volume's centre";
}

} // namespace

std::optional<XrayGeometry> readConeXray(const Options& o) {
    if (!o.cone.enabled || o.cone.geometryFrom.empty()) return std::nullopt;
    XrayGeometry g = readXrayGeometry(o.cone.geometryFrom, false);
    const std::size_t n = g.frameCount();
    if (std::size_t(o.cone.frame) >= n)
        throw SettingsError("--frame " + std::to_string(o.cone.frame) + ": " + o.cone.geometryFrom +
                            " has " + std::to_string(n) +
                            (n == 1 ? " frame (0)" : " frames (0.." + std::to_string(n - 1) + ")"));
    for (const std::string& w : g.warnings)
        std::fprintf(stderr, "fvr-render: warning: %s\n", w.c_str());
    if (g.isocentreStated && o.cone.isocentre)
        std::fprintf(
            stderr,
            "fvr-render: warning: --isocenter %s ignored: %s states its isocentre, %s "
            "(a DRR that fvr wrote, or an RT Image's IsocenterPosition)\n",
            xyzText(*o.cone.isocentre).c_str(), o.cone.geometryFrom.c_str(),
            xyzText(g.beams.empty() ? g.frames.front().isocentre : g.beams.front().isocentre)
                .c_str());
    return g;
}

std::vector<ConeView> xrayViews(const Options& o, const Volume& volume, const XrayGeometry& g) {
    const glm::dvec3 isocentre = o.cone.isocentre ? *o.cone.isocentre : volumeCentre(volume);
    std::vector<ConeView> views;
    for (const std::size_t k : framesOf(o, g)) {
        if (!g.beams.empty()) { // an RT Image: its treatment beam
            RtPlanBeam beam;
            beam.beam = g.beams[k];
            if (!g.isocentreStated) beam.beam.isocentre = isocentre;
            views.push_back({g.camera(k, isocentre), std::nullopt, beam});
            continue;
        }
        CArm arm = g.frames[k];
        if (!g.isocentreStated) arm.isocentre = isocentre;
        views.push_back({g.camera(k, isocentre), arm});
    }
    return views;
}

Json xrayGeometryJson(const Options& o, const XrayGeometry& g) {
    Json frames = Json::array();
    for (const std::size_t k : framesOf(o, g)) frames.push_back(k);
    return Json{{"file", o.cone.geometryFrom},
                {"modality", g.modality},
                {"sop_class_uid", g.sopClassUid},
                {"frames_in_file", g.frameCount()},
                {"frames", frames},
                {"isocenter_from", isocentreSource(o, g)},
                {"warnings", g.warnings}};
}

namespace {

/** Whether view `b`'s detector and C-arm equal `a`'s but for the angles (to rounding). */
bool sameRun(const ConeView& a, const CArm& armA, const ConeView& b, const CArm& armB) {
    const ConeCamera &ca = a.camera, &cb = b.camera;
    const double tol = 1e-9 * armA.sid;
    return ca.width == cb.width && ca.height == cb.height &&
           std::abs(ca.pitchU - cb.pitchU) <= 1e-12 * ca.pitchU &&
           std::abs(ca.pitchV - cb.pitchV) <= 1e-12 * ca.pitchV &&
           glm::length(ca.principalOffset - cb.principalOffset) <= 1e-9 &&
           std::abs(armA.sid - armB.sid) <= tol && std::abs(armA.sod - armB.sod) <= tol &&
           glm::length(armA.isocentre - armB.isocentre) <= tol;
}

/** Treatment beams' views as RT Images: each camera must be its beam's imager. */
ConeDicom beamDicom(const std::vector<ConeView>& views) {
    ConeDicom d;
    for (std::size_t i = 0; i < views.size(); ++i) {
        const ConeCamera& c = views[i].camera;
        const TreatmentBeam& b = views[i].beam->beam;
        const ConeCamera e =
            treatmentBeamCamera(b, c.width, c.height, c.pitchU, c.pitchV, c.principalOffset);
        const double tol = 1e-9 * b.sid;
        if (glm::length(e.source - c.source) > tol ||
            glm::length(e.detectorCentre - c.detectorCentre) > tol ||
            glm::length(e.u - c.u) > 1e-9 || glm::length(e.v - c.v) > 1e-9)
            throw SettingsError(
                "a treatment beam's DICOM output (--out FILE.dcm, --send) is an RT Image whose "
                "receptor turns with the collimator: " +
                (views.size() > 1 ? "view " + std::to_string(i) + "'s" : std::string("the")) +
                " imager is not (an RT Image read with --geometry-from whose "
                "XRayImageReceptorAngle or RTImageOrientation differs); write .npy, .pfm or .png, "
                "without --send (the sidecar records the camera)");
        d.beams.push_back(*views[i].beam);
    }
    return d;
}

} // namespace

ConeDicom coneDicom(const Volume& volume, const std::vector<ConeView>& views) {
    if (!views.empty() && views.front().beam) return beamDicom(views);
    ConeDicom d;
    const glm::dvec3 centre = volumeCentre(volume);
    for (std::size_t i = 0; i < views.size(); ++i) {
        if (views[i].arm) {
            d.arms.push_back(*views[i].arm);
            continue;
        }
        try {
            d.arms.push_back(cArmFromCamera(views[i].camera, centre));
        } catch (const SettingsError& e) {
            throw SettingsError(
                "a cone-beam DICOM output (--out FILE.dcm, --send) is an X-ray image, which holds "
                "a C-arm's geometry only: " +
                (views.size() > 1 ? "view " + std::to_string(i) + ": " : std::string()) + e.what() +
                " (write .npy, .pfm or .png, without --send; the sidecar records the camera)");
        }
    }
    d.run = views.size() > 1;
    for (std::size_t i = 1; i < views.size() && d.run; ++i)
        d.run = sameRun(views[0], d.arms[0], views[i], d.arms[i]);
    if (d.run)
        for (CArm& arm : d.arms) { // one SID, SOD and isocentre, as the file holds them
            arm.sid = d.arms[0].sid;
            arm.sod = d.arms[0].sod;
            arm.isocentre = d.arms[0].isocentre;
        }
    return d;
}

} // namespace fvr::cli
