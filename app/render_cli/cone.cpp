// fvr-render --geometry cone: cameras, checks, the ray caster and the sidecar (cone.h).
#include "cone.h"

#include <chrono>
#include <cmath>
#include <cstdio>

#include <fvr/core/errors.h>
#include <fvr/core/geometry/projection_matrix_file.h>
#include <fvr/core/render/projection.h>
#include <fvr/core/thread_pool.h>

#include "cone_polychromatic.h"
#include "run.h"

namespace fvr::cli {

using namespace fvr::core;

std::vector<ConeCamera> readConeMatrixFile(const Options& o) {
    if (!o.cone.enabled || o.cone.matrixFile.empty()) return {};
    return readProjectionMatrixFile(o.cone.matrixFile);
}

namespace {

/** The primary angles of the C-arm's views. */
std::vector<double> primaryAngles(const Options& o) {
    const ConeOptions& c = o.cone;
    std::vector<double> angles;
    if (c.orbitViews > 0) {
        for (int i = 0; i < c.orbitViews; ++i)
            angles.push_back(*c.orbitFrom + (*c.orbitTo - *c.orbitFrom) * i / (c.orbitViews - 1));
    } else if (o.sweep > 0) {
        for (int i = 0; i < o.sweep; ++i) angles.push_back(c.arm.primaryDeg + 360.0 * i / o.sweep);
    } else {
        angles.push_back(c.arm.primaryDeg);
    }
    return angles;
}

} // namespace

std::vector<ConeView> beamViews(const Options& o, const Volume& volume) {
    const ConeOptions& c = o.cone;
    std::vector<RtPlanBeam> beams = c.planBeams;
    if (c.beam) {
        beams = {RtPlanBeam{}};
        beams[0].beam = *c.beam;
        beams[0].beam.isocentre = c.isocentre ? *c.isocentre : volumeCentre(volume);
    }
    const int width = c.width > 0 ? c.width : o.settings.size;
    const int height = c.height > 0            ? c.height
                       : o.settings.height > 0 ? o.settings.height
                                               : o.settings.size;
    std::vector<ConeView> views;
    for (const RtPlanBeam& b : beams) {
        double pitchU = c.pitchU, pitchV = c.pitchV;
        if (!(pitchU > 0.0))
            pitchU = pitchV = framingPitch(volume, b.beam.sid, b.beam.sad, width, height);
        views.push_back(
            {treatmentBeamCamera(b.beam, width, height, pitchU, pitchV, c.principalOffset),
             std::nullopt, b});
    }
    return views;
}

ConeFiles readConeFiles(const Options& o) {
    ConeFiles files;
    files.matrixCameras = readConeMatrixFile(o);
    files.xray = readConeXray(o);
    return files;
}

std::vector<ConeView> coneViews(const Options& o, const Volume& volume, const ConeFiles& files) {
    std::vector<ConeView> views;
    for (const ConeCamera& camera : files.matrixCameras) views.push_back({camera, std::nullopt});
    if (!views.empty()) return views;
    if (files.xray) return xrayViews(o, volume, *files.xray);
    if (o.cone.beams()) return beamViews(o, volume);
    const ConeOptions& c = o.cone;
    CArm arm = c.arm;
    arm.isocentre = c.isocentre ? *c.isocentre : volumeCentre(volume);
    const int width = c.width > 0 ? c.width : o.settings.size;
    const int height = c.height > 0            ? c.height
                       : o.settings.height > 0 ? o.settings.height
                                               : o.settings.size;
    double pitchU = c.pitchU, pitchV = c.pitchV;
    if (!(pitchU > 0.0)) pitchU = pitchV = framingPitch(volume, arm.sid, arm.sod, width, height);
    for (const double angle : primaryAngles(o)) {
        arm.primaryDeg = angle;
        views.push_back({cArmCamera(arm, width, height, pitchU, pitchV, c.principalOffset), arm});
    }
    return views;
}

ConeProjectorOptions coneProjectorOptions(const Options& o) {
    ConeProjectorOptions po;
    po.model = o.cone.model;
    po.stepFraction = o.cone.step;
    po.mapping = o.settings.values;
    po.threads = o.threads;
    // The pixel aperture: n x n rays per pixel, averaged (the pixel's area, box-filtered).
    po.pixelSubsamples = o.settings.pixelAperture ? o.cone.pixelSubsamples : 1;
    return po;
}

DetectorImage projectConeView(const ConeSession& s, const ConeCamera& camera) {
    DetectorImage img = s.caster.project(camera);
    if (s.options.cone.flatField) {
        // I = I0 f exp(-mu p) = I0 exp(-mu (p - ln f / mu)): the flat field folded into the
        // line integrals, so that the writers' transmission and film window (outputs.cpp) see
        // the detector's exposure as they see the parallel views'.
        const std::vector<float> f = detectorFlatField(camera);
        const double mu = s.options.transmission.muWaterPerMm;
        for (std::size_t k = 0; k < img.pixels.size(); ++k)
            img.pixels[k] = float(double(img.pixels[k]) - std::log(double(f[k])) / mu);
    }
    return img;
}

std::vector<ConeView> coneBenchViews(const ConeSession& s, const std::vector<ConeView>& views) {
    const int n = s.options.bench;
    std::vector<ConeView> out;
    for (int i = 0; i < n; ++i) {
        ConeView v = views[std::size_t(i) % views.size()];
        if (v.arm) { // an orbit from the first view
            v = views.front();
            v.arm->primaryDeg += 360.0 * i / n;
            v.camera = cArmCamera(*v.arm, v.camera.width, v.camera.height, v.camera.pitchU,
                                  v.camera.pitchV, v.camera.principalOffset);
        }
        validateConeView(v.camera, s.volume);
        out.push_back(v);
    }
    return out;
}

int renderCone(const Options& asked, const Volume& volume, const ConeFiles& files,
               const DicomExportInfo& exportInfo) {
    const Options o = resolvedForVolume(asked, volume);
    for (const auto& w : o.cone.planWarnings)
        std::fprintf(stderr, "fvr-render: warning: %s: %s\n", o.cone.rtplan.c_str(), w.c_str());
    // Every view is checked against the volume before anything is rendered.
    const std::vector<ConeView> views = coneViews(o, volume, files);
    for (std::size_t i = 0; i < views.size(); ++i) {
        try {
            validateConeView(views[i].camera, volume);
        } catch (const SettingsError& e) {
            throw SettingsError(views.size() > 1 ? "view " + std::to_string(i) + ": " + e.what()
                                                 : std::string(e.what()));
        }
    }
    if (o.polychromatic()) return renderConePolychromatic(o, volume, views, files);
    const auto t0 = std::chrono::steady_clock::now();
    const std::unique_ptr<ConeCaster> caster = makeConeCaster(o, volume, coneProjectorOptions(o));
    const double prepareMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    // The C-arms of a .dcm output or --send before any rendering: a matrix-file camera may
    // have none.
    const ConeDicom dicom = !o.out.empty() && (o.format == OutputFormat::Dicom || !o.send.empty())
                                ? coneDicom(volume, views)
                                : ConeDicom{};
    const ConeSession s{
        o,      volume,    *caster, prepareMs, o.threads > 0 ? o.threads : hardwareThreads(),
        &files, exportInfo};
    if (o.bench > 0) runConeBench(s, views);
    if (!o.out.empty()) writeConeOutputs(s, views, dicom);
    return 0;
}

namespace {

Json vec3Json(const glm::dvec3& v) { return Json::array({v.x, v.y, v.z}); }

/** A view's treatment beam: IEC 61217 angles, distances, isocentre, patient position, and the
 *  plan's beam number and name (--rtplan). */
Json treatmentBeamJson(const RtPlanBeam& b) {
    Json j{{"convention", "IEC 61217; image seen from the source, columns +Xb, rows -Yb"},
           {"gantry_angle_deg", b.beam.gantryDeg},
           {"couch_angle_deg", b.beam.couchDeg},
           {"collimator_angle_deg", b.beam.collimatorDeg},
           {"sad_mm", b.beam.sad},
           {"sid_mm", b.beam.sid},
           {"isocenter_mm", vec3Json(b.beam.isocentre)},
           {"patient_position", patientPositionName(b.beam.position)}};
    if (b.number != 0 || !b.name.empty()) {
        j["beam_number"] = b.number;
        j["beam_name"] = b.name;
        j["delivery_type"] = b.deliveryType;
        j["sad_stated"] = b.sadStated;
    }
    return j;
}

} // namespace

Json coneSettingsJson(const ConeSession& s) {
    const Options& o = s.options;
    const ConeProjectorOptions& po = s.caster.options();
    return Json{{"input", o.input},
                {"geometry", "cone"},
                {"backend", s.caster.name()},
                {"renderer", s.caster.description()},
                {"ray_model", rayModelName(po.model)},
                {"step", po.stepFraction},
                {"values", valueMappingName(o.settings.values)},
                {"threads", s.threads},
                {"flat_field", o.cone.flatField},
                {"pixel_aperture", o.settings.pixelAperture},
                {"pixel_subsamples", po.pixelSubsamples},
                {"projection_matrix_file",
                 o.cone.matrixFile.empty() ? Json(nullptr) : Json(o.cone.matrixFile)},
                {"rtplan", o.cone.rtplan.empty() ? Json(nullptr) : Json(o.cone.rtplan)},
                {"geometry_from",
                 s.files && s.files->xray ? xrayGeometryJson(o, *s.files->xray) : Json(nullptr)}};
}

Json coneViewJson(const ConeView& view) {
    const ConeCamera& c = view.camera;
    Json j = Json::object();
    if (view.arm)
        j["c_arm"] = {{"primary_angle_deg", view.arm->primaryDeg},
                      {"secondary_angle_deg", view.arm->secondaryDeg},
                      {"sid_mm", view.arm->sid},
                      {"sod_mm", view.arm->sod},
                      {"isocenter_mm", vec3Json(view.arm->isocentre)}};
    if (view.beam) j["treatment_beam"] = treatmentBeamJson(*view.beam);
    const ProjectionMatrix p = c.matrix();
    Json rows = Json::array();
    for (const auto& r : p.rows) rows.push_back(Json::array({r.x, r.y, r.z, r.w}));
    j["source_mm"] = vec3Json(c.source);
    j["detector_centre_mm"] = vec3Json(c.detectorCentre);
    j["u"] = vec3Json(c.u);
    j["v"] = vec3Json(c.v);
    j["width"] = c.width;
    j["height"] = c.height;
    j["pitch_mm"] = Json::array({c.pitchU, c.pitchV});
    j["principal_offset_px"] = Json::array({c.principalOffset.x, c.principalOffset.y});
    j["source_to_detector_mm"] = c.sourceToDetector();
    j["projection_matrix"] = rows;
    return j;
}

Json coneSidecarJson(const ConeSession& s, const WrittenOutput& output,
                     const std::vector<ConeView>& views) {
    Json viewList = Json::array();
    for (const auto& v : views) viewList.push_back(coneViewJson(v));
    const ConeCamera& first = views.front().camera;
    return Json{
        {"generator", "fvr-render"},
        {"geometry", "cone"},
        {"settings", coneSettingsJson(s)},
        {"volume", volumeBlockJson(s.volume)},
        {"output", outputBlockJson(s.options, output)},
        {"image",
         {{"width", first.width},
          {"height", first.height},
          {"pitch_mm", Json::array({first.pitchU, first.pitchV})},
          {"pixel", "(col, row), row 0 at the top, is the line integral from the source to the "
                    "pixel's centre, detector_centre + (col - (W-1)/2 + du) pu u + (row - (H-1)/2 "
                    "+ dv) pv v (patient LPS mm); projection_matrix P maps [x, y, z, 1] to "
                    "[w col, w row, w]"}}},
        {"views", viewList}};
}

} // namespace fvr::cli
