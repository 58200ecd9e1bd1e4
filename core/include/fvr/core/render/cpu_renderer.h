#pragma once
/** Fourier volume rendering on the CPU: the reference the GPU renderer must match and the
 *  fallback when no usable GPU exists. */
#include <map>
#include <memory>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/projection.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/thread_pool.h>
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

/**
 * Per frame: resample the central slice perpendicular to D from the spectrum (separable kernel
 * tables; Hermitian lookups into the half spectrum; the output centring (-1)^(m+n) and the
 * physical scale (s_x s_y s_z)/(M d)^2 folded into the slice), then one inverse 2D transform:
 * complex-to-real FFT (only the half slice is sampled) or FHT with the eq. 4 correction.
 * With the band-limited voxel model, spatial frequencies outside the volume's band (|k_a| > P_a/2)
 * are zero; the other models read the spectrum's periodic continuation (taps carry the (-1)-per-
 * period sign of axes with an even voxel count) times the model's transfer function. The Nyquist
 * row and column average their two aliases, so the FFT and FHT paths compute the same image.
 * Not thread-safe: one renderer per thread (each owns its pool, plans and buffers).
 */
class CpuFourierRenderer {
public:
    /** threads <= 0: all hardware threads. */
    explicit CpuFourierRenderer(std::shared_ptr<const Spectrum> spectrum, int threads = 0);
    ~CpuFourierRenderer();

    /** Renders one projection. Throws SettingsError for a bad image geometry. */
    ProjectionImage render(const RenderParams& params, StageTimes* times = nullptr);

    const Spectrum& spectrum() const { return *m_spectrum; }

private:
    struct SizeResources;
    SizeResources& resources(int size);

    std::shared_ptr<const Spectrum> m_spectrum;
    ThreadPool m_pool;
    int m_threads;
    std::map<int, std::unique_ptr<SizeResources>> m_resources;
    std::map<Kernel, std::unique_ptr<KernelTable>> m_tables;
    std::map<VoxelModel, std::unique_ptr<TransferTable>> m_transfer;
};

} // namespace fvr::core
