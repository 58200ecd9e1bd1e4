#pragma once
/** Separable interpolation kernels for resampling the spectrum, as 1D tables (the paper stores
 *  the kernel tiles in one RGBA 1D texture; here one table row per fractional offset). */
#include <array>
#include <string>
#include <vector>

namespace fvr::core {

enum class Kernel { Nearest, Linear, BSpline, CatmullRom, Sinc4 };

/** "nearest", "linear", "bspline", "catmull-rom", "sinc4". */
const char* kernelName(Kernel k);
/** Inverse of kernelName (also accepts "trilinear", "tricubic" = bspline); throws SettingsError. */
Kernel parseKernel(const std::string& name);
/** All kernels, simplest first. */
const std::array<Kernel, 5>& allKernels();
/** Whether the kernel interpolates (weight 1 at offset 0, 0 at other integers). */
bool kernelInterpolates(Kernel k);

/** Continuous 1D kernel value at offset x (in grid units). */
double kernelValue(Kernel k, double x);

/**
 * Sampled kernel: for a coordinate t, the taps are floor(t) - (taps/2 - 1) ... and weights come
 * from a table over the fractional part (kResolution intervals, linear interpolation between
 * entries, so the table error is O(1/kResolution^2)). Nearest has one tap at round(t).
 * Weights of the windowed sinc are normalised to sum to 1 (exact DC, as the other kernels).
 */
class KernelTable {
public:
    static constexpr int kResolution = 1024;
    explicit KernelTable(Kernel k);

    Kernel kernel() const { return m_kernel; }
    int taps() const { return m_taps; }
    /** Radius in grid units (taps / 2; 0.5 for nearest). */
    double radius() const { return m_taps == 1 ? 0.5 : m_taps / 2.0; }
    /** Offset of the first tap relative to floor(t) (for nearest: relative to round(t)). */
    int firstTapOffset() const { return m_taps == 1 ? 0 : -(m_taps / 2 - 1); }

    /** Fills weights[0..taps) for fractional part frac in [0,1). */
    void weights(double frac, float* w) const {
        const double pos = frac * kResolution;
        int i = int(pos);
        if (i >= kResolution) i = kResolution - 1;
        const float t = float(pos - i);
        const float* a = &m_table[std::size_t(i) * m_taps];
        const float* b = a + m_taps;
        for (int j = 0; j < m_taps; ++j) w[j] = a[j] + t * (b[j] - a[j]);
    }
    /** The raw table: (kResolution + 1) rows of taps() weights. */
    const std::vector<float>& table() const { return m_table; }

private:
    Kernel m_kernel;
    int m_taps;
    std::vector<float> m_table;
};

} // namespace fvr::core
