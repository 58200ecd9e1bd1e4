// fvr-register: the pose of a CT that makes its DRRs match one or two X-rays (2D/3D registration,
// core/registration/registration.h). Every input is read and checked before the registration
// starts; the result is one JSON file and the before/after overlays.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/io/open_study.h>
#include <fvr/core/registration/registration.h>
#include <fvr/core/registration/registration_io.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/text.h>

#include "render_cli/json_output.h"

#ifdef FVR_HAVE_GPU
#include <fvr/gpu/drr_renderer.h>
#include <fvr/gpu/egl_context.h>
#endif

namespace {

namespace fs = std::filesystem;
using namespace fvr::core;
using Json = nlohmann::json;

struct Args {
    std::string ct, series;
    std::vector<std::string> xrays;
    std::string init, truth, targets, out, overlayPrefix;
    std::string similarity = "gradient-ncc";
    std::string levels, preset = "default";
    int global = RegistrationOptions().globalSamples; // core's default
    std::string isocentre, values = "auto", offset;
    std::vector<int> frames;
    int threads = 0;
    bool gpu = false;
    bool noCoverageMask = false;
    double detectorBlur = 0.0;
};

/** "a,b,c" as numbers; SettingsError naming the option otherwise. */
std::vector<double> numberList(const std::string& text, std::size_t count, const char* option) {
    std::vector<double> v;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        std::size_t used = 0;
        double x = 0.0;
        try {
            x = std::stod(item, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (used == 0 || item.find_first_not_of(" \t", used) != std::string::npos ||
            !std::isfinite(x))
            throw SettingsError(std::string(option) + " '" + text + "': '" + item +
                                "' is not a number");
        v.push_back(x);
    }
    if (v.size() != count)
        throw SettingsError(std::string(option) + " '" + text + "': expected " +
                            std::to_string(count) + " comma-separated numbers");
    return v;
}

/** The levels of --preset, or of --levels "PIXELS:VOXELMM:EVALS[:STEPDEG:STEPMM],...". */
std::vector<RegistrationLevel> parseLevels(const Args& a) {
    if (a.levels.empty()) {
        const RegistrationOptions defaults;
        if (a.preset == "default") return defaults.levels;
        // Pixels across the X-ray's larger side, CT voxel mm, evaluations, steps.
        if (a.preset == "fast") return {{64, 4.0, 200, 4.0, 8.0}, {128, 2.0, 120, 1.0, 2.0}};
        if (a.preset == "fine")
            return {{64, 6.0, 300, 4.0, 8.0},
                    {128, 3.0, 250, 2.0, 4.0},
                    {256, 1.5, 200, 0.5, 1.0},
                    {512, 0.0, 150, 0.2, 0.4}};
        throw SettingsError("--preset '" + a.preset + "': expected fast, default or fine");
    }
    std::vector<RegistrationLevel> levels;
    std::stringstream ss(a.levels);
    std::string item;
    while (std::getline(ss, item, ',')) {
        std::string colons = item;
        for (char& c : colons)
            if (c == ':') c = ',';
        const std::size_t n = std::size_t(std::count(item.begin(), item.end(), ':')) + 1;
        if (n != 3 && n != 5)
            throw SettingsError("--levels '" + a.levels + "': level '" + item +
                                "' is not PIXELS:VOXELMM:EVALS[:STEPDEG:STEPMM]");
        const std::vector<double> v = numberList(colons, n, "--levels");
        RegistrationLevel l;
        l.imagePixels = int(v[0]);
        l.voxelMm = v[1];
        l.maxEvaluations = int(v[2]);
        if (n == 5) {
            l.stepDeg = v[3];
            l.stepMm = v[4];
        }
        if (v[0] != l.imagePixels || l.imagePixels < 0 || l.voxelMm < 0 || l.maxEvaluations < 1 ||
            !(l.stepDeg > 0) || !(l.stepMm > 0))
            throw SettingsError(
                "--levels '" + a.levels + "': level '" + item +
                "': pixels >= 0 (whole; 0: full resolution), voxel mm >= 0, evaluations >= 1, "
                "steps > 0");
        levels.push_back(l);
    }
    return levels;
}

std::optional<Args> parseArgs(int argc, char** argv) {
    Args a;
    CLI::App app{"fvr-register: the pose of a CT from one or two X-rays (2D/3D registration)"};
    app.add_option("CT", a.ct, "the CT: a DICOM folder or file, .mhd/.mha/.nii(.gz), phantom:chest")
        ->required();
    app.add_option("XRAY", a.xrays,
                   "1 or 2 X-rays: DICOM XA/RF/DX/CR/RT Image, or .npy/.pfm/.png beside the "
                   "JSON sidecar fvr-render wrote (FILE.json)")
        ->required()
        ->expected(1, 2);
    app.add_option("--series", a.series,
                   "a DICOM folder's series to register (its key, as fvr-render --series; default: "
                   "the folder's default series)");
    app.add_option("--out", a.out, "RESULT.json: the pose, similarity, stages and timing")
        ->required();
    app.add_option("--init", a.init, "the initial pose (POSE.json; default: the identity)");
    app.add_option("--truth", a.truth, "the true pose: mTRE before and after, success");
    app.add_option("--targets", a.targets,
                   "target points for mTRE (x,y,z per line, LPS mm; default: the corners of a "
                   "100 mm cube at the isocentre)");
    app.add_option("--similarity", a.similarity, "ncc or gradient-ncc")->capture_default_str();
    app.add_option(
        "--levels", a.levels,
        "the pyramid, coarse to fine: PIXELS:VOXELMM:EVALS[:STEPDEG:STEPMM],... (PIXELS: "
        "the X-ray's larger side at the level, 0 full; VOXELMM: the CT's, 0 as it is)");
    app.add_option("--preset", a.preset, "fast, default or fine (without --levels)")
        ->capture_default_str();
    app.add_option("--global", a.global,
                   "Halton poses of the global stage, at its own coarse level (0: none)")
        ->capture_default_str();
    app.add_option("--isocenter", a.isocentre,
                   "x,y,z (LPS mm): the rotations' centre, and the isocentre of X-rays that do "
                   "not state one (default: the CT's centre)");
    app.add_option("--values", a.values, "auto, line-integrals or intensity")
        ->capture_default_str();
    app.add_option("--frame", a.frames, "the frame of each X-ray (one value: all)")->delimiter(',');
    app.add_option("--offset", a.offset, "rx,ry,rz,tx,ty,tz (deg, mm) added to the initial pose");
    app.add_option("--threads", a.threads, "CPU threads (0: all)")->capture_default_str();
    app.add_flag("--gpu", a.gpu, "render the DRRs on the GPU (EGL) where the build has one");
    app.add_flag("--no-coverage-mask", a.noCoverageMask,
                 "count pixels whose rays leave the CT through its cut ends");
    app.add_option("--detector-blur", a.detectorBlur,
                   "the X-rays' detector blur, a Gaussian's sigma in pixels, given to the DRRs "
                   "too (0: none)")
        ->capture_default_str();
    app.add_option("--overlay-prefix", a.overlayPrefix,
                   "PATH: PATH-before-blend.png, PATH-after-blend.png, -before-checker, "
                   "-after-checker (default: --out without .json)");
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        app.exit(e);
        return std::nullopt;
    } catch (const CLI::ParseError& e) {
        throw SettingsError(e.what());
    }
    return a;
}

} // namespace

namespace {

/** Everything read from the command line's files, checked. */
struct Inputs {
    std::vector<XrayInput> xrays;
    glm::dvec3 centre{0.0};
    glm::dmat4 init{1.0};
    std::optional<glm::dmat4> truth;
    std::vector<glm::dvec3> targets; ///< empty: the cube's corners
    std::vector<double> offset = std::vector<double>(6, 0.0);
    RegistrationOptions options;
    fs::path out, overlayPrefix;
};

/** SettingsError (a bad option: exit status 2) when `file` cannot be written: a folder, or its
 * folder missing or read-only. */
void checkWritable(const fs::path& file, const std::string& what) {
    if (fs::is_directory(file)) throw SettingsError(what + " " + file.string() + ": is a folder");
    const fs::path dir = file.parent_path().empty() ? fs::path(".") : file.parent_path();
    if (!fs::is_directory(dir))
        throw SettingsError(what + " " + file.string() + ": the folder " + dir.string() +
                            " does not exist");
    if (access(dir.c_str(), W_OK) != 0)
        throw SettingsError(what + " " + file.string() + ": the folder " + dir.string() +
                            " is not writable");
}

fs::path overlayPrefixOf(const Args& a) {
    if (!a.overlayPrefix.empty()) return a.overlayPrefix;
    fs::path p = a.out;
    if (asciiLower(p.extension().string()) == ".json") p.replace_extension();
    return p;
}

/** The overlay files of view `view` (of `views`): PREFIX[-viewN]-{before,after}-{blend,checker}. */
fs::path overlayPath(const fs::path& prefix, std::size_t view, std::size_t views, bool after,
                     bool blend) {
    std::string name = prefix.filename().string();
    if (views > 1) name += "-view" + std::to_string(view + 1);
    name += after ? "-after" : "-before";
    name += blend ? "-blend.png" : "-checker.png";
    return prefix.parent_path() / name;
}

std::vector<XrayInput> readXrays(const Args& a, const glm::dvec3& isocentre) {
    if (a.frames.size() > 1 && a.frames.size() != a.xrays.size())
        throw SettingsError("--frame: one frame for all X-rays or one per X-ray (" +
                            std::to_string(a.xrays.size()) + ")");
    const XrayValues values = parseXrayValues(a.values);
    std::vector<XrayInput> xrays;
    for (std::size_t i = 0; i < a.xrays.size(); ++i) {
        const int frame = a.frames.empty() ? 0 : a.frames[a.frames.size() > 1 ? i : 0];
        xrays.push_back(readXrayInput(a.xrays[i], isocentre, values, frame));
    }
    checkSameFrame(xrays);
    return xrays;
}

/** Reads and checks every input but the CT; `centre` is the isocentre (the CT's centre unless
 *  --isocenter), for X-rays without one and pose files without centre_mm. */
Inputs readInputs(const Args& a, const glm::dvec3& centre) {
    Inputs in;
    in.centre = centre;
    in.out = a.out;
    in.overlayPrefix = overlayPrefixOf(a);
    checkWritable(in.out, "--out");
    for (const bool after : {false, true})
        for (const bool blend : {false, true})
            checkWritable(overlayPath(in.overlayPrefix, 0, a.xrays.size(), after, blend),
                          "overlay");
    in.xrays = readXrays(a, centre);
    if (!a.init.empty()) in.init = readPoseJson(a.init, centre);
    if (!a.truth.empty()) in.truth = readPoseJson(a.truth, centre);
    if (!a.targets.empty()) in.targets = readTargetsCsv(a.targets);
    if (!a.offset.empty()) in.offset = numberList(a.offset, 6, "--offset");
    RegistrationOptions& o = in.options;
    o.similarity = parseSimilarity(a.similarity);
    o.levels = parseLevels(a);
    if (a.global < 0) throw SettingsError("--global: expected a number of samples >= 0");
    o.globalSamples = a.global;
    if (a.threads < 0) throw SettingsError("--threads: expected >= 0");
    o.projector.threads = a.threads;
    o.coverageMask = !a.noCoverageMask;
    if (!(a.detectorBlur >= 0.0) || !std::isfinite(a.detectorBlur))
        throw SettingsError("--detector-blur: expected a sigma in pixels >= 0");
    o.detectorBlurPixels = a.detectorBlur;
    o.centreSet = true;
    o.centre = centre;
    return in;
}

/** The renderer factory: the GPU's for --gpu where the build and the machine have one (the
 *  context kept in `context`), else empty (the CPU's). */
DrrRendererFactory rendererFactory(bool gpu, std::shared_ptr<void>& context) {
    if (!gpu) return {};
#ifdef FVR_HAVE_GPU
    try {
        context = std::make_shared<fvr::gpu::EglContext>();
        return fvr::gpu::gpuDrrRendererFactory();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fvr-register: the GPU cannot render (%s); the CPU does\n", e.what());
        return {};
    }
#else
    (void)context;
    std::fprintf(stderr, "fvr-register: built without the GPU library; the CPU renders\n");
    return {};
#endif
}

/** Progress on stderr: each stage as it starts, then every 50 evaluations. */
std::function<void(const RegistrationProgress&)> stderrProgress() {
    auto last = std::make_shared<std::pair<std::string, int>>();
    return [last](const RegistrationProgress& p) {
        const bool newStage = p.stage != last->first;
        if (!newStage && p.evaluations - last->second < 50) return;
        *last = {p.stage, p.evaluations};
        std::fprintf(stderr,
                     "fvr-register: %s (%d/%d): %d/%d evaluations, similarity %.4f, pose "
                     "%.2f %.2f %.2f deg %.2f %.2f %.2f mm\n",
                     p.stage.c_str(), p.stageIndex + 1, p.stageCount, p.evaluations,
                     p.maxEvaluations, p.bestSimilarity, p.bestPose.rotationDeg.x,
                     p.bestPose.rotationDeg.y, p.bestPose.rotationDeg.z, p.bestPose.translationMm.x,
                     p.bestPose.translationMm.y, p.bestPose.translationMm.z);
    };
}

/** A sidecar's X-ray rendered from another volume than the CT (its name, grid or position):
 *  said, not refused (another CT of the same patient in the same frame is a fair input). */
void warnOtherVolume(Inputs& in, const Volume& ct) {
    // Keys sorted, as read; a name that is not UTF-8 gets U+FFFD, as fvr-render's sidecar has it.
    Json block = Json::parse(
        fvr::cli::volumeBlockJson(ct).dump(-1, ' ', false, Json::error_handler_t::replace));
    block.erase("units");
    const std::string mine = "volume " + block.dump();
    for (XrayInput& x : in.xrays)
        if (x.frameOfReference.rfind("volume ", 0) == 0 && x.frameOfReference != mine)
            x.warnings.push_back("rendered from another volume than the CT (" + x.frameOfReference +
                                 "; the CT: " + mine + ")");
}

Json vec3Json(const glm::dvec3& v) { return Json::array({v.x, v.y, v.z}); }

Json poseJson(const glm::dmat4& T, const glm::dvec3& centre) {
    return Json::parse(poseJsonText(T, centre));
}

Json stageJson(const StageReport& s) {
    return Json{{"name", s.name},
                {"renderer", s.renderer},
                {"image_size", Json::array({s.imageWidth, s.imageHeight})},
                {"voxel_mm", s.voxelMm},
                {"evaluations", s.evaluations},
                {"drrs", s.drrs},
                {"seconds", s.seconds},
                {"similarity_before", s.similarityBefore},
                {"similarity_after", s.similarityAfter},
                {"rotation_deg", vec3Json(s.pose.rotationDeg)},
                {"translation_mm", vec3Json(s.pose.translationMm)}};
}

Json xrayJson(const XrayInput& x) {
    return Json{{"file", x.file.string()},
                {"frame", x.frame},
                {"size", Json::array({x.view.camera.width, x.view.camera.height})},
                {"values", x.valuesNote},
                {"patient_id", x.patientId},
                {"frame_of_reference", x.frameOfReference},
                {"warnings", x.warnings}};
}

} // namespace

namespace {

/** The initial pose: --init's (about the centre) plus --offset. */
Pose initialPose(const Inputs& in) {
    std::vector<double> p = poseFromMatrix(in.init, in.centre).parameters();
    for (std::size_t k = 0; k < 6; ++k) p[k] += in.offset[k];
    return Pose::fromParameters(p.data());
}

/** The before/after overlays of every view at full resolution; returns the files written. */
std::vector<std::string> writeOverlays(const Inputs& in, const Volume& ct,
                                       const RegistrationOptions& o, const glm::dmat4& before,
                                       const glm::dmat4& after) {
    const std::unique_ptr<DrrRenderer> renderer =
        o.renderer ? o.renderer(ct, o.projector) : cpuDrrRenderer(ct, o.projector);
    std::vector<std::string> files;
    for (const bool isAfter : {false, true}) {
        std::vector<ConeCamera> cameras;
        for (const XrayInput& x : in.xrays)
            cameras.push_back(posedCamera(x.view.camera, isAfter ? after : before));
        const std::vector<DetectorImage> drrs = renderer->render(cameras);
        for (std::size_t v = 0; v < in.xrays.size(); ++v) {
            const RegistrationView& view = in.xrays[v].view;
            for (const bool blend : {true, false}) {
                const fs::path p =
                    overlayPath(in.overlayPrefix, v, in.xrays.size(), isAfter, blend);
                writeOverlayPng(p, blend ? "blend" : "checkerboard", view.image, drrs[v].pixels,
                                view.camera.width, view.camera.height);
                files.push_back(p.string());
            }
        }
    }
    return files;
}

Json evaluationJson(const Inputs& in, const glm::dmat4& before, const glm::dmat4& after) {
    const std::vector<glm::dvec3> targets =
        in.targets.empty() ? cubeCorners(in.centre, 100.0) : in.targets;
    const double mtreBefore = meanTargetError(*in.truth, before, targets);
    const double mtreAfter = meanTargetError(*in.truth, after, targets);
    return Json{{"truth", poseJson(*in.truth, in.centre)},
                {"targets", in.targets.empty() ? "the 8 corners of a 100 mm cube at the isocentre"
                                               : std::to_string(in.targets.size()) +
                                                     " points from the --targets file"},
                {"mtre_before_mm", mtreBefore},
                {"mtre_after_mm", mtreAfter},
                {"success_threshold_mm", 2.0},
                {"success", mtreAfter < 2.0}};
}

Json resultJson(const Args& a, const Inputs& in, const OpenedStudy& study, const Pose& init,
                const RegistrationResult& r) {
    Json stages = Json::array();
    for (const StageReport& s : r.stages) stages.push_back(stageJson(s));
    Json xrays = Json::array();
    for (const XrayInput& x : in.xrays) xrays.push_back(xrayJson(x));
    Json levels = Json::array();
    for (const RegistrationLevel& l : in.options.levels)
        levels.push_back({{"image_pixels", l.imagePixels},
                          {"voxel_mm", l.voxelMm},
                          {"max_evaluations", l.maxEvaluations},
                          {"step_deg", l.stepDeg},
                          {"step_mm", l.stepMm}});
    const glm::dmat4 initMatrix = poseMatrix(init, in.centre);
    return Json{{"generator", "fvr-register"},
                {"pose", poseJson(r.matrix, in.centre)},
                {"initial_pose", poseJson(initMatrix, in.centre)},
                {"similarity",
                 {{"measure", similarityName(in.options.similarity)},
                  {"before", r.similarityBefore},
                  {"after", r.similarityAfter}}},
                {"stages", stages},
                {"evaluations", r.evaluations},
                {"drrs", r.drrs},
                {"seconds", r.seconds},
                {"cancelled", r.cancelled},
                {"history", r.history},
                {"options",
                 {{"levels", levels},
                  {"global_samples", in.options.globalSamples},
                  {"coverage_mask", in.options.coverageMask},
                  {"detector_blur_px", in.options.detectorBlurPixels},
                  {"threads", in.options.projector.threads},
                  {"gpu_asked", a.gpu}}},
                {"inputs",
                 {{"ct", a.ct},
                  {"ct_warnings", study.warnings},
                  {"xrays", xrays},
                  {"init", a.init.empty() ? Json(nullptr) : Json(a.init)},
                  {"offset", in.offset},
                  {"isocenter_mm", vec3Json(in.centre)}}}};
}

void printStages(const RegistrationResult& r) {
    for (const StageReport& s : r.stages)
        std::fprintf(stderr,
                     "fvr-register: %s: %dx%d, voxel %.2f mm, %d evaluations (%d DRRs), %.2f s, "
                     "similarity %.4f -> %.4f [%s]\n",
                     s.name.c_str(), s.imageWidth, s.imageHeight, s.voxelMm, s.evaluations, s.drrs,
                     s.seconds, s.similarityBefore, s.similarityAfter, s.renderer.c_str());
}

int run(const Args& a) {
    // Every input but the CT first (with a provisional centre), so that bad input is refused
    // before the CT is loaded; then again about the CT's centre (cheap: headers and images).
    std::optional<glm::dvec3> iso;
    if (!a.isocentre.empty()) {
        const std::vector<double> v = numberList(a.isocentre, 3, "--isocenter");
        iso = glm::dvec3(v[0], v[1], v[2]);
    }
    readInputs(a, iso.value_or(glm::dvec3(0.0)));
    OpenOptions open;
    open.seriesKey = a.series;
    OpenedStudy study = openStudy(classifyInput(a.ct), open);
    for (const std::string& w : study.warnings)
        std::fprintf(stderr, "fvr-register: warning: %s: %s\n", a.ct.c_str(), w.c_str());
    Inputs in = readInputs(a, iso.value_or(volumeCentre(study.volume)));
    warnOtherVolume(in, study.volume);
    for (const XrayInput& x : in.xrays) {
        for (const std::string& w : x.warnings)
            std::fprintf(stderr, "fvr-register: warning: %s: %s\n", x.file.c_str(), w.c_str());
        std::fprintf(stderr, "fvr-register: %s: %dx%d, %s\n", x.file.c_str(), x.view.camera.width,
                     x.view.camera.height, x.valuesNote.c_str());
    }
    std::shared_ptr<void> gpuContext;
    in.options.renderer = rendererFactory(a.gpu, gpuContext);
    in.options.progress = stderrProgress();
    std::vector<RegistrationView> views;
    for (const XrayInput& x : in.xrays) views.push_back(x.view);
    const Pose init = initialPose(in);
    const RegistrationResult r = registerPose(study.volume, views, init, in.options);
    printStages(r);
    Json result = resultJson(a, in, study, init, r);
    if (in.truth) result["evaluation"] = evaluationJson(in, poseMatrix(init, in.centre), r.matrix);
    result["overlays"] =
        writeOverlays(in, study.volume, in.options, poseMatrix(init, in.centre), r.matrix);
    writeFileAtomic(in.out, fvr::cli::jsonText(result)); // fvr-render's layout
    std::fprintf(stderr, "fvr-register: similarity %.4f -> %.4f in %.2f s; wrote %s\n",
                 r.similarityBefore, r.similarityAfter, r.seconds, in.out.c_str());
    if (result.contains("evaluation"))
        std::fprintf(stderr, "fvr-register: mTRE %.3f mm -> %.3f mm\n",
                     result["evaluation"]["mtre_before_mm"].get<double>(),
                     result["evaluation"]["mtre_after_mm"].get<double>());
    return 0;
}

} // namespace

int main(int argc, char** argv) {
    try {
        const std::optional<Args> args = parseArgs(argc, argv);
        if (!args) return 0; // --help
        return run(*args);
    } catch (const InputError& e) {
        std::cerr << "fvr-register: error: " << e.what() << "\n";
        return 2;
    } catch (const std::bad_alloc&) {
        std::cerr << "fvr-register: error: out of memory\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "fvr-register: error: " << e.what() << "\n";
        return 1;
    }
}
