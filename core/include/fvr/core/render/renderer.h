#pragma once
/** What every Fourier renderer takes per frame (RenderParams) and the interface the CPU renderer
 *  (cpu_renderer.h) and the GPU renderer (fvr/gpu/gpu_renderer.h) implement, so that fvr-render
 *  and the workstation's views pick a backend once and then render through one call. */
#include <string>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/projection.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/xray.h>

namespace fvr::core {

/** What one frame needs besides the spectrum. */
struct RenderParams {
    ViewFrame view;
    ImageGeometry image;
    Kernel kernel = Kernel::Linear;
    /** Depth cueing strength in [0, 1] (xray.h), in the frequency domain: the slice adds
     *  b/(2 pi) i times the spectrum's derivative along the view (with the kernel's derivative
     *  weights) to a times the spectrum. Needs a kernel with a derivative (not nearest). */
    double depthCue = 0.0;
    /** Spectral filter multiplied into the slice before the inverse transform (xray.h). */
    SliceFilter filter;
    /** Writes 0 to pixels whose ray misses the voxel model's support (rayMissesVolume with
     *  voxelModelReach): removes the kernel's ghost copies and ringing outside the volume's
     *  shadow, where the true projection is 0. */
    bool clipToVolume = false;
    /** What lies between the voxels (voxel_model.h): BandLimited samples the spectrum inside the
     *  volume's band only; Trilinear and BSpline sample it at every frequency of the slice (the
     *  voxels' spectrum repeats outside the band) and multiply by the model's transfer function,
     *  giving the projection of that interpolant (what a ray caster with that interpolation
     *  integrates). Costs one product per slice sample. */
    VoxelModel voxelModel = VoxelModel::BandLimited;
    /** Detector pixels that integrate over their area (d x d) instead of sampling the
     *  projection at their centre: the slice is multiplied by pixelApertureResponse(m / M)
     *  pixelApertureResponse(n / M). Compare with a spatial projector with pixelSubsamples. */
    bool pixelAperture = false;
    /** Writes max(0, p) where the spectrum's values are all >= 0 (Spectrum::nonNegative: their
     *  line integrals cannot be negative): removes what is left of the interpolation's ringing
     *  and aliases below zero. No effect on other spectra (raw HU, say). */
    bool nonNegative = false;
};

/** Checks geometry, depth cue and filter (SettingsError naming the problem). */
void validateRenderParams(const RenderParams& params);
/** The same, and the image against the spectrum's volume (validateImageGeometry with its
 *  dimensions and spacing): what both renderers check before every frame. */
void validateRenderParams(const RenderParams& params, const Spectrum& spectrum);

/** Throws RenderError when the image holds pixels that are not finite (NaN, inf: the
 *  projection overflowed float), giving their count: never a silent NaN in an output. fvr-render
 *  calls it on every image it writes. Not per frame in the renderers: preprocessing refuses
 *  values whose spectrum could overflow, so a frame cannot (the scan cost ~6 % of a 512^2 frame).
 */
void checkFiniteImage(const ProjectionImage& image);

/** A Fourier volume renderer holding one spectrum. */
class Renderer {
public:
    virtual ~Renderer() = default;
    /** Renders one projection (float line integrals, row 0 at the top) with the stage times.
     *  Throws SettingsError for bad parameters; backends add their own errors (GlError). */
    virtual ProjectionImage render(const RenderParams& params, StageTimes* times = nullptr) = 0;
    /** One line naming the backend and its device ("CPU, 8 threads", "GPU: <GL_RENDERER>"). */
    virtual std::string describe() const = 0;
    virtual bool isGpu() const = 0;
};

} // namespace fvr::core
