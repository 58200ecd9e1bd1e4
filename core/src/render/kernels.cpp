#include <fvr/core/render/kernels.h>

#include <algorithm>
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
    case Kernel::KaiserBessel4: return "kaiser-bessel4";
    case Kernel::KaiserBessel6: return "kaiser-bessel6";
    }
    return "?";
}

Kernel parseKernel(const std::string& name) {
    if (name == "nearest") return Kernel::Nearest;
    if (name == "linear" || name == "trilinear") return Kernel::Linear;
    if (name == "bspline" || name == "tricubic" || name == "cubic-bspline") return Kernel::BSpline;
    if (name == "catmull-rom" || name == "catmullrom") return Kernel::CatmullRom;
    if (name == "sinc4" || name == "sinc") return Kernel::Sinc4;
    if (name == "kaiser-bessel4" || name == "kaiser-bessel" || name == "kb4" || name == "kb")
        return Kernel::KaiserBessel4;
    if (name == "kaiser-bessel6" || name == "kb6") return Kernel::KaiserBessel6;
    throw SettingsError(
        "kernel: expected nearest|linear|bspline|catmull-rom|sinc4|kaiser-bessel4|kaiser-bessel6, "
        "found '" +
        name + "'");
}

Kernel kaiserBesselKernel(int width) {
    if (width == 4) return Kernel::KaiserBessel4;
    if (width == 6) return Kernel::KaiserBessel6;
    throw SettingsError("kernel width: expected 4|6 for kaiser-bessel, found " +
                        std::to_string(width));
}

const std::array<Kernel, 7>& allKernels() {
    static const std::array<Kernel, 7> all{
        Kernel::Nearest, Kernel::Linear,        Kernel::BSpline,      Kernel::CatmullRom,
        Kernel::Sinc4,   Kernel::KaiserBessel4, Kernel::KaiserBessel6};
    return all;
}

bool kernelInterpolates(Kernel k) {
    return k != Kernel::BSpline && k != Kernel::KaiserBessel4 && k != Kernel::KaiserBessel6;
}

bool griddingCorrectionHelps(Kernel k) { return k != Kernel::Linear; }

int kernelTaps(Kernel k) {
    switch (k) {
    case Kernel::Nearest: return 1;
    case Kernel::Linear: return 2;
    case Kernel::KaiserBessel6: return 6;
    default: return 4;
    }
}

double kernelOversampling(const std::array<std::int64_t, 3>& volumeDims,
                          const std::array<std::int64_t, 3>& padded) {
    double s = 0.0;
    for (int a = 0; a < 3; ++a) {
        if (volumeDims[a] <= 0 || padded[a] <= 0) return kDefaultKernelOversampling;
        const double r = double(padded[a]) / double(volumeDims[a]);
        s = a == 0 ? r : std::min(s, r);
    }
    return s;
}

double kaiserBesselBeta(int width, double oversampling) {
    const double w = width, s = oversampling;
    const double arg = (w / s) * (w / s) * (s - 0.5) * (s - 0.5) - 0.8;
    return std::numbers::pi * std::sqrt(std::max(arg, 0.0));
}

namespace {

int kbWidth(Kernel k) { return k == Kernel::KaiserBessel6 ? 6 : 4; }

double sincPi(double u) {
    const double x = std::numbers::pi * u;
    return std::abs(x) < 1e-12 ? 1.0 : std::sin(x) / x;
}

/** sinh(z)/z for z^2 = z2 (sin(|z|)/|z| for negative z2). */
double sinhcOfSquare(double z2) {
    if (std::abs(z2) < 1e-12) return 1.0;
    if (z2 > 0) {
        const double z = std::sqrt(z2);
        return std::sinh(z) / z;
    }
    const double z = std::sqrt(-z2);
    return std::sin(z) / z;
}

/** Integral of kernelValue(k, x) cos(2 pi u x) over the support (Simpson's rule). */
double numericFourier(Kernel k, double u, double oversampling) {
    const double r = kernelTaps(k) / 2.0;
    constexpr int n = 2048;
    const double h = 2.0 * r / n;
    double sum = 0.0;
    for (int i = 0; i <= n; ++i) {
        const double x = -r + i * h;
        const double c = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
        sum += c * kernelValue(k, x, oversampling) * std::cos(2.0 * std::numbers::pi * u * x);
    }
    return sum * h / 3.0;
}

/** I0(x), the modified Bessel function of order 0, by its power series sum ((x/2)^k / k!)^2 (all
 *  terms positive: no cancellation; converges for every x, 30-60 terms for the Kaiser-Bessel
 *  betas). Thread-safe, unlike std::cyl_bessel_i in libstdc++, which goes through lgamma and
 *  writes the global signgam (a data race when renderers build their tables at once). */
double besselI0(double x) {
    const double q = 0.25 * x * x;
    double term = 1.0, sum = 1.0;
    for (int k = 1; k < 500 && term > 1e-17 * sum; ++k) {
        term *= q / (double(k) * double(k));
        sum += term;
    }
    return sum;
}
} // namespace

double kernelValue(Kernel k, double x, double oversampling) {
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
    case Kernel::KaiserBessel4:
    case Kernel::KaiserBessel6: {
        const double W = kbWidth(k);
        if (a >= W / 2.0) return 0.0;
        const double beta = kaiserBesselBeta(int(W), oversampling);
        const double q = 2.0 * a / W;
        // Unit integral: the integral of I0(beta sqrt(1 - (2x/W)^2)) is W sinh(beta) / beta.
        return besselI0(beta * std::sqrt(1.0 - q * q)) / (W * sinhcOfSquare(beta * beta));
    }
    }
    return 0.0;
}

double kernelFourier(Kernel k, double u, double oversampling) {
    switch (k) {
    case Kernel::Nearest: return sincPi(u);
    case Kernel::Linear: return std::pow(sincPi(u), 2);
    case Kernel::BSpline: return std::pow(sincPi(u), 4);
    case Kernel::KaiserBessel4:
    case Kernel::KaiserBessel6: {
        const double W = kbWidth(k);
        const double beta = kaiserBesselBeta(int(W), oversampling);
        const double piwu = std::numbers::pi * W * u;
        return sinhcOfSquare(beta * beta - piwu * piwu) / sinhcOfSquare(beta * beta);
    }
    case Kernel::CatmullRom:
    case Kernel::Sinc4:
        return numericFourier(k, u, oversampling) / numericFourier(k, 0.0, oversampling);
    }
    return 1.0;
}

void KernelTable::row(double frac, double* w) const {
    if (m_taps == 1) {
        w[0] = 1.0;
        return;
    }
    double sum = 0.0;
    for (int j = 0; j < m_taps; ++j) {
        // Tap j sits at floor(t) + firstTapOffset() + j; its distance from t:
        const double x = frac - (firstTapOffset() + j);
        w[j] = kernelValue(m_kernel, x, m_oversampling);
        sum += w[j];
    }
    if (m_kernel == Kernel::Sinc4)
        for (int j = 0; j < m_taps; ++j) w[j] /= sum;
}

KernelTable::KernelTable(Kernel k, double oversampling)
    : m_kernel(k), m_oversampling(oversampling), m_taps(kernelTaps(k)) {
    m_table.resize(std::size_t(kResolution + 1) * m_taps);
    m_derivative.assign(std::size_t(kResolution + 1) * m_taps, 0.0f);
    double w[kMaxTaps], a[kMaxTaps], b[kMaxTaps], c[kMaxTaps];
    for (int i = 0; i <= kResolution; ++i) {
        const double frac = double(i) / kResolution;
        row(frac, w);
        for (int j = 0; j < m_taps; ++j) m_table[std::size_t(i) * m_taps + j] = float(w[j]);
        if (m_taps == 1) continue;
        // Derivative of the row within (0, 1), where every tap stays on one piece of its kernel
        // (the kernels have kinks or, Kaiser-Bessel, steps at integers): central differences
        // inside, one-sided second-order differences at the ends.
        constexpr double h = 1e-5, eps = 1e-9;
        float* d = &m_derivative[std::size_t(i) * m_taps];
        if (frac - h > 0.0 && frac + h < 1.0) {
            row(frac - h, a);
            row(frac + h, b);
            for (int j = 0; j < m_taps; ++j) d[j] = float((b[j] - a[j]) / (2 * h));
        } else {
            const double s = frac < 0.5 ? 1.0 : -1.0; // step inwards
            const double f0 = frac + s * eps;
            row(f0, a);
            row(f0 + s * h, b);
            row(f0 + s * 2 * h, c);
            for (int j = 0; j < m_taps; ++j)
                d[j] = float(s * (-3 * a[j] + 4 * b[j] - c[j]) / (2 * h));
        }
    }
}

} // namespace fvr::core
