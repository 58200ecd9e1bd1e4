#pragma once
/** Separable interpolation kernels for resampling the spectrum, as 1D tables (the paper stores
 *  the kernel tiles in one RGBA 1D texture; here one table row per fractional offset). */
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace fvr::core {

enum class Kernel { Nearest, Linear, BSpline, CatmullRom, Sinc4, KaiserBessel4, KaiserBessel6 };

/** "nearest", "linear", "bspline", "catmull-rom", "sinc4", "kaiser-bessel4", "kaiser-bessel6". */
const char* kernelName(Kernel k);
/** Inverse of kernelName (also accepts "trilinear", "tricubic" = bspline, "kaiser-bessel" =
 *  kaiser-bessel4); throws SettingsError. */
Kernel parseKernel(const std::string& name);
/** The Kaiser-Bessel kernel of a width (4 or 6); throws SettingsError for other widths. */
Kernel kaiserBesselKernel(int width);
/** All kernels, simplest first. */
const std::array<Kernel, 7>& allKernels();
/** Whether the kernel interpolates (weight 1 at offset 0, 0 at other integers). */
bool kernelInterpolates(Kernel k);
/** Whether gridding correction (deapodization) makes the kernel more accurate, measured
 *  against ray casting at oversampling 1.25 (Shepp-Logan 40³ and the body CT, trilinear voxel
 *  model): Kaiser-Bessel and the cubic B-spline need it (17-20 dB without, 54-57 dB with),
 *  Catmull-Rom, the windowed sinc and nearest gain 1-8 dB. Linear does not gain on average
 *  (22.3 against 22.8 dB on the body CT) and its projected mass errs twice as much deapodized
 *  (+28 % against -15 %): the workstation's "Gridding correction" leaves it out. */
bool griddingCorrectionHelps(Kernel k);
/** Taps per axis: 1 (nearest), 2 (linear), 4, or 6 (kaiser-bessel6). */
int kernelTaps(Kernel k);

/** Oversampling assumed where none is known (the Kaiser-Bessel beta depends on it). */
constexpr double kDefaultKernelOversampling = 2.0;
/** The oversampling a spectrum's kernels are designed for: min over axes of padded / volume
 *  size (both the renderers and the deapodization use this, so they always agree). */
double kernelOversampling(const std::array<std::int64_t, 3>& volumeDims,
                          const std::array<std::int64_t, 3>& padded);
/** Kaiser-Bessel shape parameter for width W and oversampling sigma (Beatty, Nishimura and
 *  Pauly 2005): beta = pi sqrt((W/sigma)^2 (sigma - 1/2)^2 - 0.8). */
double kaiserBesselBeta(int width, double oversampling);

/** Continuous 1D kernel value at offset x (in grid units). Kaiser-Bessel kernels are
 *  I0(beta sqrt(1 - (2x/W)^2)) normalised to unit integral; the other kernels ignore the
 *  oversampling. */
double kernelValue(Kernel k, double x, double oversampling = kDefaultKernelOversampling);

/**
 * Continuous Fourier transform of the 1D kernel at frequency u (cycles per grid unit),
 * normalised so that kernelFourier(k, 0) = 1. Closed forms: nearest sinc(u), linear sinc^2(u),
 * B-spline sinc^4(u), Kaiser-Bessel sinh(sqrt(beta^2 - (pi W u)^2)) / sqrt(...) (sin for an
 * imaginary root) over sinh(beta)/beta. Catmull-Rom and the windowed sinc are integrated
 * numerically (Simpson, 2048 intervals over their support).
 */
double kernelFourier(Kernel k, double u, double oversampling = kDefaultKernelOversampling);

/**
 * Sampled kernel: for a coordinate t, the taps are floor(t) - (taps/2 - 1) ... and weights come
 * from a table over the fractional part (kResolution intervals, linear interpolation between
 * entries, so the table error is O(1/kResolution^2)). Nearest has one tap at round(t).
 * Weights of the windowed sinc are normalised to sum to 1 (exact DC, as the other kernels);
 * Kaiser-Bessel weights are the unit-integral kernel itself (their sum is 1 to ~1e-4 at
 * oversampling 2), so that deapodization by kernelFourier() is exact.
 */
class KernelTable {
public:
    static constexpr int kResolution = 1024;
    static constexpr int kMaxTaps = 6;
    /** oversampling: of the spectrum the table samples (only Kaiser-Bessel depends on it). */
    explicit KernelTable(Kernel k, double oversampling = kDefaultKernelOversampling);

    Kernel kernel() const { return m_kernel; }
    double oversampling() const { return m_oversampling; }
    int taps() const { return m_taps; }
    /** Radius in grid units (taps / 2; 0.5 for nearest). */
    double radius() const { return m_taps == 1 ? 0.5 : m_taps / 2.0; }
    /** Offset of the first tap relative to floor(t) (for nearest: relative to round(t)). */
    int firstTapOffset() const { return m_taps == 1 ? 0 : -(m_taps / 2 - 1); }

    /** Fills weights[0..taps) for fractional part frac in [0,1). */
    void weights(double frac, float* w) const { interpolate(m_table, frac, w); }
    /** weights() with the tap count known at compile time (T == taps()): the renderer's inner
     *  loop. The same values. */
    template <int T>
    void weights(double frac, float* w) const {
        const double pos = frac * kResolution;
        int i = int(pos);
        if (i >= kResolution) i = kResolution - 1;
        const float t = float(pos - i);
        const float* a = m_table.data() + std::size_t(i) * T;
        for (int j = 0; j < T; ++j) w[j] = a[j] + t * (a[T + j] - a[j]);
    }
    /** Derivatives d w_j / d frac of the weights (the derivative of the interpolant along an
     *  axis: depth cueing). Nearest has none (a zero row); linear gives -1, +1. */
    void derivativeWeights(double frac, float* w) const { interpolate(m_derivative, frac, w); }
    /** The raw table: (kResolution + 1) rows of taps() weights. */
    const std::vector<float>& table() const { return m_table; }
    /** The derivative table, same layout. */
    const std::vector<float>& derivativeTable() const { return m_derivative; }

private:
    void row(double frac, double* w) const;
    /** Linear interpolation between the rows of a (kResolution + 1) x taps table. */
    void interpolate(const std::vector<float>& table, double frac, float* w) const {
        const double pos = frac * kResolution;
        int i = int(pos);
        if (i >= kResolution) i = kResolution - 1;
        const float t = float(pos - i);
        const float* a = &table[std::size_t(i) * m_taps];
        const float* b = a + m_taps;
        for (int j = 0; j < m_taps; ++j) w[j] = a[j] + t * (b[j] - a[j]);
    }

    Kernel m_kernel;
    double m_oversampling;
    int m_taps;
    std::vector<float> m_table;
    std::vector<float> m_derivative;
};

} // namespace fvr::core
