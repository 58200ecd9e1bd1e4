#pragma once
/** 2D/3D registration: the rigid pose (pose.h) of a CT that makes its DRRs match one or more
 *  X-rays of known geometry (jointly: a biplane pair is two views).
 *
 *  Method. A pyramid of levels, coarse to fine; each level has its own image downsampling
 *  (block means of the X-ray, its camera to match: similarity.h) and its own CT (block means to
 *  a voxel size), so that a coarse DRR costs a small fraction of a fine one. An optional global
 *  stage comes first, at its own coarser level: the similarity at a low-discrepancy (Halton) set
 *  of poses around the initial one, and a local search from each of the best few (multi-start),
 *  for starting poses further off than the local search reaches. Every level then
 *  refines the best pose with NLopt's BOBYQA (Powell's bound-constrained quadratic models: no
 *  derivatives, few evaluations for 6 parameters) within bounds around the initial pose. The
 *  cost is minus the similarity, summed over the views.
 *
 *  Masks. Pixels outside an X-ray's own mask (collimation, a region of interest) never count.
 *  With `coverageMask`, neither do pixels whose ray crosses a cut end of the CT (the first or
 *  last slice plane) or misses it: there the X-ray shows anatomy the CT does not hold, which
 *  would pull the pose. The coverage is recomputed for each pose. */
#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <fvr/core/geometry/camera.h>
#include <fvr/core/registration/pose.h>
#include <fvr/core/registration/similarity.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/volume.h>

namespace fvr::core {

/** One X-ray: its camera at the identity pose and its values as line integrals (larger = more
 *  attenuation; a raw radiograph's intensities converted by -ln(I / I0) first), W x H of the
 *  camera, row 0 at the top; the mask empty (every pixel) or W x H, non-zero = used. */
struct RegistrationView {
    std::string name; ///< for messages: the file, "view 1"
    ConeCamera camera;
    std::vector<float> image;
    std::vector<std::uint8_t> mask;
};

/** What renders a level's DRRs: line integrals of one (downsampled) CT for several cameras. */
class DrrRenderer {
public:
    virtual ~DrrRenderer() = default;
    virtual std::vector<DetectorImage> render(const std::vector<ConeCamera>& cameras) = 0;
    /** "CPU trilinear ray casting, exact per cell" and the like. */
    virtual std::string describe() const = 0;
};
/** Makes a level's renderer for its CT (which outlives the renderer). */
using DrrRendererFactory =
    std::function<std::unique_ptr<DrrRenderer>(const Volume& volume, const ConeProjectorOptions&)>;
/** core::ConeProjector on the CPU. */
std::unique_ptr<DrrRenderer> cpuDrrRenderer(const Volume& volume,
                                            const ConeProjectorOptions& options);

struct RegistrationLevel {
    /** The X-rays' block means to about this many pixels across their larger side (a whole
     *  factor, levelImageFactor); 0: full resolution. */
    int imagePixels = 0;
    double voxelMm = 0.0; ///< the CT's block means to about this voxel size (0: the CT as it is)
    int maxEvaluations = 200; ///< BOBYQA's budget at this level (each: one DRR per view)
    double stepDeg = 2.0; ///< BOBYQA's initial trust radius for the rotations
    double stepMm = 4.0; ///< ... and the translations
};

/** Where the registration stands, for progress bars (called from the registering thread). */
struct RegistrationProgress {
    std::string stage; ///< "global", "level 1/3", ...
    int stageIndex = 0;
    int stageCount = 0;
    int evaluations = 0; ///< in this stage so far
    int maxEvaluations = 0; ///< this stage's budget
    double bestSimilarity = 0.0;
    Pose bestPose;
};

struct RegistrationOptions {
    SimilarityMeasure similarity = SimilarityMeasure::GradientNcc;
    std::vector<RegistrationLevel> levels = {
        {64, 4.0, 300, 4.0, 8.0}, {128, 2.0, 200, 1.0, 2.0}, {256, 1.0, 120, 0.3, 0.6}};
    /** The rotations' centre: the isocentre (default: the CT's centre, volumeCentre). */
    bool centreSet = false;
    glm::dvec3 centre{0.0};
    /** The global stage, before the levels, at its own coarse level: `globalSamples` Halton
     *  poses within +-range of the initial pose, then BOBYQA from the best `globalStarts`
     *  (globalLevel.maxEvaluations shared among them). 0 samples: no global stage. On by
     *  default: at 32 pixels and 8 mm voxels it costs a fraction of a second and widens the
     *  capture range (README, "2D/3D registration"). */
    int globalSamples = 200;
    int globalStarts = 4;
    double globalRangeDeg = 15.0;
    double globalRangeMm = 30.0;
    RegistrationLevel globalLevel{32, 8.0, 400, 4.0, 8.0};
    /** BOBYQA's bounds about the initial pose. */
    double boundDeg = 30.0;
    double boundMm = 60.0;
    bool coverageMask = true;
    /** The X-rays' detector blur, a Gaussian's standard deviation in their full-resolution
     *  pixels (0: none). The DRRs get the same blur of their intensities exp(-p) before -ln, as a
     *  detector blurs the light it converts: a blur applied to intensities moves the edges of a
     *  radiograph's line integrals inward, which a sharp DRR would match by a wrong
     *  magnification (a depth error in a single view). The intensities are those of water's
     *  attenuation at 70 keV (the Mu mapping's line integrals are mm of water). */
    double detectorBlurPixels = 0.0;
    ConeProjectorOptions projector; ///< the model and threads; mapping Mu by default
    DrrRendererFactory renderer; ///< empty: cpuDrrRenderer
    std::function<void(const RegistrationProgress&)> progress;
    const std::atomic<bool>* cancel = nullptr; ///< set: stops at the next evaluation

    RegistrationOptions() { projector.mapping = ValueMapping::Mu; }
};

struct StageReport {
    std::string name; ///< "global", "level 1", ...
    std::string renderer; ///< DrrRenderer::describe()
    int imageWidth = 0, imageHeight = 0; ///< the first view's at this stage
    double voxelMm = 0.0; ///< the CT's largest spacing at this stage
    int evaluations = 0; ///< poses evaluated
    int drrs = 0; ///< DRRs rendered (evaluations x views)
    double seconds = 0.0;
    double similarityBefore = 0.0, similarityAfter = 0.0; ///< at this stage's resolution
    Pose pose; ///< the best after the stage
};

struct RegistrationResult {
    Pose pose; ///< about `centre`
    glm::dmat4 matrix{1.0};
    glm::dvec3 centre{0.0};
    /** At the finest level (the level reached when cancelled), mean over the views. */
    double similarityBefore = 0.0, similarityAfter = 0.0;
    std::vector<StageReport> stages;
    /** The best similarity after each evaluation, all stages in order (each at its stage's
     *  resolution). */
    std::vector<double> history;
    int evaluations = 0, drrs = 0;
    double seconds = 0.0;
    bool cancelled = false; ///< the result is the best pose found before the cancel
};

/** Finds the pose of `ct` (CT numbers; mapped by options.projector.mapping) that best matches
 *  the views, starting from `init` (about options' centre). SettingsError naming the problem for
 *  no views, a view whose image or mask is not its camera's size, non-finite values, a camera the
 *  CT cannot be seen by (validateConeView), no levels, or a level that would shrink an image
 *  below 16 pixels. */
RegistrationResult registerPose(const Volume& ct, const std::vector<RegistrationView>& views,
                                const Pose& init, const RegistrationOptions& options = {});

/** The block size that brings a W x H image to about `imagePixels` across its larger side
 *  (at least 1; 1 for imagePixels 0). */
int levelImageFactor(int width, int height, int imagePixels);

/** The whole block size per axis that brings the CT's voxels to about `voxelMm`:
 *  round(voxelMm / spacing), at least 1 and at most the axis's voxels; all 1 for voxelMm <= 0. */
Dims3 volumeBlockFactors(const Volume& volume, double voxelMm);

/** The CT's block means to about `voxelMm` (per axis: the whole factor round(voxelMm / spacing),
 *  at least 1), the grid's centre kept; the volume itself (a copy) when every factor is 1. */
Volume downsampleVolume(const Volume& volume, double voxelMm);

/** Which pixels of `camera` see the CT (at pose T) across its whole cut: rays that meet its box
 *  and neither enter nor leave it through the first or last slice planes (unless the principal
 *  ray runs within 45 degrees of the slice axis, when meeting the box is enough). */
std::vector<std::uint8_t> coverageMask(const Volume& ct, const ConeCamera& camera,
                                       const glm::dmat4& T);

} // namespace fvr::core
