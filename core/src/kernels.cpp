#include <fvr/core/kernels.h>

#include <cmath>
#include <numbers>

#include <fvr/core/errors.h>

namespace fvr::core {

const char* kernelName(Kernel k) {
    switch (k) {
    case Kernel::Nearest: return "nearest";
    case Kernel::Linear: return "linear";
    case Kernel::BSpline: return "bspline";
    case Kernel::CatmullRom: return "catmull-rom";
    case Kernel::Sinc4: return "sinc4";
    }
    return "?";
}

Kernel parseKernel(const std::string& name) {
    if (name == "nearest") return Kernel::Nearest;
    if (name == "linear" || name == "trilinear") return Kernel::Linear;
    if (name == "bspline" || name == "tricubic" || name == "cubic-bspline") return Kernel::BSpline;
    if (name == "catmull-rom" || name == "catmullrom") return Kernel::CatmullRom;
    if (name == "sinc4" || name == "sinc") return Kernel::Sinc4;
    throw SettingsError("kernel: expected nearest|linear|bspline|catmull-rom|sinc4, found '" +
                        name + "'");
}

const std::array<Kernel, 5>& allKernels() {
    static const std::array<Kernel, 5> all{Kernel::Nearest, Kernel::Linear, Kernel::BSpline,
                                           Kernel::CatmullRom, Kernel::Sinc4};
    return all;
}

bool kernelInterpolates(Kernel k) { return k != Kernel::BSpline; }

double kernelValue(Kernel k, double x) {
    const double a = std::abs(x);
    switch (k) {
    case Kernel::Nearest: return a < 0.5 ? 1.0 : (a == 0.5 ? 0.5 : 0.0);
    case Kernel::Linear: return a < 1.0 ? 1.0 - a : 0.0;
    case Kernel::BSpline:
        if (a < 1.0) return 2.0 / 3.0 - a * a + 0.5 * a * a * a;
        if (a < 2.0) return (2.0 - a) * (2.0 - a) * (2.0 - a) / 6.0;
        return 0.0;
    case Kernel::CatmullRom:
        if (a < 1.0) return 1.5 * a * a * a - 2.5 * a * a + 1.0;
        if (a < 2.0) return -0.5 * a * a * a + 2.5 * a * a - 4.0 * a + 2.0;
        return 0.0;
    case Kernel::Sinc4: {
        if (a >= 2.0) return 0.0;
        const double pi = std::numbers::pi;
        const double sinc = a < 1e-12 ? 1.0 : std::sin(pi * a) / (pi * a);
        // Blackman window of total width 4, centred on 0.
        const double w = 0.42 + 0.5 * std::cos(pi * a / 2.0) + 0.08 * std::cos(pi * a);
        return sinc * w;
    }
    }
    return 0.0;
}

KernelTable::KernelTable(Kernel k) : m_kernel(k) {
    switch (k) {
    case Kernel::Nearest: m_taps = 1; break;
    case Kernel::Linear: m_taps = 2; break;
    default: m_taps = 4; break;
    }
    m_table.resize(std::size_t(kResolution + 1) * m_taps);
    for (int i = 0; i <= kResolution; ++i) {
        const double frac = double(i) / kResolution;
        float* row = &m_table[std::size_t(i) * m_taps];
        if (m_taps == 1) {
            row[0] = 1.0f;
            continue;
        }
        double sum = 0.0;
        double w[4];
        for (int j = 0; j < m_taps; ++j) {
            // Tap j sits at floor(t) + firstTapOffset() + j; its distance from t:
            const double x = frac - (firstTapOffset() + j);
            w[j] = kernelValue(k, x);
            sum += w[j];
        }
        const bool normalise = (k == Kernel::Sinc4);
        for (int j = 0; j < m_taps; ++j) row[j] = float(normalise ? w[j] / sum : w[j]);
    }
}

} // namespace fvr::core
