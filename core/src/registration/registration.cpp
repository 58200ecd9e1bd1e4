// 2D/3D registration (registration/registration.h): the levels' objective, NLopt's BOBYQA,
// the multi-start global stage.
#include <fvr/core/registration/registration.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>

#include <nlopt.h>

#include <fvr/core/errors.h>
#include <fvr/core/xray/xray.h>

namespace fvr::core {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

/** The levels' CTs and renderers, one per distinct block size: levels whose voxel sizes round to
 *  the same blocks (a 3 mm CT at 2, 3 and 4 mm) share the CT and its renderer (on the GPU: one
 *  upload), and a level at the CT's own voxels uses the CT itself, not a copy. */
class LevelCts {
public:
    LevelCts(const Volume& ct, const RegistrationOptions& options) : m_ct(ct), m_options(options) {}

    struct Entry {
        Dims3 factors;
        std::unique_ptr<Volume> owned; ///< the block means; null when the factors are all 1
        const Volume* ct = nullptr;
        std::unique_ptr<DrrRenderer> renderer;
    };

    Entry& at(double voxelMm) {
        const Dims3 f = volumeBlockFactors(m_ct, voxelMm);
        for (auto& e : m_entries)
            if (e->factors == f) return *e;
        auto e = std::make_unique<Entry>();
        e->factors = f;
        if (f != Dims3{1, 1, 1})
            e->owned = std::make_unique<Volume>(downsampleVolume(m_ct, voxelMm));
        e->ct = e->owned ? e->owned.get() : &m_ct;
        e->renderer = m_options.renderer ? m_options.renderer(*e->ct, m_options.projector)
                                         : cpuDrrRenderer(*e->ct, m_options.projector);
        m_entries.push_back(std::move(e));
        return *m_entries.back();
    }

private:
    const Volume& m_ct;
    const RegistrationOptions& m_options;
    std::vector<std::unique_ptr<Entry>> m_entries;
};

/** One level's CT, renderer, cameras and X-rays, and the similarity of a pose there. */
class LevelObjective {
public:
    LevelObjective(LevelCts::Entry& ct, const std::vector<RegistrationView>& views,
                   const RegistrationLevel& level, const RegistrationOptions& options,
                   const glm::dvec3& centre)
        : m_level(ct), m_options(options), m_centre(centre) {
        for (const RegistrationView& v : views) {
            const int f = levelImageFactor(v.camera.width, v.camera.height, level.imagePixels);
            m_cameras.push_back(downsampleCamera(v.camera, f));
            m_blur.push_back(options.detectorBlurPixels / double(f));
            m_targets.emplace_back(
                options.similarity,
                downsampleImage({v.camera.width, v.camera.height, v.image, v.mask}, f));
        }
    }

    /** The mean similarity over the views at `pose` (-1 where the CT cannot be seen). */
    double similarity(const Pose& pose) {
        const glm::dmat4 t = poseMatrix(pose, m_centre);
        std::vector<ConeCamera> cameras;
        for (const ConeCamera& c : m_cameras) cameras.push_back(posedCamera(c, t));
        std::vector<DetectorImage> drrs;
        try {
            for (const ConeCamera& c : cameras) validateConeView(c, ct());
            drrs = m_level.renderer->render(cameras);
        } catch (const SettingsError&) {
            return -1.0; // a pose from which the CT is out of view: the worst score
        }
        ++m_evaluations;
        m_drrs += int(drrs.size());
        double sum = 0.0;
        for (std::size_t v = 0; v < drrs.size(); ++v) {
            if (m_blur[v] > 0.0) blurAsDetector(drrs[v], m_blur[v]);
            sum += viewSimilarity(v, drrs[v], t);
        }
        return sum / double(drrs.size());
    }

    const std::vector<ConeCamera>& cameras() const { return m_cameras; }
    const Volume& ct() const { return *m_level.ct; }
    std::string describe() const { return m_level.renderer->describe(); }
    int evaluations() const { return m_evaluations; }
    int drrs() const { return m_drrs; }

private:
    /** Line integrals in mm of water (the Mu mapping) to I/I0 at 70 keV, blurred, and back. */
    static void blurAsDetector(DetectorImage& drr, double sigma) {
        static const float mu = float(waterAttenuationPerMm(70.0));
        for (float& p : drr.pixels) p = std::exp(-mu * p);
        gaussianBlur(drr.pixels, drr.width, drr.height, sigma);
        for (float& p : drr.pixels) p = -std::log(std::max(p, 1e-30f)) / mu;
    }

    double viewSimilarity(std::size_t v, const DetectorImage& drr, const glm::dmat4& t) const {
        if (!m_options.coverageMask) return m_targets[v].score(drr.pixels.data());
        const std::vector<std::uint8_t> covered = coverageMask(ct(), m_cameras[v], t);
        return m_targets[v].score(drr.pixels.data(), covered.data());
    }

    LevelCts::Entry& m_level;
    const RegistrationOptions& m_options;
    glm::dvec3 m_centre;
    std::vector<ConeCamera> m_cameras;
    std::vector<SimilarityTarget> m_targets; ///< the X-rays at this level
    std::vector<double> m_blur; ///< per view, in this level's pixels
    int m_evaluations = 0, m_drrs = 0;
};

/** The search state shared with NLopt's callback: scaled parameters x (p = origin + x scale),
 *  the best pose so far, the history, cancel and progress. */
struct Search {
    LevelObjective* objective = nullptr;
    const RegistrationOptions* options = nullptr;
    std::vector<double> origin, scale;
    double best = -2.0;
    Pose bestPose;
    std::vector<double>* history = nullptr;
    RegistrationProgress progress;
    nlopt_opt opt = nullptr;
    std::exception_ptr error;
    bool cancelled = false;

    Pose poseOf(const double* x) const {
        double p[6];
        for (int k = 0; k < 6; ++k) p[k] = origin[k] + x[k] * scale[k];
        return Pose::fromParameters(p);
    }

    /** The similarity at pose p, recorded. */
    double evaluate(const Pose& p) {
        if (options->cancel && options->cancel->load()) {
            cancelled = true;
            if (opt) nlopt_force_stop(opt);
            return best;
        }
        const double s = objective->similarity(p);
        if (s > best) best = s, bestPose = p;
        history->push_back(best);
        ++progress.evaluations;
        progress.bestSimilarity = best;
        progress.bestPose = bestPose;
        if (options->progress) options->progress(progress);
        return s;
    }
};

double nloptCost(unsigned n, const double* x, double* grad, void* data) {
    (void)n;
    (void)grad; // BOBYQA uses no derivatives
    auto* search = static_cast<Search*>(data);
    try {
        return -search->evaluate(search->poseOf(x));
    } catch (...) {
        search->error = std::current_exception();
        nlopt_force_stop(search->opt);
        return 0.0;
    }
}

/** BOBYQA from `start` within the options' bounds about `search.origin`, at most `budget`
 *  evaluations; the best pose stays in `search`. */
void bobyqa(Search& search, const Pose& start, const RegistrationLevel& level, int budget) {
    const RegistrationOptions& o = *search.options;
    search.scale = {level.stepDeg, level.stepDeg, level.stepDeg,
                    level.stepMm,  level.stepMm,  level.stepMm};
    nlopt_opt opt = nlopt_create(NLOPT_LN_BOBYQA, 6);
    search.opt = opt;
    double lo[6], hi[6], x[6], step[6];
    const std::vector<double> s = start.parameters();
    for (int k = 0; k < 6; ++k) {
        const double bound = (k < 3 ? o.boundDeg : o.boundMm) / search.scale[k];
        lo[k] = -bound;
        hi[k] = bound;
        x[k] = std::clamp((s[k] - search.origin[k]) / search.scale[k], lo[k], hi[k]);
        step[k] = 1.0;
    }
    nlopt_set_lower_bounds(opt, lo);
    nlopt_set_upper_bounds(opt, hi);
    nlopt_set_min_objective(opt, nloptCost, &search);
    nlopt_set_initial_step(opt, step);
    nlopt_set_xtol_abs1(opt, 0.02); // 2 % of the level's step
    nlopt_set_maxeval(opt, std::max(8, budget));
    double cost = 0.0;
    nlopt_optimize(opt, x, &cost); // the best pose is kept by the callback whatever the result
    nlopt_destroy(opt);
    search.opt = nullptr;
    if (search.error) std::rethrow_exception(search.error);
}

/** The k-th point of the Halton sequence in base b, in [0, 1). */
double halton(int k, int b) {
    double f = 1.0, r = 0.0;
    for (int i = k; i > 0; i /= b) {
        f /= b;
        r += f * (i % b);
    }
    return r;
}

/** The global stage: Halton poses around `init`, then BOBYQA from the best few. */
void globalStage(Search& search, const Pose& init, const RegistrationLevel& level) {
    const RegistrationOptions& o = *search.options;
    static constexpr int kBases[6] = {2, 3, 5, 7, 11, 13};
    std::vector<std::pair<double, Pose>> scored{{search.evaluate(init), init}};
    const std::vector<double> p0 = init.parameters();
    for (int k = 1; k <= o.globalSamples && !search.cancelled; ++k) {
        double p[6];
        for (int a = 0; a < 6; ++a)
            p[a] = p0[a] + (2.0 * halton(k, kBases[a]) - 1.0) *
                               (a < 3 ? o.globalRangeDeg : o.globalRangeMm);
        const Pose pose = Pose::fromParameters(p);
        scored.emplace_back(search.evaluate(pose), pose);
    }
    std::sort(scored.begin(), scored.end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
    const int starts = std::clamp(o.globalStarts, 1, int(scored.size()));
    for (int s = 0; s < starts && !search.cancelled; ++s)
        bobyqa(search, scored[s].second, level, level.maxEvaluations / starts);
}

void validateInputs(const Volume& ct, const std::vector<RegistrationView>& views,
                    const RegistrationOptions& options) {
    if (views.empty()) throw SettingsError("registration: no X-ray views");
    if (options.levels.empty()) throw SettingsError("registration: no levels");
    if (ct.voxelCount() <= 0 || ct.voxels.size() != std::size_t(ct.voxelCount()))
        throw SettingsError("registration: the CT holds no voxels");
    for (const RegistrationView& v : views) {
        v.camera.validate();
        const std::size_t n = std::size_t(v.camera.width) * v.camera.height;
        if (v.image.size() != n)
            throw SettingsError("registration: " + v.name + ": the image has " +
                                std::to_string(v.image.size()) + " values, its camera " +
                                std::to_string(n));
        if (!v.mask.empty() && v.mask.size() != n)
            throw SettingsError("registration: " + v.name + ": the mask is not the image's size");
        for (float x : v.image)
            if (!std::isfinite(x))
                throw SettingsError("registration: " + v.name + ": a value is not finite");
        validateConeView(v.camera, ct);
        std::vector<RegistrationLevel> all = options.levels;
        if (options.globalSamples > 0) all.push_back(options.globalLevel);
        for (const RegistrationLevel& l : all) {
            const int f = levelImageFactor(v.camera.width, v.camera.height, l.imagePixels);
            if (v.camera.width / f < 16 || v.camera.height / f < 16)
                throw SettingsError("registration: " + v.name + ": a level of " +
                                    std::to_string(l.imagePixels) +
                                    " pixels shrinks it below 16 pixels");
        }
    }
}

} // namespace

namespace {

/** One stage: from `start`, the global search or BOBYQA on `objective`; its report. */
StageReport runStage(Search& search, LevelObjective& objective, const RegistrationLevel& level,
                     const std::string& name, bool global, const Pose& start) {
    const auto ts = Clock::now();
    const int e0 = objective.evaluations(), d0 = objective.drrs();
    StageReport report;
    report.name = name;
    search.objective = &objective;
    search.progress.stage = name;
    search.progress.evaluations = 0;
    search.progress.maxEvaluations =
        level.maxEvaluations + (global ? search.options->globalSamples + 1 : 1);
    search.best = -2.0;
    report.similarityBefore = search.evaluate(start);
    if (global)
        globalStage(search, start, level);
    else
        bobyqa(search, start, level, level.maxEvaluations);
    report.similarityAfter = search.best;
    report.pose = search.bestPose;
    report.renderer = objective.describe();
    report.imageWidth = objective.cameras().front().width;
    report.imageHeight = objective.cameras().front().height;
    const Vec3& sp = objective.ct().spacing;
    report.voxelMm = std::max({sp[0], sp[1], sp[2]});
    report.evaluations = objective.evaluations() - e0;
    report.drrs = objective.drrs() - d0;
    report.seconds = secondsSince(ts);
    ++search.progress.stageIndex;
    return report;
}

} // namespace

RegistrationResult registerPose(const Volume& ct, const std::vector<RegistrationView>& views,
                                const Pose& init, const RegistrationOptions& options) {
    validateInputs(ct, views, options);
    const auto t0 = Clock::now();
    RegistrationResult result;
    result.centre = options.centreSet ? options.centre : volumeCentre(ct);
    Search search;
    search.options = &options;
    search.origin = init.parameters();
    search.history = &result.history;
    search.bestPose = init;
    const bool global = options.globalSamples > 0;
    const int levels = int(options.levels.size());
    search.progress.stageCount = levels + (global ? 1 : 0);
    auto record = [&](const StageReport& r) {
        result.evaluations += r.evaluations;
        result.drrs += r.drrs;
        result.stages.push_back(r);
    };
    LevelCts cts(ct, options);
    Pose current = init;
    if (global) {
        LevelObjective objective(cts.at(options.globalLevel.voxelMm), views, options.globalLevel,
                                 options, result.centre);
        record(runStage(search, objective, options.globalLevel, "global", true, current));
        current = search.bestPose;
    }
    for (int l = 0; l < levels && !search.cancelled; ++l) {
        const RegistrationLevel& level = options.levels[std::size_t(l)];
        LevelObjective objective(cts.at(level.voxelMm), views, level, options, result.centre);
        record(
            runStage(search, objective, level, "level " + std::to_string(l + 1), false, current));
        current = search.bestPose;
        if (l == levels - 1 || search.cancelled) {
            // Before and after at this level's resolution (the finest unless cancelled).
            result.similarityBefore = objective.similarity(init);
            result.similarityAfter = objective.similarity(current);
        }
    }
    result.pose = current;
    result.matrix = poseMatrix(current, result.centre);
    result.cancelled = search.cancelled;
    result.seconds = secondsSince(t0);
    return result;
}

} // namespace fvr::core
