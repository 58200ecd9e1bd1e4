// fvr-render's cone-beam options: the C-arm and detector, --projection-matrix, --geometry-from,
// the treatment beams and RT Plans, and the checks that join them (declared once, as
// options.cpp declares the others).
#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <fvr/core/dicom/rt_plan.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/geometry/projection_matrix_file.h>
#include <fvr/core/geometry/treatment_beam.h>

#include "options_internal.h"

namespace fvr::cli::detail {
namespace {

/** "a,b" as two finite numbers, or nothing. */
std::optional<std::pair<double, double>> toPair(const std::string& s, char sep = ',') {
    const auto at = s.find(sep);
    if (at == std::string::npos) return std::nullopt;
    const auto a = toNumber(s.substr(0, at)), b = toNumber(s.substr(at + 1));
    if (!a || !b) return std::nullopt;
    return std::pair{*a, *b};
}

/** --detector-size "WxH" (or "N": square), each 16..4096; throws SettingsError. */
std::pair<int, int> parseDetectorSize(const std::string& s) {
    return core::parseImageSize(s, "detector size");
}

/** --pitch "PU[,PV]", mm, each > 0; throws SettingsError. */
std::pair<double, double> parsePitch(const std::string& s) {
    const auto one = toNumber(s);
    const auto two = toPair(s);
    if (!one && !two) throw SettingsError("pitch: expected PU or PU,PV in mm, found '" + s + "'");
    const auto p = two ? *two : std::pair{*one, *one};
    if (!(p.first > 0) || !(p.second > 0))
        throw SettingsError("pitch: expected a positive number of mm, found '" + s + "'");
    return p;
}

/** --orbit "FROM:TO:N" (degrees, N >= 2 views); throws SettingsError. */
std::tuple<double, double, int> parseOrbit(const std::string& s) {
    const auto bad = [&] {
        return SettingsError("orbit: expected FROM:TO:N (degrees, N >= 2 views), found '" + s +
                             "'");
    };
    const auto a = s.find(':'), b = s.rfind(':');
    if (a == std::string::npos || a == b) throw bad();
    const auto from = toNumber(s.substr(0, a)), to = toNumber(s.substr(a + 1, b - a - 1));
    const auto n = core::parseNumber<int>(s.substr(b + 1));
    if (!from || !to || !n || *n < 2 || *n > 100000) throw bad();
    return {*from, *to, *n};
}

/** The camera options of --geometry cone (checked together in checkGeometry). */
void declareConeCamera(CLI::App& app, ConeOptions& c) {
    const std::string g = "Cone beam (--geometry cone)";
    addNumber(app, "--primary-angle", c.arm.primaryDeg, "DEG",
              "C-arm primary angle, DICOM's PositionerPrimaryAngle: LAO +, RAO -\n"
              "(default 0: source posterior, detector anterior, the AP position)")
        ->group(g);
    addNumber(
        app, "--secondary-angle", c.arm.secondaryDeg, "DEG",
        "C-arm secondary angle -90..90, DICOM's PositionerSecondaryAngle:\n"
        "cranial +, caudal - (default 0)",
        [](double v) { return v >= -90 && v <= 90; }, "expected -90..90 degrees")
        ->group(g);
    addNumber(
        app, "--sid", c.arm.sid, "MM",
        "source to detector distance (default 1000; 1500 with --beam or --rtplan)",
        [](double v) { return v > 0; }, "expected a positive number of mm")
        ->group(g);
    addNumber(
        app, "--sod", c.arm.sod, "MM", "source to isocentre distance, < SID (default 750)",
        [](double v) { return v > 0; }, "expected a positive number of mm")
        ->group(g);
    app.add_option_function<std::string>(
           "--isocenter",
           [&c](const std::string& s) {
               const core::Vec3 v = *toVec3(s);
               c.isocentre = glm::dvec3(v[0], v[1], v[2]);
           },
           "the isocentre in patient LPS mm (default: the volume's centre)")
        ->check(CLI::Validator(
            [](std::string& s) -> std::string {
                return toVec3(s) ? "" : "expected x,y,z, found '" + s + "'";
            },
            ""))
        ->option_text("X,Y,Z")
        ->group(g);
    app.add_option_function<std::string>(
           "--detector-size",
           [&c](const std::string& s) { std::tie(c.width, c.height) = parseDetectorSize(s); },
           "detector columns x rows, 16..4096 each (default: --size square)")
        ->check(coreCheck(parseDetectorSize))
        ->option_text("WxH")
        ->group(g);
    app.add_option_function<std::string>(
           "--pitch", [&c](const std::string& s) { std::tie(c.pitchU, c.pitchV) = parsePitch(s); },
           "detector pixel pitch in mm, columns[,rows] (default: the volume's\n"
           "diagonal magnified at the isocentre fills the detector)")
        ->check(coreCheck(parsePitch))
        ->option_text("PU[,PV]")
        ->group(g);
    app.add_option_function<std::string>(
           "--principal-point",
           [&c](const std::string& s) {
               const auto p = *toPair(s);
               c.principalOffset = {p.first, p.second};
           },
           "the principal-point offset in pixels (default 0,0): pixel (i, j) lies at\n"
           "the detector centre + (i - (W-1)/2 + DU) pu u + (j - (H-1)/2 + DV) pv v,\n"
           "so the isocentre images at pixel ((W-1)/2 - DU, (H-1)/2 - DV)")
        ->check(CLI::Validator(
            [](std::string& s) -> std::string {
                return toPair(s) ? "" : "expected DU,DV in pixels, found '" + s + "'";
            },
            ""))
        ->option_text("DU,DV")
        ->group(g);
}

/** --geometry-from and --frame: the camera of an X-ray (checked in checkGeometryFrom). */
void declareConeFromXray(CLI::App& app, ConeOptions& c) {
    const std::string g = "Cone beam (--geometry cone)";
    app.add_option("--geometry-from", c.geometryFrom,
                   "the camera of a DICOM X-ray (XA, RF, DX, CR: its C-arm angles, SID, SOD,\n"
                   "detector size and pitch) or RT Image (its treatment beam and imager)\n"
                   "instead of the C-arm options; the isocentre is the file's where it\n"
                   "states one (a DRR fvr wrote, an RT Image's IsocenterPosition), else\n"
                   "--isocenter, else the volume's centre")
        ->option_text("XRAY.dcm")
        ->group(g);
    app.add_option_function<std::string>(
           "--frame",
           [&c](const std::string& s) {
               c.allFrames = s == "all";
               if (!c.allFrames) c.frame = *core::parseNumber<int>(s);
           },
           "with --geometry-from: the frame whose C-arm places the view, 0-based\n"
           "(default 0), or all (every frame's, one view each)")
        ->check(CLI::Validator(
            [](std::string& s) -> std::string {
                const auto k = core::parseNumber<int>(s);
                return s == "all" || (k && *k >= 0)
                           ? ""
                           : "expected a frame number 0, 1, ... or all, found '" + s + "'";
            },
            ""))
        ->option_text("K|all")
        ->group(g);
}

} // namespace

void declareCone(CLI::App& app, ConeOptions& c) {
    const std::string g = "Cone beam (--geometry cone)";
    app.add_option_function<std::string>(
           "--geometry", [&c](const std::string& s) { c.enabled = s == "cone"; },
           "parallel (default: Fourier volume rendering) | cone (a point source and a\n"
           "flat detector, as a C-arm or a radiograph: ray cast on the CPU)")
        ->check(CLI::IsMember({"parallel", "cone"}))
        ->option_text("parallel|cone")
        ->group(g);
    declareConeCamera(app, c);
    declareConeFromXray(app, c);
    addParsed(app, "--ray-model", c.model, core::parseRayModel, "M",
              "trilinear (default; exact per cell) | bspline (cubic B-spline, sampled)\n"
              "| box (voxels as cubes, exact path lengths: plastimatch drr -i exact)")
        ->group(g);
    addNumber(
        app, "--step", c.step, "F",
        "ray step as a fraction 0..4 of the smallest voxel spacing (trilinear:\n"
        "default 0 = exact; bspline: default 0.25; not for box)",
        [](double v) { return v >= 0 && v <= 4; }, "expected a fraction in 0..4")
        ->group(g);
    app.add_flag("--flat-field", c.flatField,
                 "with --beer-lambert or --kvp: a real detector's open-beam response,\n"
                 "inverse square x obliquity, (SID/r)^3, multiplies the transmitted intensity")
        ->group(g);
    app.add_option("--pixel-subsamples", c.pixelSubsamples,
                   "with --pixel-aperture: N x N rays per detector pixel, averaged (1..16,\n"
                   "default 4): the pixel's area instead of its centre")
        ->check(CLI::Range(1, 16))
        ->option_text("N")
        ->needs("--pixel-aperture")
        ->group(g);
    app.add_option("--projection-matrix", c.matrixFile,
                   "the camera(s) from a 3x4 projection-matrix file (detector, pitch, then\n"
                   "three rows of four numbers per view; docs/user/fvr-render.md) instead\n"
                   "of the C-arm options")
        ->option_text("FILE")
        ->group(g);
    app.add_option_function<std::string>(
           "--orbit",
           [&c](const std::string& s) {
               double from, to;
               std::tie(from, to, c.orbitViews) = parseOrbit(s);
               c.orbitFrom = from;
               c.orbitTo = to;
           },
           "a rotational run: N views with primary angles FROM to TO inclusive\n"
           "(degrees); --sweep N with --geometry cone: N views 360/N apart from\n"
           "--primary-angle")
        ->check(coreCheck(parseOrbit))
        ->option_text("FROM:TO:N")
        ->group(g);
}

namespace {

/** --rtplan: the plan's beams (only --beam-number's), each checked as a camera with the
 *  imager at `sid`. */
void readPlanBeams(ConeOptions& c, double sid) {
    const core::RtPlan plan = core::readRtPlan(c.rtplan);
    c.planWarnings = plan.warnings;
    std::string numbers;
    for (const core::RtPlanBeam& b : plan.beams) {
        numbers += (numbers.empty() ? "" : ", ") + std::to_string(b.number);
        if (c.beamNumber && b.number != *c.beamNumber) continue;
        c.planBeams.push_back(b);
        c.planBeams.back().beam.sid = sid;
        try {
            core::treatmentBeamCamera(c.planBeams.back().beam, 64, 64, 1.0, 1.0);
        } catch (const SettingsError& e) {
            throw SettingsError("--rtplan " + c.rtplan + ": beam number " +
                                std::to_string(b.number) + ": " + e.what());
        }
    }
    if (c.planBeams.empty())
        throw SettingsError("--beam-number " + std::to_string(*c.beamNumber) + ": " + c.rtplan +
                            " has no such beam (its beams: " + numbers + ")");
}

/** --beam GANTRY,COUCH,COLL: three finite angles in degrees; throws SettingsError. */
glm::dvec3 parseBeamAngles(const std::string& s) {
    const auto v = toVec3(s);
    if (!v)
        throw SettingsError("beam: expected GANTRY,COUCH,COLL in degrees (IEC 61217), found '" + s +
                            "'");
    return {(*v)[0], (*v)[1], (*v)[2]};
}

} // namespace

/** Treatment beams (IEC 61217, core/geometry/treatment_beam.h) as the cone-beam camera, from
 *  the command line or an RT Plan (checked in checkBeam). */
void declareBeam(CLI::App& app, ConeOptions& c) {
    const std::string g = "Treatment beam (--geometry cone)";
    app.add_option_function<std::string>(
           "--beam",
           [&c](const std::string& s) {
               const glm::dvec3 a = parseBeamAngles(s);
               c.beam = core::TreatmentBeam{};
               c.beam->gantryDeg = a.x;
               c.beam->couchDeg = a.y;
               c.beam->collimatorDeg = a.z;
           },
           "a treatment beam instead of the C-arm: IEC 61217 gantry, couch (patient\n"
           "support) and collimator angles in degrees; gantry 0 = source above the\n"
           "couch (AP for HFS), 90 = source at the HFS patient's left. The image is\n"
           "the imager's at --sid (default 1500) seen from the source (columns +Xb,\n"
           "rows -Yb), about --isocenter (default: the volume's centre)")
        ->check(coreCheck(parseBeamAngles))
        ->option_text("G,C,K")
        ->group(g);
    addNumber(
        app, "--sad", c.sad, "MM",
        "with --beam: source to axis (isocentre) distance (default 1000)",
        [](double v) { return v > 0; }, "expected a positive number of mm")
        ->group(g);
    addParsed(app, "--patient-position", c.patientPosition, core::parsePatientPosition, "POS",
              "with --beam: how the patient lies on the couch, DICOM's codes HFS\n"
              "(default), HFP, FFS, FFP, HFDL, HFDR, FFDL, FFDR")
        ->group(g);
    app.add_option("--rtplan", c.rtplan,
                   "the beams of a DICOM RT Plan (each beam's first control point: angles,\n"
                   "isocentre, SAD; the patient position of its setup), one view each in\n"
                   "the plan's order, written as a stack; --sid is the imager's distance")
        ->option_text("FILE")
        ->group(g);
    app.add_option_function<int>(
           "--beam-number", [&c](int n) { c.beamNumber = n; },
           "with --rtplan: only the beam of this Beam Number (300A,00C0)")
        ->option_text("N")
        ->group(g);
}

namespace {

/** The beam options that need --geometry cone, and what each treatment-beam option replaces. */
const std::vector<std::string> kBeamOptions = {"--beam", "--rtplan", "--beam-number", "--sad",
                                               "--patient-position"};
const std::vector<std::pair<std::string, std::string>> kBeamReplaces = {
    {"--primary-angle", "a C-arm angle"},
    {"--secondary-angle", "a C-arm angle"},
    {"--sod", "the beam's source-to-isocentre distance is --sad"},
    {"--orbit", "a C-arm's arc"},
    {"--sweep", "a C-arm's orbit"},
    {"--projection-matrix", "the file fixes the camera"}};
const std::vector<std::pair<std::string, std::string>> kPlanGives = {
    {"--beam", "the plan gives the beams"},
    {"--sad", "the plan gives each beam's SAD"},
    {"--isocenter", "the plan gives each beam's isocentre"},
    {"--patient-position", "the plan's patient setup gives it"}};

/** The treatment beam's checks, and the RT Plan read, before any input loads. */
void checkBeam(const CLI::App& app, Options& o) {
    ConeOptions& c = o.cone;
    if (!c.enabled) {
        for (const auto& name : kBeamOptions)
            if (app.count(name) > 0) throw SettingsError(name + ": only with --geometry cone");
        return;
    }
    if (!c.beams()) {
        for (const auto& name : {"--sad", "--patient-position"})
            if (app.count(name) > 0) throw SettingsError(std::string(name) + ": only with --beam");
        if (app.count("--beam-number") > 0)
            throw SettingsError("--beam-number: only with --rtplan");
        return;
    }
    // A beam's image is seen from the source (the C-arm's mirrored): its DICOM output is an RT
    // Image (core/dicom/rt_image.h), one per beam.
    const std::string way = c.beam ? "--beam" : "--rtplan";
    for (const auto& [name, why] : kBeamReplaces)
        if (app.count(name) > 0) throw SettingsError(name + ": not with " + way + " (" + why + ")");
    if (!c.rtplan.empty()) {
        for (const auto& [name, why] : kPlanGives)
            if (app.count(name) > 0)
                throw SettingsError(name + ": not with --rtplan (" + why + ")");
    } else if (app.count("--beam-number") > 0) {
        throw SettingsError("--beam-number: only with --rtplan");
    }
    const double sid = app.count("--sid") > 0 ? c.arm.sid : 1500.0;
    if (c.beam) {
        c.beam->sad = c.sad;
        c.beam->sid = sid;
        c.beam->position = c.patientPosition;
        try { // the beam's own checks (SAD < SID, finite angles) now
            core::treatmentBeamCamera(*c.beam, 64, 64, 1.0, 1.0);
        } catch (const SettingsError& e) {
            throw SettingsError(std::string("--beam: ") + e.what());
        }
        return;
    }
    readPlanBeams(c, sid);
}

/** The options that only cone beam takes. */
const std::vector<std::string> kConeOnly = {"--primary-angle", "--secondary-angle",
                                            "--sid",           "--sod",
                                            "--isocenter",     "--detector-size",
                                            "--pitch",         "--principal-point",
                                            "--ray-model",     "--step",
                                            "--flat-field",    "--projection-matrix",
                                            "--orbit",         "--geometry-from",
                                            "--frame",         "--pixel-subsamples"};

/** The options that only the parallel (Fourier) renderers take, and why not in cone beam. */
const std::vector<std::pair<std::string, std::string>> kParallelOnly = {
    {"--view", "the C-arm's --primary-angle and --secondary-angle place the view"},
    {"--dir", "the C-arm's --primary-angle and --secondary-angle place the view"},
    {"--up", "the C-arm's --primary-angle and --secondary-angle place the view"},
    {"--axis", "--sweep turns the C-arm's primary angle; --orbit gives an arc"},
    {"--views", "give the views as --projection-matrix FILE"},
    {"--pixel-size", "the detector's --pitch sets the pixel size"},
    {"--kernel", "a Fourier rendering setting; cone beam ray casts: see --ray-model"},
    {"--kernel-width", "a Fourier rendering setting; cone beam ray casts: see --ray-model"},
    {"--deapodize", "a Fourier rendering setting"},
    {"--transform", "a Fourier rendering setting"},
    {"--oversampling", "a Fourier rendering setting"},
    {"--voxel-model", "cone beam takes --ray-model"},
    {"--clip", "cone-beam rays are clipped to the volume always"},
    {"--no-clip", "cone-beam rays are clipped to the volume always"},
    {"--keep-negative", "a Fourier rendering setting"},
    {"--non-negative", "a Fourier rendering setting"},
    {"--depth-cue", "a Fourier rendering setting"},
    {"--sharpen", "a Fourier rendering setting"},
    {"--sharpen-radius", "a Fourier rendering setting"},
    {"--band-limit", "a Fourier rendering setting"},
    {"--fp16", "a Fourier rendering setting (the spectrum's storage)"}};

/** The options --projection-matrix replaces (the file fixes the camera). */
const std::vector<std::string> kMatrixFixes = {
    "--primary-angle",   "--secondary-angle", "--sid",   "--sod",
    "--isocenter",       "--detector-size",   "--pitch", "--size",
    "--principal-point", "--orbit",           "--sweep"};

/** The options --geometry-from replaces: the X-ray's C-arm and detector fix the camera
 *  (--isocenter stays: the isocentre where the file states none). */
const std::vector<std::string> kXrayFixes = {"--primary-angle",
                                             "--secondary-angle",
                                             "--sid",
                                             "--sod",
                                             "--detector-size",
                                             "--pitch",
                                             "--size",
                                             "--orbit",
                                             "--sweep",
                                             "--principal-point",
                                             "--beam",
                                             "--sad",
                                             "--rtplan",
                                             "--beam-number",
                                             "--patient-position"};

/** --geometry-from against the options it replaces, and --frame without it. */
void checkGeometryFrom(const CLI::App& app, const ConeOptions& c) {
    if (c.geometryFrom.empty()) {
        if (app.count("--frame") > 0)
            throw SettingsError("--frame: only with --geometry-from XRAY.dcm");
        return;
    }
    if (!c.matrixFile.empty())
        throw SettingsError("--geometry-from: not with --projection-matrix (one or the other "
                            "gives the camera)");
    for (const auto& name : kXrayFixes)
        if (app.count(name) > 0)
            throw SettingsError(name + ": not with --geometry-from (the X-ray's C-arm and "
                                       "detector fix the camera)");
}

} // namespace

/** The cone-beam checks that need the parsed command line: cone options without --geometry
 *  cone, parallel options with it, and the camera's own checks (before any input loads). */
void checkGeometry(const CLI::App& app, Options& o) {
    checkBeam(app, o);
    const ConeOptions& c = o.cone;
    if (!c.enabled) {
        for (const auto& name : kConeOnly)
            if (app.count(name) > 0) throw SettingsError(name + ": only with --geometry cone");
        return;
    }
    for (const auto& [name, why] : kParallelOnly)
        if (app.count(name) > 0)
            throw SettingsError(name + ": not with --geometry cone (" + why + ")");
    checkGeometryFrom(app, c);
    if (!c.matrixFile.empty())
        for (const auto& name : kMatrixFixes)
            if (app.count(name) > 0)
                throw SettingsError(name + ": not with --projection-matrix (the file fixes "
                                           "the camera and its views)");
    if (c.orbitViews > 0 && app.count("--sweep") > 0)
        throw SettingsError("--orbit: not with --sweep (one or the other gives the views)");
    if (c.orbitViews > 0 && app.count("--primary-angle") > 0)
        throw SettingsError("--orbit: not with --primary-angle (the orbit's FROM is the first "
                            "view's primary angle)");
    if (app.count("--detector-size") > 0 && app.count("--size") > 0)
        throw SettingsError("--detector-size: not with --size (both set the detector's size)");
    if (c.flatField && !o.beerLambert && !o.polychromatic())
        throw SettingsError("--flat-field: multiplies transmitted intensity, so it needs "
                            "--beer-lambert or --kvp");
    if (o.polychromatic() && !o.send.empty())
        throw SettingsError("--send: not with --kvp (I/I0 has no DICOM export yet)");
    if (c.model == core::RayModel::Box && app.count("--step") > 0)
        throw SettingsError("--step: not with --ray-model box (exact path lengths, no step)");
    if (c.matrixFile.empty() && !c.beams() && c.geometryFrom.empty()) {
        // The C-arm's own checks (SOD < SID) now; the isocentre and a default pitch follow
        // from the volume and cannot make it fail.
        core::CArm arm = c.arm;
        arm.isocentre = glm::dvec3(0.0);
        try {
            core::cArmCamera(arm, 64, 64, c.pitchU > 0 ? c.pitchU : 1.0,
                             c.pitchV > 0 ? c.pitchV : 1.0, c.principalOffset);
        } catch (const SettingsError& e) {
            throw SettingsError(std::string("--geometry cone: ") + e.what());
        }
    }
}

} // namespace fvr::cli::detail
