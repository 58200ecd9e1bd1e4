// The 2D/3D registration's evaluation (README, "2D/3D registration"): simulated X-rays of a CT
// at poses drawn uniformly within +-R degrees about each axis and +-T mm along each axis
// (core/registration/simulated_xray.h: polychromatic, noisy, blurred, HU offset, box model),
// registered from the geometry as recorded (the identity), one view (AP) or two (AP and left
// lateral, 90 degrees apart). Success: mTRE < 2 mm over the corners of a 100 mm cube at the
// isocentre. Prints one JSON line per registration and a summary; --json FILE writes them all.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <fvr/core/io/open_study.h>
#include <fvr/core/registration/registration.h>
#include <fvr/core/registration/simulated_xray.h>

#ifdef FVR_EVAL_GPU
#include <fvr/gpu/drr_renderer.h>
#include <fvr/gpu/egl_context.h>
#endif

using namespace fvr::core;
using Json = nlohmann::json;

namespace {

struct Config {
    std::string ct;
    int views = 1, poses = 10, size = 256, global = 200, threads = 2;
    double rangeDeg = 10.0, rangeMm = 20.0, sid = 1000.0, sod = 750.0;
    unsigned seed = 1;
    std::string similarity = "gradient-ncc", json;
    bool gpu = false, noCoverage = false;
    double detectorBlur = 0.0, globalRange = 15.0;
    XraySimulation sim;
};

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::vector<ConeCamera> cameras(const Config& c, const Volume& ct) {
    std::vector<ConeCamera> out;
    const double pitch = framingPitch(ct, c.sid, c.sod, c.size, c.size);
    for (int v = 0; v < c.views; ++v) {
        CArm arm;
        arm.primaryDeg = v == 0 ? 0.0 : 90.0;
        arm.sid = c.sid;
        arm.sod = c.sod;
        arm.isocentre = volumeCentre(ct);
        out.push_back(cArmCamera(arm, c.size, c.size, pitch, pitch));
    }
    return out;
}

Json runOne(const Config& c, const Volume& ct, const std::vector<ConeCamera>& cams,
            const Pose& truth, int index, const RegistrationOptions& options) {
    const glm::dvec3 centre = volumeCentre(ct);
    const glm::dmat4 tTruth = poseMatrix(truth, centre);
    std::vector<RegistrationView> views;
    for (std::size_t v = 0; v < cams.size(); ++v) {
        XraySimulation sim = c.sim;
        sim.seed = std::uint64_t(c.seed) * 1000 + std::uint64_t(index) * 10 + v;
        sim.threads = c.threads;
        views.push_back(
            {"view " + std::to_string(v + 1), cams[v], simulateXray(ct, cams[v], tTruth, sim), {}});
    }
    const RegistrationResult r = registerPose(ct, views, Pose{}, options);
    const std::vector<glm::dvec3> targets = cubeCorners(centre, 100.0);
    const double before = meanTargetError(tTruth, glm::dmat4(1.0), targets);
    const double after = meanTargetError(tTruth, r.matrix, targets);
    Json j{
        {"index", index},
        {"truth_rotation_deg", {truth.rotationDeg.x, truth.rotationDeg.y, truth.rotationDeg.z}},
        {"truth_translation_mm",
         {truth.translationMm.x, truth.translationMm.y, truth.translationMm.z}},
        {"found_rotation_deg", {r.pose.rotationDeg.x, r.pose.rotationDeg.y, r.pose.rotationDeg.z}},
        {"found_translation_mm",
         {r.pose.translationMm.x, r.pose.translationMm.y, r.pose.translationMm.z}},
        {"mtre_before_mm", before},
        {"mtre_mm", after},
        {"success", after < 2.0},
        {"seconds", r.seconds},
        {"evaluations", r.evaluations},
        {"drrs", r.drrs},
        {"similarity_before", r.similarityBefore},
        {"similarity_after", r.similarityAfter}};
    for (const StageReport& s : r.stages)
        j["stages"].push_back(
            {{"name", s.name},
             {"mtre_mm", meanTargetError(tTruth, poseMatrix(s.pose, centre), targets)},
             {"seconds", s.seconds},
             {"drrs", s.drrs},
             {"image", s.imageWidth},
             {"voxel_mm", s.voxelMm},
             {"renderer", s.renderer}});
    return j;
}

} // namespace

int run(int argc, char** argv) {
    Config c;
    CLI::App app{"fvr_register_eval: 2D/3D registration against simulated X-rays"};
    app.add_option("ct", c.ct, "CT: DICOM folder, volume file or phantom:chest")->required();
    app.add_option("--views", c.views, "1 (AP) or 2 (AP and lateral)")->check(CLI::Range(1, 2));
    app.add_option("--poses", c.poses, "registrations");
    app.add_option("--range-deg", c.rangeDeg, "truth rotations uniform in +-R");
    app.add_option("--range-mm", c.rangeMm, "truth translations uniform in +-T");
    app.add_option("--size", c.size, "detector pixels per side");
    app.add_option("--global", c.global, "global stage samples (0: none)");
    app.add_option("--global-range", c.globalRange,
                   "the global stage's range: +-DEG degrees and +-DEG mm x 2 (default 15)");
    app.add_option("--threads", c.threads, "CPU threads");
    app.add_option("--seed", c.seed, "pose and noise seed");
    app.add_option("--similarity", c.similarity, "ncc or gradient-ncc");
    app.add_flag("--no-coverage", c.noCoverage, "no coverage mask");
    app.add_option("--detector-blur", c.detectorBlur, "the blur the registration models (px)");
    app.add_option("--sim-kvp", c.sim.kvp, "simulated tube kVp");
    app.add_option("--sim-mas", c.sim.mAs, "simulated exposure (0: no noise)");
    app.add_option("--sim-blur", c.sim.blurPixels, "simulated detector blur (pixels)");
    app.add_option("--sim-hu", c.sim.huOffset, "simulated CT number offset (HU)");
    app.add_option("--json", c.json, "write every registration's JSON here");
#ifdef FVR_EVAL_GPU
    app.add_flag("--gpu", c.gpu, "render the DRRs on the GPU (headless EGL)");
#endif
    CLI11_PARSE(app, argc, argv);

    const Volume ct = openStudy(classifyInput(c.ct)).volume;
    const std::vector<ConeCamera> cams = cameras(c, ct);
    RegistrationOptions options;
    options.similarity = parseSimilarity(c.similarity);
    options.projector.threads = c.threads;
    options.globalSamples = c.global;
    options.globalRangeDeg = c.globalRange;
    options.globalRangeMm = 2.0 * c.globalRange;
    options.coverageMask = !c.noCoverage;
    options.detectorBlurPixels = c.detectorBlur;
#ifdef FVR_EVAL_GPU
    std::unique_ptr<fvr::gpu::EglContext> gpu;
    if (c.gpu) {
        gpu = std::make_unique<fvr::gpu::EglContext>();
        std::fprintf(stderr, "GPU: %s\n", gpu->description().c_str());
        options.renderer = fvr::gpu::gpuDrrRendererFactory();
    }
#endif
    std::mt19937 rng(c.seed);
    std::uniform_real_distribution<double> rot(-c.rangeDeg, c.rangeDeg), mm(-c.rangeMm, c.rangeMm);
    Json all = Json::array();
    std::vector<double> mtre, seconds;
    int successes = 0;
    for (int i = 0; i < c.poses; ++i) {
        Pose truth;
        truth.rotationDeg = {rot(rng), rot(rng), rot(rng)};
        truth.translationMm = {mm(rng), mm(rng), mm(rng)};
        const Json j = runOne(c, ct, cams, truth, i, options);
        std::printf("%s\n", j.dump().c_str());
        std::fflush(stdout);
        mtre.push_back(j["mtre_mm"]);
        seconds.push_back(j["seconds"]);
        successes += j["success"].get<bool>() ? 1 : 0;
        all.push_back(j);
    }
    const Json summary{{"ct", c.ct},
                       {"views", c.views},
                       {"poses", c.poses},
                       {"range_deg", c.rangeDeg},
                       {"range_mm", c.rangeMm},
                       {"success_rate", double(successes) / c.poses},
                       {"median_mtre_mm", median(mtre)},
                       {"median_seconds", median(seconds)},
                       {"threads", c.threads},
                       {"global", c.global},
                       {"global_range_deg", c.globalRange},
                       {"gpu", c.gpu},
                       {"coverage_mask", !c.noCoverage},
                       {"detector_blur_px", c.detectorBlur},
                       {"simulation",
                        {{"kvp", c.sim.kvp},
                         {"mAs", c.sim.mAs},
                         {"blur_px", c.sim.blurPixels},
                         {"hu_offset", c.sim.huOffset}}}};
    std::printf("summary %s\n", summary.dump().c_str());
    if (!c.json.empty()) std::ofstream(c.json) << Json{{"summary", summary}, {"runs", all}}.dump(1);
    return 0;
}

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fvr_register_eval: %s\n", e.what());
        return 1;
    }
}
