#pragma once
/** Fourier volume rendering on the CPU: the reference the GPU renderer must match and the
 *  fallback when no usable GPU exists. */
#include <map>
#include <memory>

#include <fvr/core/render/renderer.h>
#include <fvr/core/thread_pool.h>

namespace fvr::core {

namespace detail {
struct CpuSliceLookups;
} // namespace detail

/**
 * Per frame: resample the central slice perpendicular to D from the spectrum (separable kernel
 * tables; Hermitian lookups into the half spectrum; the output centring (-1)^(m+n) and the
 * physical scale (s_x s_y s_z)/(M d)^2 folded into the slice), then one inverse 2D transform:
 * complex-to-real FFT (only the half slice is sampled) or the 2D Hartley transform (Re - Im of
 * the slice's real-to-complex FFT).
 * With the band-limited voxel model, spatial frequencies outside the volume's band (|k_a| > P_a/2)
 * are zero; the other models read the spectrum's periodic continuation (taps carry the (-1)-per-
 * period sign of axes with an even voxel count) times the model's transfer function. The Nyquist
 * row and column average their two aliases, so the FFT and FHT paths compute the same image.
 * Not thread-safe: one renderer per thread (each owns its pool, plans and buffers).
 */
class CpuFourierRenderer final : public Renderer {
public:
    /** threads <= 0: all hardware threads. */
    explicit CpuFourierRenderer(std::shared_ptr<const Spectrum> spectrum, int threads = 0);
    ~CpuFourierRenderer();

    /** Renders one projection. Throws SettingsError for a bad image geometry. */
    ProjectionImage render(const RenderParams& params, StageTimes* times = nullptr) override;
    std::string describe() const override;
    bool isGpu() const override { return false; }

    const Spectrum& spectrum() const { return *m_spectrum; }

private:
    struct SizeResources;
    SizeResources& resources(int size);
    /** The voxel model's transfer table covering the slice's frequencies (null: band-limited). */
    const TransferTable* transferTable(VoxelModel model, double maxCyclesPerVoxel);
    /** The inverse 2D transform of the sampled slice in `res` into the image. */
    void invertSlice(SizeResources& res, ProjectionImage& img);
    /** Zeroes pixels outside the volume's shadow (clipToVolume) and clamps negative line
     *  integrals of a non-negative spectrum (nonNegative). */
    void clipAndClamp(const RenderParams& params, ProjectionImage& img);

    std::shared_ptr<const Spectrum> m_spectrum;
    ThreadPool m_pool;
    int m_threads;
    std::map<int, std::unique_ptr<SizeResources>> m_resources;
    std::map<Kernel, std::unique_ptr<KernelTable>> m_tables;
    std::map<VoxelModel, std::unique_ptr<TransferTable>> m_transfer;
    /** The spectrum's signed-index lookups of the fast slice walk (built once per spectrum). */
    std::unique_ptr<const detail::CpuSliceLookups> m_lookups;
};

} // namespace fvr::core
