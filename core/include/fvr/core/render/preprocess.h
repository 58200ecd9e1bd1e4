#pragma once
/** Preprocessing: value mapping, zero padding, wrap-around centring and the 3D transform, on a
 *  worker thread with progress and cancellation. */
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/volume.h>

namespace fvr::core {

/** How the 3D Hartley transform is computed (both give the same spectrum; tested). */
enum class HartleyMethod {
    FromFft, ///< real-to-complex FFT, then H = Re G - Im G
    Dht ///< separable FFTW_DHT passes, then the correction of the paper's eq. 5
};

enum class PlannerEffort { Estimate, Measure };

struct PreprocessOptions {
    ValueMapping mapping = ValueMapping::Raw;
    TransformKind transform = TransformKind::Fft;
    HartleyMethod hartleyMethod = HartleyMethod::FromFft;
    /** Zero-padding factor per axis in [1, 2]; 1 is the paper. Padded sizes are the next
     *  FFT-friendly size (2^a 3^b 5^c 7^d) at or above ceil(factor * N). */
    double oversampling = 1.0;
    /** Explicit padded sizes (each >= the volume's); overrides oversampling. */
    std::optional<Dims3> paddedDims;
    /** Deapodization: the kernel the spectrum is made for. When set, each voxel is divided by
     *  the kernel's continuous Fourier transform (normalised to 1 at 0), separably per axis,
     *  at its centred position x in padded-grid units: f(x) / prod_a kernelFourier(k, x_a/P_a,
     *  sigma), sigma = kernelOversampling(dims, padded). Interpolating that spectrum with the
     *  kernel then leaves no apodization (only the kernel's aliases). The spectrum records the
     *  kernel (Spectrum::deapodizedFor) and renderers refuse any other kernel (SettingsError).
     *  Empty: no deapodization (any kernel). */
    std::optional<Kernel> deapodizeFor;
    int threads = 0; ///< 0: all hardware threads
    /** FFTW planning: Measure (default) uses the measured plans of the wisdom on disk (XDG
     *  cache); those it lacks are planned ESTIMATE at once and measured in the background for
     *  the next load (fftw_planning.h). Estimate plans at once without measuring. */
    PlannerEffort effort = PlannerEffort::Measure;
    bool operator==(const PreprocessOptions&) const = default;
};

/** Raises Cancelled at the next check once cancel() was called. Thread-safe. */
class CancelToken {
public:
    void cancel() { m_flag.store(true, std::memory_order_relaxed); }
    bool cancelled() const { return m_flag.load(std::memory_order_relaxed); }
    void check() const;

private:
    std::atomic<bool> m_flag{false};
};

/** Progress callback: fraction in [0, 1], monotone non-decreasing, and the current stage name. */
using ProgressFn = std::function<void(double fraction, std::string_view stage)>;

/** Smallest 2^a 3^b 5^c 7^d >= n. */
std::int64_t nextFftSize(std::int64_t n);
/** The padded sizes the options give for a volume. Throws SettingsError for a factor outside
 *  [1, 2] or explicit sizes smaller than the volume. */
Dims3 paddedDimsFor(const Dims3& dims, const PreprocessOptions& options);
/** The per-axis deapodization factors 1 / kernelFourier(k, x / P, sigma) for the padded
 *  positions j = 0..P-1 of an axis of n voxels (only the n voxel positions matter; x is the
 *  voxel's offset from the volume centre (n-1)/2, in padded-grid units). */
std::vector<float> deapodizationFactors(Kernel k, std::int64_t n, std::int64_t p,
                                        double oversampling);
/** Bytes the spectrum will take (what to show before preprocessing). */
std::size_t spectrumBytes(const Dims3& padded);

/**
 * Runs the whole preprocessing on the calling thread. Throws Cancelled (memory already freed),
 * SettingsError, std::bad_alloc.
 */
std::shared_ptr<const Spectrum> preprocess(const Volume& volume, const PreprocessOptions& options,
                                           const ProgressFn& progress = {},
                                           const CancelToken* cancel = nullptr);

/** preprocess() on its own thread. Destruction cancels and joins. */
class PreprocessJob {
public:
    PreprocessJob(std::shared_ptr<const Volume> volume, PreprocessOptions options);
    ~PreprocessJob();
    PreprocessJob(const PreprocessJob&) = delete;
    PreprocessJob& operator=(const PreprocessJob&) = delete;

    void cancel() { m_cancel.cancel(); }
    bool finished() const { return m_finished.load(); }
    double fraction() const { return m_fraction.load(); }
    std::string stage() const;
    /** Waits, then returns the spectrum or rethrows the job's exception (Cancelled included). */
    std::shared_ptr<const Spectrum> get();

private:
    std::shared_ptr<const Volume> m_volume;
    PreprocessOptions m_options;
    CancelToken m_cancel;
    std::atomic<double> m_fraction{0.0};
    std::atomic<bool> m_finished{false};
    mutable std::mutex m_mutex;
    std::string m_stage;
    std::shared_ptr<const Spectrum> m_result;
    std::exception_ptr m_error;
    std::thread m_thread;
};

} // namespace fvr::core
