#include <fvr/core/render/cpu_renderer.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string_view>
#include <type_traits>

#include <fvr/core/errors.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/slice_params.h>

#include "fftw_support.h"

#ifdef __x86_64__
#include <immintrin.h>
#endif

namespace fvr::core {

using Clock = std::chrono::steady_clock;
using cfloat = std::complex<float>;

std::string projectionUnits(ValueMapping mapping, ValueUnits source) {
    if (mapping == ValueMapping::Mu) return "mm (mu/mu_water x mm)";
    if (mapping == ValueMapping::MuBone) return "mm (bone-enhanced mu/mu_water x mm)";
    if (source == ValueUnits::HounsfieldUnits) return "HU x mm";
    return "value x mm";
}

struct CpuFourierRenderer::SizeResources {
    int size = 0;
    FftwBuffer slice; // Fft: M rows x (M/2+1) complex; Fht: M x M real
    FftwBuffer image; // Fft: M x M real output; Fht: M rows x (M/2+1) complex
    /** Fft: complex-to-real, slice -> image. Fht: real-to-complex, slice -> image, whose
     *  Re - Im is the 2D Hartley transform (hartleyFromHalfSpectrum): FFTW_DHT plans are 5x
     *  slower from ESTIMATE and 4x slower measured, and give the separable transform. */
    detail::Plan inverse;
    /** The measured plan the background planner is making (null: the plan above is final),
     *  and the estimate plan it replaced (kept: destroying it would wait for the planner). */
    std::shared_ptr<detail::PlanSlot> measured;
    detail::Plan replaced;
};

namespace {
/** Signed tap index -> stored row offset (floats) and period sign of one axis of the spectrum,
 *  over the indices [-reach, reach]: wrapAxis's wrap and antiperiodic sign, looked up once per
 *  tap row by the fast slice walk instead of computed per tap. */
class AxisLookup {
public:
    AxisLookup(std::int64_t P, bool anti, std::int64_t stride, std::int64_t reach);
    std::int64_t reach() const { return m_reach; }
    /** Indexed by the signed tap index. */
    const std::int64_t* offsets() const { return m_offset.data() + m_reach; }
    const float* signs() const { return m_sign.data() + m_reach; }

private:
    std::int64_t m_reach;
    std::vector<std::int64_t> m_offset;
    std::vector<float> m_sign;
};
} // namespace

/** The lookups of the renderer's spectrum, out to four periods and the widest kernel's taps
 *  beyond them (samples further out take the general path): x for the Hartley spectrum only
 *  (the half spectrum's x is read directly), y and z for both. They depend on the spectrum
 *  alone, so every frame shares them. */
struct detail::CpuSliceLookups {
    AxisLookup x, y, z;
    explicit CpuSliceLookups(const Spectrum& s);
};

CpuFourierRenderer::CpuFourierRenderer(std::shared_ptr<const Spectrum> spectrum, int threads)
    : m_spectrum(std::move(spectrum)), m_pool(threads),
      m_threads(threads > 0 ? threads : hardwareThreads()) {
    if (!m_spectrum || !m_spectrum->data) throw SettingsError("renderer: no spectrum");
    m_lookups = std::make_unique<const detail::CpuSliceLookups>(*m_spectrum);
    const double sigma = kernelOversampling(m_spectrum->volumeDims, m_spectrum->padded);
    for (Kernel k : allKernels()) m_tables.emplace(k, std::make_unique<KernelTable>(k, sigma));
}

CpuFourierRenderer::~CpuFourierRenderer() = default;

namespace {
/** The inverse 2D transform of an M x M slice, out of place (SizeResources::inverse). */
fftwf_plan planInverse(bool hartley, int M, float* slice, float* image, unsigned flags) {
    if (hartley)
        return fftwf_plan_dft_r2c_2d(M, M, slice, reinterpret_cast<fftwf_complex*>(image), flags);
    return fftwf_plan_dft_c2r_2d(M, M, reinterpret_cast<fftwf_complex*>(slice), image, flags);
}

/** The 2D Hartley transform H = Re F - Im F of an M x M real image from its r2c transform F
 *  (M rows of M/2+1; F(-k) = conj F(k) gives the columns beyond M/2). */
void hartleyFromHalfSpectrum(const float* F, float* H, int M, ThreadPool& pool) {
    const std::int64_t h = M / 2 + 1;
    pool.parallelFor(M, 16, [&](std::int64_t r0, std::int64_t r1) {
        for (std::int64_t y = r0; y < r1; ++y) {
            const float* row = F + 2 * h * y;
            const float* mirror = F + 2 * h * ((M - y) % M);
            float* out = H + std::int64_t(M) * y;
            for (std::int64_t x = 0; x < h; ++x) out[x] = row[2 * x] - row[2 * x + 1];
            for (std::int64_t x = h; x < M; ++x)
                out[x] = mirror[2 * (M - x)] + mirror[2 * (M - x) + 1];
        }
    });
}
} // namespace

CpuFourierRenderer::SizeResources& CpuFourierRenderer::resources(int M) {
    auto it = m_resources.find(M);
    if (it != m_resources.end()) return *it->second;
    detail::ensureFftwInitialised();
    auto r = std::make_unique<SizeResources>();
    r->size = M;
    const bool hartley = m_spectrum->kind == TransformKind::Fht;
    const std::size_t half = std::size_t(M) * (M / 2 + 1) * 2, full = std::size_t(M) * M;
    const std::size_t sliceFloats = hartley ? full : half, imageFloats = hartley ? half : full;
    r->slice = allocateFftw(sliceFloats);
    r->image = allocateFftw(imageFloats);
    const int threads = M >= 512 ? m_threads : 1;
    detail::QuickPlan q;
    {
        std::lock_guard lock(detail::planMutex());
        fftwf_plan_with_nthreads(threads);
        q = detail::planQuickly(true, [&](unsigned flags) {
            return planInverse(hartley, M, r->slice.get(), r->image.get(), flags);
        });
    }
    r->inverse = detail::Plan(q.plan);
    if (!q.plan) throw std::runtime_error("FFTW could not plan the inverse 2D transform");
    if (q.measureLater) {
        // Measured on buffers of its own (MEASURE overwrites them), executed on ours: both come
        // from fftwf_malloc, so their alignment agrees (new-array execution is legal).
        r->measured = std::make_shared<detail::PlanSlot>();
        detail::planInBackground(
            [slot = r->measured, hartley, M, threads, sliceFloats, imageFloats] {
                FftwBuffer slice = allocateFftw(sliceFloats);
                FftwBuffer image = allocateFftw(imageFloats);
                std::lock_guard lock(detail::planMutex());
                fftwf_plan_with_nthreads(threads);
                slot->set(
                    planInverse(hartley, M, slice.get(), image.get(), detail::plannerFlags(true)));
            });
    }
    detail::saveWisdom();
    return *m_resources.emplace(M, std::move(r)).first->second;
}

namespace {

/** Everything the per-sample code reads, precomputed per frame. */
struct SliceContext {
    const float* data;
    std::int64_t P0, P1, P2, rs;
    double half0, half1, half2; // band limits P/2 (+ tiny tolerance); infinite for compact models
    const KernelTable* table;
    int first;
    // Depth cueing: value a G(k) + i E.grad G(k) (FFT) or a H(k) + E.grad H(-k) (FHT), with
    // E_a = b/(2 pi) D_a s_a P_a (xray.h; the derivative theorem with the centred spectrum).
    float depthA = 1.0f;
    float E[3] = {0, 0, 0};
    // Axes of an even voxel count: the spectrum changes sign from one period to the next.
    bool anti[3] = {false, false, false};
    // The voxel model's transfer function (null: band-limited), at nu_a = k_a / P_a.
    const TransferTable* model = nullptr;
    double invP[3] = {1, 1, 1};
    /** The spectrum's lookups of the fast row walk (the renderer's). */
    const detail::CpuSliceLookups* lookups = nullptr;
};

/** k(m, n) = m * A + n * B in spectrum index units, m and n signed image frequencies. */
struct FrameMapping {
    double A[3], B[3];
    float scale;
};

/** Signed index in (-P/2, P/2] of the T taps base, base + 1, ... of one axis; where the axis is
 *  antiperiodic, the taps of odd periods negate their weights (and derivative weights): the
 *  interpolation then runs over the spectrum's true continuation (Spectrum, voxel_model.h). */
template <int T>
inline void wrapAxis(std::int64_t base, std::int64_t P, bool anti, std::int64_t* idx, float* w,
                     float* dw) {
    const std::int64_t hi = P / 2;
    std::int64_t r = base, q = 0;
    while (r > hi) r -= P, ++q;
    while (r <= hi - P) r += P, --q;
    for (int t = 0; t < T; ++t) {
        idx[t] = r;
        if (anti && (q & 1)) {
            w[t] = -w[t];
            if (dw) dw[t] = -dw[t];
        }
        if (++r > hi) r -= P, ++q;
    }
}

template <int T>
inline void axisWeights(const SliceContext& c, double k, std::int64_t& base, float* w) {
    if constexpr (T == 1) {
        base = std::int64_t(std::floor(k + 0.5));
        w[0] = 1.0f;
    } else if constexpr (T == 3) {
        // The linear kernel over three taps (depth cueing, see axisDerivWeights).
        const double f = std::floor(k);
        base = std::int64_t(f) - 1;
        w[0] = 0.0f;
        w[2] = float(k - f);
        w[1] = 1.0f - w[2];
    } else if constexpr (T == 2) {
        // The linear table is exact; computing the two weights directly is cheaper.
        const double f = std::floor(k);
        base = std::int64_t(f);
        w[1] = float(k - f);
        w[0] = 1.0f - w[1];
    } else {
        const double f = std::floor(k);
        base = std::int64_t(f) + c.first;
        c.table->weights(k - f, w);
    }
}

/** Weights and their derivatives (depth cueing; T >= 2). */
template <int T>
inline void axisDerivWeights(const SliceContext& c, double k, std::int64_t& base, float* w,
                             float* dw) {
    const double f = std::floor(k);
    if constexpr (T == 3) {
        // The linear kernel: its derivative is -1, +1 between integers and undefined on them,
        // where the slice samples lie for every view along an axis (k_D = 0). There it takes the
        // mean of both sides, the central difference (G[j+1] - G[j-1]) / 2, which needs a third
        // tap; the symmetric choice also keeps the FFT and the FHT paths equal.
        const double r = std::nearbyint(k);
        if (std::abs(k - r) < 1e-6) {
            base = std::int64_t(r) - 1;
            w[0] = 0.0f, w[1] = 1.0f, w[2] = 0.0f;
            dw[0] = -0.5f, dw[1] = 0.0f, dw[2] = 0.5f;
        } else {
            base = std::int64_t(f) - 1;
            w[0] = 0.0f;
            w[2] = float(k - f);
            w[1] = 1.0f - w[2];
            dw[0] = 0.0f, dw[1] = -1.0f, dw[2] = 1.0f;
        }
    } else {
        base = std::int64_t(f) + c.first;
        c.table->weights(k - f, w);
        c.table->derivativeWeights(k - f, dw);
    }
}

/** The taps' signed indices and weights along x, y and z (with the period signs folded in),
 *  with their derivatives when Derivative (dx..dz are then written; otherwise left alone). */
template <int T, bool Derivative>
inline void tapWeights(const SliceContext& c, double kx, double ky, double kz, std::int64_t* ix,
                       std::int64_t* iy, std::int64_t* iz, float* wx, float* wy, float* wz,
                       float* dx, float* dy, float* dz) {
    std::int64_t bx, by, bz;
    if constexpr (Derivative) {
        axisDerivWeights<T>(c, kx, bx, wx, dx);
        axisDerivWeights<T>(c, ky, by, wy, dy);
        axisDerivWeights<T>(c, kz, bz, wz, dz);
    } else {
        axisWeights<T>(c, kx, bx, wx);
        axisWeights<T>(c, ky, by, wy);
        axisWeights<T>(c, kz, bz, wz);
        dx = dy = dz = nullptr;
    }
    wrapAxis<T>(bx, c.P0, c.anti[0], ix, wx, dx);
    wrapAxis<T>(by, c.P1, c.anti[1], iy, wy, dy);
    wrapAxis<T>(bz, c.P2, c.anti[2], iz, wz, dz);
}

inline bool outOfBand(const SliceContext& c, double kx, double ky, double kz) {
    return std::abs(kx) > c.half0 || std::abs(ky) > c.half1 || std::abs(kz) > c.half2;
}

/** The interpolated spectrum and, with Depth, E.grad of it, at one continuous frequency. */
template <class V>
struct Sampled {
    V v{};
    V dv{};
};

/** floor(k) as an index, without a libm call (|k| < 2^62). */
inline std::int64_t floorIndex(double k) {
    const auto i = std::int64_t(k);
    return i - std::int64_t(k < double(i));
}

/** The first tap and the weights of one axis (the kernels without depth cueing: 1, 2, 4, 6 taps);
 *  the same weights as axisWeights. */
template <int T>
[[gnu::always_inline]] inline std::int64_t interiorAxis(const SliceContext& c, double k, float* w) {
    if constexpr (T == 1) {
        w[0] = 1.0f;
        return floorIndex(k + 0.5);
    } else if constexpr (T == 2) {
        const std::int64_t f = floorIndex(k);
        w[1] = float(k - double(f));
        w[0] = 1.0f - w[1];
        return f;
    } else {
        const std::int64_t f = floorIndex(k);
        c.table->weights<T>(k - double(f), w);
        return f + c.first;
    }
}

/** Whether the taps b .. b + T - 1 lie in one period (-P/2, P/2] (no wrap, no period sign). */
template <int T>
inline bool inPrincipalPeriod(std::int64_t b, std::int64_t P) {
    const std::int64_t hi = P / 2;
    return b > hi - P && b + T - 1 <= hi;
}

/** Moves the taps b .. b + T - 1 by whole periods into (-P/2, P/2] (the periodic continuation
 *  the non-band-limited voxel models read), negating `sign` for an odd number of periods of an
 *  antiperiodic axis, as wrapAxis does tap by tap; false where the taps straddle a period's
 *  edge. */
template <int T>
[[gnu::always_inline]] inline bool intoPrincipalPeriod(std::int64_t& b, std::int64_t P, bool anti,
                                                       float& sign) {
    const std::int64_t hi = P / 2;
    if (b > hi || b <= hi - P) {
        const std::int64_t a = b - hi; // periods to remove: ceil(a / P)
        const std::int64_t q = a > 0 ? (a + P - 1) / P : -((-a) / P);
        b -= q * P;
        if (anti && (q & 1)) sign = -sign;
    }
    return b + T - 1 <= hi;
}

/** The storage row of signed index i in (-P, P). */
inline std::int64_t storedIndex(std::int64_t i, std::int64_t P) { return i < 0 ? i + P : i; }

/** Four floats (two complex values) as one SIMD register: GCC's portable vector extension (SSE2
 *  on the x86-64 baseline, NEON on arm64). */
using Float4 = float __attribute__((vector_size(16)));

inline Float4 load4(const float* p) {
    Float4 v;
    std::memcpy(&v, p, sizeof v); // unaligned
    return v;
}

/** The common case of the half-spectrum lookup, for kx >= 0 and an even tap count: the taps of
 *  each axis in one period (moved into (-P/2, P/2] with its sign) and, along x, in the stored
 *  half, so no mirror and no tap-by-tap wrap; false (nothing written) otherwise. The T complex
 * values of a tap row are T/2 SIMD registers, weighted by (w_x w_y) pairs; the z weights apply per
 * plane. */
template <int T>
[[gnu::always_inline]] inline bool interiorComplex(const SliceContext& c, double kx, double ky,
                                                   double kz, cfloat& out) {
    static_assert(T % 2 == 0);
    constexpr int V = T / 2; // registers per tap row
    float wx[T], wy[T], wz[T], sign = 1.0f;
    std::int64_t bx = interiorAxis<T>(c, kx, wx);
    std::int64_t by = interiorAxis<T>(c, ky, wy);
    std::int64_t bz = interiorAxis<T>(c, kz, wz);
    if (!intoPrincipalPeriod<T>(bx, c.P0, c.anti[0], sign) || bx < 0 || bx + T - 1 > c.P0 / 2 ||
        !intoPrincipalPeriod<T>(by, c.P1, c.anti[1], sign) ||
        !intoPrincipalPeriod<T>(bz, c.P2, c.anti[2], sign))
        return false;
    Float4 wxy[T][V]; // (w_x w_y) for the (re, im) pairs of two taps
    for (int v = 0; v < V; ++v) {
        const Float4 w = {wx[2 * v], wx[2 * v], wx[2 * v + 1], wx[2 * v + 1]};
        for (int yc = 0; yc < T; ++yc) wxy[yc][v] = wy[yc] * w;
    }
    const std::int64_t rs = c.rs; // floats per row
    const float* base = c.data + 2 * bx;
    std::int64_t rowY[T];
    for (int t = 0; t < T; ++t) rowY[t] = storedIndex(by + t, c.P1);
    Float4 acc = {0, 0, 0, 0};
    for (int zc = 0; zc < T; ++zc) {
        const std::int64_t plane = c.P1 * storedIndex(bz + zc, c.P2);
        Float4 accZ = {0, 0, 0, 0};
        for (int yc = 0; yc < T; ++yc) {
            const float* row = base + (rowY[yc] + plane) * rs;
            for (int v = 0; v < V; ++v) accZ += wxy[yc][v] * load4(row + 4 * v);
        }
        acc += wz[zc] * accZ;
    }
    out = {sign * (acc[0] + acc[2]), sign * (acc[1] + acc[3])};
    return true;
}

/** Nearest: the one tap, interior as above. */
template <>
[[gnu::always_inline]] inline bool interiorComplex<1>(const SliceContext& c, double kx, double ky,
                                                      double kz, cfloat& out) {
    float w, sign = 1.0f;
    std::int64_t bx = interiorAxis<1>(c, kx, &w);
    std::int64_t by = interiorAxis<1>(c, ky, &w);
    std::int64_t bz = interiorAxis<1>(c, kz, &w);
    if (!intoPrincipalPeriod<1>(bx, c.P0, c.anti[0], sign) || bx < 0 || bx > c.P0 / 2 ||
        !intoPrincipalPeriod<1>(by, c.P1, c.anti[1], sign) ||
        !intoPrincipalPeriod<1>(bz, c.P2, c.anti[2], sign))
        return false;
    const std::int64_t row = storedIndex(by, c.P1) + c.P1 * storedIndex(bz, c.P2);
    out = sign * reinterpret_cast<const cfloat*>(c.data)[row * (c.rs / 2) + bx];
    return true;
}

/** interiorComplex with depth cueing: G and E.grad G from the same taps, for kx >= 0 (T = 3 is
 *  linear over three taps; its x row loads a fourth, zero-weighted tap to fill two registers). */
template <int T>
[[gnu::always_inline]] inline bool interiorComplexDepth(const SliceContext& c, double kx, double ky,
                                                        double kz, Sampled<cfloat>& out) {
    constexpr int TX = (T + 1) / 2 * 2; // taps loaded along x
    constexpr int V = TX / 2;
    float wx[TX] = {}, dx[TX] = {}, wy[T], dy[T], wz[T], dz[T];
    std::int64_t bx, by, bz;
    float sign = 1.0f;
    axisDerivWeights<T>(c, kx, bx, wx, dx);
    axisDerivWeights<T>(c, ky, by, wy, dy);
    axisDerivWeights<T>(c, kz, bz, wz, dz);
    if (!intoPrincipalPeriod<TX>(bx, c.P0, c.anti[0], sign) || bx < 0 || bx + TX - 1 > c.P0 / 2 ||
        !intoPrincipalPeriod<T>(by, c.P1, c.anti[1], sign) ||
        !intoPrincipalPeriod<T>(bz, c.P2, c.anti[2], sign))
        return false;
    Float4 wv[V], dv[V];
    for (int v = 0; v < V; ++v) {
        wv[v] = Float4{wx[2 * v], wx[2 * v], wx[2 * v + 1], wx[2 * v + 1]};
        dv[v] = Float4{dx[2 * v], dx[2 * v], dx[2 * v + 1], dx[2 * v + 1]};
    }
    const float* base = c.data + 2 * bx;
    std::int64_t rowY[T];
    for (int t = 0; t < T; ++t) rowY[t] = storedIndex(by + t, c.P1);
    Float4 acc = {0, 0, 0, 0}, dacc = {0, 0, 0, 0};
    for (int zc = 0; zc < T; ++zc) {
        const std::int64_t plane = c.P1 * storedIndex(bz + zc, c.P2);
        for (int yc = 0; yc < T; ++yc) {
            const float* row = base + (rowY[yc] + plane) * c.rs;
            Float4 sx = {0, 0, 0, 0}, dsx = {0, 0, 0, 0};
            for (int v = 0; v < V; ++v) {
                const Float4 x = load4(row + 4 * v);
                sx += wv[v] * x;
                dsx += dv[v] * x;
            }
            acc += (wz[zc] * wy[yc]) * sx;
            dacc += (wz[zc] * wy[yc] * c.E[0]) * dsx +
                    (c.E[1] * dy[yc] * wz[zc] + c.E[2] * wy[yc] * dz[zc]) * sx;
        }
    }
    out = {{sign * (acc[0] + acc[2]), sign * (acc[1] + acc[3])},
           {sign * (dacc[0] + dacc[2]), sign * (dacc[1] + dacc[3])}};
    return true;
}

/** Samples ahead whose spectrum rows the slice walk prefetches: every sample's for nearest and
 *  linear (their loads are cache misses more than arithmetic: -25 % slice time at 512^2 of a
 *  256^3 spectrum, 8-24 ahead alike), every fourth sample's for the wider kernels (their T x T
 *  rows change slowly along the walk: -6 %; every sample's cost more than it saved). Complex
 *  (FFT) slices only: the Hartley slice prefetches for nearest and linear. */
constexpr int kPrefetchAhead = 12;

/** Prefetches the rows an interior sample at continuous k will read (nothing for the others). */
template <int T>
[[gnu::always_inline]] inline void prefetchInterior(const SliceContext& c, double kx, double ky,
                                                    double kz) {
    if (kx < 0) {
        kx = -kx;
        ky = -ky;
        kz = -kz;
    }
    const std::int64_t off = T >= 4 ? c.first : 0; // the first tap, as interiorAxis
    const std::int64_t bx = floorIndex(T == 1 ? kx + 0.5 : kx) + off;
    const std::int64_t by = floorIndex(T == 1 ? ky + 0.5 : ky) + off;
    const std::int64_t bz = floorIndex(T == 1 ? kz + 0.5 : kz) + off;
    if (bx < 0 || bx + T - 1 > c.P0 / 2 || !inPrincipalPeriod<T>(by, c.P1) ||
        !inPrincipalPeriod<T>(bz, c.P2))
        return;
    const float* base = c.data + 2 * bx;
    for (int zc = 0; zc < T; ++zc)
        for (int yc = 0; yc < T; ++yc)
            __builtin_prefetch(
                base + (storedIndex(by + yc, c.P1) + c.P1 * storedIndex(bz + zc, c.P2)) * c.rs);
}

/** prefetchInterior for the Hartley spectrum (no half-spectrum mirror). */
template <int T>
[[gnu::always_inline]] inline void prefetchHartleyInterior(const SliceContext& c, double kx,
                                                           double ky, double kz) {
    const std::int64_t off = T >= 4 ? c.first : 0; // the first tap, as interiorAxis
    const std::int64_t bx = floorIndex(T == 1 ? kx + 0.5 : kx) + off;
    const std::int64_t by = floorIndex(T == 1 ? ky + 0.5 : ky) + off;
    const std::int64_t bz = floorIndex(T == 1 ? kz + 0.5 : kz) + off;
    if (!inPrincipalPeriod<T>(bx, c.P0) || !inPrincipalPeriod<T>(by, c.P1) ||
        !inPrincipalPeriod<T>(bz, c.P2))
        return;
    const float* base = c.data + storedIndex(bx, c.P0);
    for (int zc = 0; zc < T; ++zc)
        for (int yc = 0; yc < T; ++yc)
            __builtin_prefetch(
                base + (storedIndex(by + yc, c.P1) + c.P1 * storedIndex(bz + zc, c.P2)) * c.rs);
}

/** Interpolated complex G at continuous signed frequency k from the half spectrum (with Depth
 *  also E.grad G), the period signs included; no band cut, no model. */
template <int T, bool Depth>
inline Sampled<cfloat> interpolateComplex(const SliceContext& c, double kx, double ky, double kz) {
    bool conjugate = false;
    if (kx < 0) {
        kx = -kx;
        ky = -ky;
        kz = -kz;
        conjugate = true;
    }
    std::int64_t ix[T], iy[T], iz[T];
    float wx[T], wy[T], wz[T], dx[T], dy[T], dz[T];
    tapWeights<T, Depth>(c, kx, ky, kz, ix, iy, iz, wx, wy, wz, dx, dy, dz);
    bool flip[T];
    bool anyFlip = false;
    float my[T], mz[T]; // the mirror's sign: -(+P/2) is stored as +P/2, one period away
    for (int t = 0; t < T; ++t) {
        flip[t] = ix[t] < 0; // beyond the stored half: its negative image
        if (flip[t]) ix[t] = -ix[t];
        anyFlip |= flip[t];
        my[t] = c.anti[1] && 2 * iy[t] == c.P1 ? -1.0f : 1.0f;
        mz[t] = c.anti[2] && 2 * iz[t] == c.P2 ? -1.0f : 1.0f;
        if (iy[t] < 0) iy[t] += c.P1;
        if (iz[t] < 0) iz[t] += c.P2;
    }
    const cfloat* base = reinterpret_cast<const cfloat*>(c.data);
    const std::int64_t H = c.rs / 2; // complex per row
    cfloat acc{}, dacc{};
    auto accumulate = [&](int zc, int yc, const cfloat* vals) {
        cfloat sx{};
        for (int xc = 0; xc < T; ++xc) sx += wx[xc] * vals[xc];
        acc += (wz[zc] * wy[yc]) * sx;
        if constexpr (Depth) {
            cfloat dsx{};
            for (int xc = 0; xc < T; ++xc) dsx += dx[xc] * vals[xc];
            dacc += (wz[zc] * wy[yc] * c.E[0]) * dsx +
                    (c.E[1] * dy[yc] * wz[zc] + c.E[2] * wy[yc] * dz[zc]) * sx;
        }
    };
    cfloat vals[T];
    for (int zc = 0; zc < T; ++zc)
        for (int yc = 0; yc < T; ++yc) {
            const cfloat* row = base + (iy[yc] + c.P1 * iz[zc]) * H;
            if (!anyFlip) {
                for (int xc = 0; xc < T; ++xc) vals[xc] = row[ix[xc]];
            } else {
                const std::int64_t jy = iy[yc] == 0 ? 0 : c.P1 - iy[yc];
                const std::int64_t jz = iz[zc] == 0 ? 0 : c.P2 - iz[zc];
                const cfloat* mrow = base + (jy + c.P1 * jz) * H;
                const float ms = my[yc] * mz[zc];
                for (int xc = 0; xc < T; ++xc)
                    vals[xc] = flip[xc] ? ms * std::conj(mrow[ix[xc]]) : row[ix[xc]];
            }
            accumulate(zc, yc, vals);
        }
    // G(k) = conj G(-k), and then grad G(k) = -conj grad G(-k).
    if (conjugate) return {std::conj(acc), -std::conj(dacc)};
    return {acc, dacc};
}

/** The voxel model's transfer function T(k) = prod_a t(k_a / P_a) and, with Depth, E.grad T. */
template <bool Depth>
inline void modelTransfer(const SliceContext& c, double kx, double ky, double kz, float& t,
                          float& gt) {
    const double nu[3] = {kx * c.invP[0], ky * c.invP[1], kz * c.invP[2]};
    const float tx = c.model->valueCovered(float(nu[0])), ty = c.model->valueCovered(float(nu[1])),
                tz = c.model->valueCovered(float(nu[2]));
    t = tx * ty * tz;
    if constexpr (Depth) {
        gt = c.E[0] * float(c.invP[0]) * c.model->derivative(nu[0]) * ty * tz +
             c.E[1] * float(c.invP[1]) * tx * c.model->derivative(nu[1]) * tz +
             c.E[2] * float(c.invP[2]) * tx * ty * c.model->derivative(nu[2]);
    }
}

/** The slice value at continuous signed frequency k: the model's spectrum (band cut or transfer
 *  function), with Depth the depth-cued a G + i E.grad G of it. */
template <int T, bool Depth>
inline cfloat sampleComplex(const SliceContext& c, double kx, double ky, double kz, float t,
                            float gt) {
    if (outOfBand(c, kx, ky, kz)) return {};
    Sampled<cfloat> s;
    bool interior = false;
    // G(k) = conj G(-k) for kx < 0, and then grad G(k) = -conj grad G(-k) (interpolateComplex).
    const double sx = kx < 0 ? -1.0 : 1.0;
    if constexpr (Depth) {
        interior = interiorComplexDepth<T>(c, sx * kx, sx * ky, sx * kz, s);
        if (interior && kx < 0) s = {std::conj(s.v), -std::conj(s.dv)};
    } else {
        interior = interiorComplex<T>(c, sx * kx, sx * ky, sx * kz, s.v);
        if (interior && kx < 0) s.v = std::conj(s.v);
    }
    if (!interior) s = interpolateComplex<T, Depth>(c, kx, ky, kz);
    if (c.model) {
        if constexpr (Depth) s.dv = t * s.dv + gt * s.v; // E.grad (T G)
        s.v *= t;
    }
    if constexpr (Depth)
        return {c.depthA * s.v.real() - s.dv.imag(), c.depthA * s.v.imag() + s.dv.real()};
    return s.v;
}

/** The common case of the Hartley lookup: the taps of each axis in one period (moved into
 *  (-P/2, P/2] with its sign), so no tap-by-tap wrap; false (nothing written) otherwise. Four taps
 * of a row are one SIMD register. */
template <int T>
[[gnu::always_inline]] inline bool interiorHartley(const SliceContext& c, double kx, double ky,
                                                   double kz, float& out) {
    float wx[T], wy[T], wz[T], sign = 1.0f;
    std::int64_t bx = interiorAxis<T>(c, kx, wx);
    std::int64_t by = interiorAxis<T>(c, ky, wy);
    std::int64_t bz = interiorAxis<T>(c, kz, wz);
    if (!intoPrincipalPeriod<T>(bx, c.P0, c.anti[0], sign) ||
        !intoPrincipalPeriod<T>(by, c.P1, c.anti[1], sign) ||
        !intoPrincipalPeriod<T>(bz, c.P2, c.anti[2], sign))
        return false;
    std::int64_t ix[T], rowY[T];
    for (int t = 0; t < T; ++t) {
        ix[t] = storedIndex(bx + t, c.P0);
        rowY[t] = storedIndex(by + t, c.P1);
    }
    const bool contiguous = ix[T - 1] == ix[0] + T - 1; // the x taps do not cross kx = 0
    float acc = 0.0f;
    for (int zc = 0; zc < T; ++zc) {
        const std::int64_t plane = c.P1 * storedIndex(bz + zc, c.P2);
        float accZ = 0.0f;
        for (int yc = 0; yc < T; ++yc) {
            const float* row = c.data + (rowY[yc] + plane) * c.rs;
            if constexpr (T == 4) {
                if (contiguous) {
                    const Float4 p = Float4{wx[0], wx[1], wx[2], wx[3]} * load4(row + ix[0]);
                    accZ += wy[yc] * ((p[0] + p[1]) + (p[2] + p[3]));
                    continue;
                }
            }
            float sx = 0.0f;
            for (int xc = 0; xc < T; ++xc) sx += wx[xc] * row[ix[xc]];
            accZ += wy[yc] * sx;
        }
        acc += wz[zc] * accZ;
    }
    out = sign * acc;
    return true;
}

/** Interpolated Hartley value at continuous signed frequency k; with Derivative also E.grad H
 *  there (depth cueing, FHT path), from the same taps with the derivative weights. Period signs
 *  included; no band cut, no model. */
template <int T, bool Derivative = false>
inline Sampled<float> interpolateHartley(const SliceContext& c, double kx, double ky, double kz) {
    std::int64_t ix[T], iy[T], iz[T];
    float wx[T], wy[T], wz[T], dx[T], dy[T], dz[T];
    tapWeights<T, Derivative>(c, kx, ky, kz, ix, iy, iz, wx, wy, wz, dx, dy, dz);
    for (int t = 0; t < T; ++t) {
        if (ix[t] < 0) ix[t] += c.P0;
        if (iy[t] < 0) iy[t] += c.P1;
        if (iz[t] < 0) iz[t] += c.P2;
    }
    float acc = 0.0f, dacc = 0.0f;
    for (int zc = 0; zc < T; ++zc)
        for (int yc = 0; yc < T; ++yc) {
            const float* row = c.data + (iy[yc] + c.P1 * iz[zc]) * c.rs;
            float sx = 0.0f;
            for (int xc = 0; xc < T; ++xc) sx += wx[xc] * row[ix[xc]];
            acc += (wz[zc] * wy[yc]) * sx;
            if constexpr (Derivative) {
                float dsx = 0.0f;
                for (int xc = 0; xc < T; ++xc) dsx += dx[xc] * row[ix[xc]];
                dacc += (wz[zc] * wy[yc] * c.E[0]) * dsx +
                        (c.E[1] * dy[yc] * wz[zc] + c.E[2] * wy[yc] * dz[zc]) * sx;
            }
        }
    return {acc, dacc};
}

/** The Hartley slice value at continuous signed frequency k: the model's Hartley spectrum H_m
 *  (band cut or transfer function), with Depth a H_m(k) + E.grad H_m(-k). */
template <int T, bool Depth>
inline float sampleHartley(const SliceContext& c, double kx, double ky, double kz, float t,
                           float gt) {
    if (outOfBand(c, kx, ky, kz)) return 0.0f;
    // The value's taps (linear with depth cueing runs on 3, the first of weight 0: 2 here).
    constexpr int TV = T == 3 ? 2 : T;
    float h;
    if (!interiorHartley<TV>(c, kx, ky, kz, h)) h = interpolateHartley<T>(c, kx, ky, kz).v;
    if constexpr (!Depth) {
        return c.model ? t * h : h;
    } else {
        const Sampled<float> m =
            interpolateHartley<T, true>(c, -kx, -ky, -kz); // H(-k), E.grad H(-k)
        if (!c.model) return c.depthA * h + m.dv;
        // T is even, grad T odd: E.grad (T H)(-k) = T(k) E.grad H(-k) - H(-k) E.grad T(k).
        return c.depthA * t * h + t * m.dv - gt * m.v;
    }
}

/** The model's transfer function along the slice: a row's products at once (vectorised), single
 *  samples (Nyquist aliases, depth cueing) from the tables. */
struct RowTransfer {
    const SliceContext& c;
    const FrameMapping& f;
    std::vector<float> row;

    RowTransfer(const SliceContext& ctx, const FrameMapping& map, int M) : c(ctx), f(map) {
        if (c.model) row.resize(std::size_t(M));
    }
    /** T at m = m0 .. m0 + count - 1 of image row n into row[first ...]. */
    void fill(int first, int m0, int count, int n) {
        if (!c.model) return;
        float nu0[3], dnu[3];
        for (int a = 0; a < 3; ++a) {
            nu0[a] = float((m0 * f.A[a] + n * f.B[a]) * c.invP[a]);
            dnu[a] = float(f.A[a] * c.invP[a]);
        }
        voxelModelTransferRow(c.model->model(), nu0, dnu, count, row.data() + first);
    }
    /** T and E.grad T at image frequency (m, n); the row's value when Depth is off. */
    template <bool Depth>
    void at(double m, double n, int index, float& t, float& gt) const {
        gt = 0.0f;
        if (!c.model) {
            t = 1.0f;
        } else if (Depth || index < 0) {
            modelTransfer<Depth>(c, m * f.A[0] + n * f.B[0], m * f.A[1] + n * f.B[1],
                                 m * f.A[2] + n * f.B[2], t, gt);
        } else {
            t = row[std::size_t(index)];
        }
    }
};

/** The slice value at image frequency (m, n): the complex or the Hartley sample, with the voxel
 *  model's transfer value from the row's (index) or computed on its own (index < 0: the
 *  Nyquist aliases, depth cueing). */
template <int T, bool Depth, bool Hartley>
inline auto slicePoint(const SliceContext& c, const FrameMapping& f, const RowTransfer& model,
                       double m, double n, int index) {
    float t, gt;
    model.at<Depth>(m, n, index, t, gt);
    const double kx = m * f.A[0] + n * f.B[0], ky = m * f.A[1] + n * f.B[1],
                 kz = m * f.A[2] + n * f.B[2];
    if constexpr (Hartley)
        return sampleHartley<T, Depth>(c, kx, ky, kz, t, gt);
    else
        return sampleComplex<T, Depth>(c, kx, ky, kz, t, gt);
}

/** The mean of a slice sample over the aliases of the Nyquist frequencies: (+-m) when column m
 *  is the Nyquist column, (+-n) when row n is the Nyquist row, so the FFT and FHT paths compute
 *  the same image. Only the Nyquist row and column come here. */
template <class V, class Sample>
V nyquistMean(const Sample& sample, int m, int n, bool nyquistColumn, bool nyquistRow) {
    const int ms = nyquistColumn ? 2 : 1;
    const int ns = nyquistRow ? 2 : 1;
    V sum{};
    for (int a = 0; a < ms; ++a)
        for (int b = 0; b < ns; ++b) sum += sample(a ? -m : m, b ? -n : n, -1);
    return sum / float(ms * ns);
}

AxisLookup::AxisLookup(std::int64_t P, bool anti, std::int64_t stride, std::int64_t reach)
    : m_reach(reach), m_offset(std::size_t(2 * reach + 1)), m_sign(std::size_t(2 * reach + 1)) {
    const std::int64_t hi = P / 2;
    for (std::int64_t i = -reach; i <= reach; ++i) {
        const std::int64_t a = i - hi; // periods to remove: ceil(a / P), as intoPrincipalPeriod
        const std::int64_t q = a > 0 ? (a + P - 1) / P : -((-a) / P);
        m_offset[std::size_t(i + reach)] = storedIndex(i - q * P, P) * stride;
        m_sign[std::size_t(i + reach)] = anti && (q & 1) ? -1.0f : 1.0f;
    }
}

} // namespace

detail::CpuSliceLookups::CpuSliceLookups(const Spectrum& s)
    : x(s.padded[0], s.volumeDims[0] % 2 == 0, 1,
        s.kind == TransformKind::Fht ? 4 * s.padded[0] + KernelTable::kMaxTaps + 2 : 0),
      y(s.padded[1], s.volumeDims[1] % 2 == 0, s.rowStride(),
        4 * s.padded[1] + KernelTable::kMaxTaps + 2),
      z(s.padded[2], s.volumeDims[2] % 2 == 0, s.rowStride() * s.padded[1],
        4 * s.padded[2] + KernelTable::kMaxTaps + 2) {}

namespace {

using FrameLookups = detail::CpuSliceLookups;

/** The columns [first, last] of one slice row whose samples take the fast path: the m where
 *  every constraint lo <= a + b m <= hi holds, shrunk by one column on each side (the rounding
 *  of the bounds never admits a sample the fast path cannot take). */
class ColumnSpan {
public:
    ColumnSpan(int first, int last) : m_lo(first), m_hi(last) {}
    void require(double a, double b, double lo, double hi) {
        if (b == 0.0) {
            if (!(a >= lo && a <= hi)) m_lo = 1.0, m_hi = 0.0;
            return;
        }
        double m0 = (lo - a) / b, m1 = (hi - a) / b;
        if (b < 0) std::swap(m0, m1);
        m_lo = std::max(m_lo, m0);
        m_hi = std::min(m_hi, m1);
    }
    int first() const { return int(std::ceil(std::clamp(m_lo, -1e9, 1e9))) + 1; }
    int last() const { return int(std::floor(std::clamp(m_hi, -1e9, 1e9))) - 1; }

private:
    double m_lo, m_hi;
};

/** Which copy of the half spectrum a fast span of the half slice reads, as the general path
 *  does: the sample at k is read at k+ = s k (s = +1 where kx >= 0; s = -1, the conjugate of the
 *  mirror, where kx < 0), moved by q >= 0 periods along x (k+ - q P0 e_x, times -1 for an odd q
 *  along an antiperiodic x). q = 0 is the band; the trilinear and B-spline voxel models read
 *  beyond it. Mirroring before the floor and moving after it (exact integers) keeps the general
 *  path's taps where k+ falls on an integer (a truncated kernel's taps are not symmetric). */
struct Side {
    double s = 1.0;
    int q = 0;
    /** The moved taps lie at negative x (k+ - q P0 in (-P0/2, 0]): each is read at its mirror
     *  image, conjugated (the general path's per-tap mirror, for all taps at once). */
    bool reflect = false;
};

/** The fast columns of row n of the half slice for one side: every tap along x in the stored
 *  half, along y and z inside the lookups, k inside the band. */
template <int T, bool Depth>
ColumnSpan fastColumns(const SliceContext& c, const FrameMapping& f, const FrameLookups& l, int M,
                       int n, Side side) {
    ColumnSpan span(0, M / 2 - 1);
    const double s = side.s;
    // The first tap relative to floor(kx) and the taps loaded along x. Depth cueing's linear
    // (T = 3) starts at round(k) - 1 on integers (floor(k) at most) and loads a fourth tap.
    const double first = T == 1 ? 0.0 : T == 3 ? -1.0 : double(c.first);
    const double lastX = Depth && T == 3 ? 3.0 : first + T - 1;
    const double xlo = std::max(-first, s < 0 ? 1e-9 : 0.0);
    const double xhi = double(c.P0 / 2) - (T == 1 ? 0.0 : lastX);
    const double half[3] = {c.half0, c.half1, c.half2};
    const double reach[3] = {std::numeric_limits<double>::infinity(), double(l.y.reach() - T - 2),
                             double(l.z.reach() - T - 2)};
    for (int a = 0; a < 3; ++a) {
        const double ka = s * n * f.B[a], kb = s * f.A[a];
        const double lim = std::min(half[a], reach[a]);
        if (a == 0) {
            span.require(ka, kb, -lim, lim); // the band, on k itself
            // Reflected: the taps floor(v) + first + t in [-P0/2, 0] (nearest: round(v)).
            const double rlo = -double(c.P0 / 2) - (T == 1 ? 0.0 : first);
            const double rhi = T == 1 ? -0.5 : -(first + T - 1);
            span.require(s * n * f.B[0] - side.q * double(c.P0), kb, side.reflect ? rlo : xlo,
                         side.reflect ? rhi : xhi);
        } else {
            span.require(ka, kb, -lim, lim);
        }
    }
    return span;
}

/** Two doubles, two int32 and two floats as SIMD values (SSE2 on the x86-64 baseline). */
using Double2 = double __attribute__((vector_size(16)));
using Int2 = std::int32_t __attribute__((vector_size(8)));
using Float2 = float __attribute__((vector_size(8)));

/** The floor indices and fractional parts of one axis for a chunk of fast columns: k = m a + b
 *  at m = m0, m0 + 1, ..., two columns per SIMD operation. The same values as floorIndex and
 *  k - floor(k) (|k| < 2^31 in the fast columns; the fraction stays in double for the tables,
 *  in float for linear, as axisWeights rounds it). T = 1 rounds to nearest (floor(k + 1/2)). */
template <int T, class Frac>
inline void floorChunk(double a, double b, int m0, int count, std::int32_t* index, Frac* frac) {
    for (int j = 0; j < count; j += 2) {
        // k from m exactly as the general path computes it (m a + b), not accumulated.
        const Double2 mm = {double(m0 + j), double(m0 + j + 1)};
        const Double2 kk = T == 1 ? mm * a + b + 0.5 : mm * a + b;
        const Double2 t = __builtin_convertvector(__builtin_convertvector(kk, Int2), Double2);
        const Double2 fl = kk < t ? t - 1.0 : t;
        const Int2 i = __builtin_convertvector(fl, Int2);
        index[j] = i[0];
        index[j + 1] = i[1];
        if constexpr (T > 1) {
            const Double2 fr = kk - fl;
            if constexpr (std::is_same_v<Frac, float>) {
                const Float2 f2 = __builtin_convertvector(fr, Float2);
                frac[j] = f2[0];
                frac[j + 1] = f2[1];
            } else {
                frac[j] = fr[0];
                frac[j + 1] = fr[1];
            }
        }
    }
}

/** What a fast column's sample reads, copied out of the frame's context into locals (the
 *  compiler then keeps them in registers across the row's stores). */
struct FastTaps {
    const float* data;
    const KernelTable* table;
    std::int64_t first;
    const std::int64_t *ox, *oy, *oz; // the lookups, indexed by signed tap index
    const float *sx, *sy, *sz;

    FastTaps(const SliceContext& c, const FrameLookups& l)
        : data(c.data), table(c.table), first(c.first), ox(l.x.offsets()), oy(l.y.offsets()),
          oz(l.z.offsets()), sx(l.x.signs()), sy(l.y.signs()), sz(l.z.signs()) {}

    /** The weights of one axis from the fraction (axisWeights), and its first tap. */
    template <int T, class Frac>
    [[gnu::always_inline]] std::int64_t weights(std::int32_t floor, Frac frac, float* w) const {
        if constexpr (T == 1) {
            w[0] = 1.0f;
            return floor;
        } else if constexpr (T == 2) {
            w[1] = frac;
            w[0] = 1.0f - w[1];
            return floor;
        } else {
            table->weights<T>(frac, w);
            return std::int64_t(floor) + first;
        }
    }

    /** The weights and derivative weights of one axis from the fraction (axisDerivWeights), and
     *  its first tap. */
    template <int T>
    [[gnu::always_inline]] std::int64_t derivWeights(std::int32_t floor, double frac, float* w,
                                                     float* dw) const {
        if constexpr (T == 3) {
            // On integers (within 1e-6), the central difference about round(k).
            const bool up = frac > 0.5; // round(k) = floor + 1 (frac = 1/2 is no integer)
            if ((up ? 1.0 - frac : frac) < 1e-6) {
                w[0] = 0.0f, w[1] = 1.0f, w[2] = 0.0f;
                dw[0] = -0.5f, dw[1] = 0.0f, dw[2] = 0.5f;
                return std::int64_t(floor) + (up ? 0 : -1);
            }
            w[0] = 0.0f;
            w[2] = float(frac);
            w[1] = 1.0f - w[2];
            dw[0] = 0.0f, dw[1] = -1.0f, dw[2] = 1.0f;
            return std::int64_t(floor) - 1;
        } else {
            table->weights(frac, w);
            table->derivativeWeights(frac, dw);
            return std::int64_t(floor) + first;
        }
    }

    /** The depth-cued sample at k (kx >= 0): G and E.grad G from the same taps,
     *  interiorComplexDepth's sums with the y and z rows and period signs from the lookups. */
    template <int T>
    [[gnu::always_inline]] Sampled<cfloat> depthSample(const std::int32_t* i, const double* fr,
                                                       const float* E) const {
        constexpr int TX = (T + 1) / 2 * 2; // taps loaded along x
        constexpr int V = TX / 2;
        float wx[TX] = {}, dx[TX] = {}, wy[T], dy[T], wz[T], dz[T];
        const std::int64_t bx = derivWeights<T>(i[0], fr[0], wx, dx);
        const std::int64_t by = derivWeights<T>(i[1], fr[1], wy, dy);
        const std::int64_t bz = derivWeights<T>(i[2], fr[2], wz, dz);
        const std::int64_t *ry = oy + by, *rz = oz + bz;
        for (int t = 0; t < T; ++t) {
            wy[t] *= sy[by + t], dy[t] *= sy[by + t];
            wz[t] *= sz[bz + t], dz[t] *= sz[bz + t];
        }
        Float4 wv[V], dv[V];
        for (int v = 0; v < V; ++v) {
            wv[v] = Float4{wx[2 * v], wx[2 * v], wx[2 * v + 1], wx[2 * v + 1]};
            dv[v] = Float4{dx[2 * v], dx[2 * v], dx[2 * v + 1], dx[2 * v + 1]};
        }
        const float* base = data + 2 * bx;
        Float4 acc = {0, 0, 0, 0}, dacc = {0, 0, 0, 0};
        for (int zc = 0; zc < T; ++zc) {
            const float* plane = base + rz[zc];
            for (int yc = 0; yc < T; ++yc) {
                const float* row = plane + ry[yc];
                Float4 rx = {0, 0, 0, 0}, drx = {0, 0, 0, 0}; // the row: sum and derivative along x
                for (int v = 0; v < V; ++v) {
                    const Float4 x = load4(row + 4 * v);
                    rx += wv[v] * x;
                    drx += dv[v] * x;
                }
                acc += (wz[zc] * wy[yc]) * rx;
                dacc += (wz[zc] * wy[yc] * E[0]) * drx +
                        (E[1] * dy[yc] * wz[zc] + E[2] * wy[yc] * dz[zc]) * rx;
            }
        }
        return {{acc[0] + acc[2], acc[1] + acc[3]}, {dacc[0] + dacc[2], dacc[1] + dacc[3]}};
    }

    /** weights() with the taps reflected through 0 where Reflect: b .. b + T - 1 become
     *  -(b + T - 1) .. -b, the weights in reverse order. */
    template <int T, bool Reflect, class Frac>
    [[gnu::always_inline]] std::int64_t tapsOf(std::int32_t floor, Frac frac, float* w) const {
        const std::int64_t b = weights<T>(floor, frac, w);
        if constexpr (!Reflect) {
            return b;
        } else {
            for (int t = 0; t < T / 2; ++t) std::swap(w[t], w[T - 1 - t]);
            return -b - (T - 1);
        }
    }

    /** The half-spectrum sample at k (kx >= 0) from its floor indices and fractions:
     *  interiorComplex's sum with the y and z rows and period signs from the lookups (the same
     *  values where interiorComplex applies, and wrapAxis's per-tap signs where the taps straddle
     *  a period's edge). */
    template <int T, bool Reflect = false, class Frac>
    [[gnu::always_inline]] cfloat sample(const std::int32_t* i, const Frac* fr) const {
        float wx[T], wy[T], wz[T];
        const std::int64_t bx = tapsOf<T, Reflect>(i[0], fr[0], wx);
        const std::int64_t by = tapsOf<T, Reflect>(i[1], fr[1], wy);
        const std::int64_t bz = tapsOf<T, Reflect>(i[2], fr[2], wz);
        const std::int64_t *ry = oy + by, *rz = oz + bz;
        const float *ty = sy + by, *tz = sz + bz;
        if constexpr (T == 1) {
            const float* p = data + 2 * bx + ry[0] + rz[0];
            return (ty[0] * tz[0]) * cfloat(p[0], p[1]);
        } else {
            constexpr int V = T / 2;
            Float4 wxy[T][V];
            for (int v = 0; v < V; ++v) {
                const Float4 w = {wx[2 * v], wx[2 * v], wx[2 * v + 1], wx[2 * v + 1]};
                for (int yc = 0; yc < T; ++yc) wxy[yc][v] = (ty[yc] * wy[yc]) * w;
            }
            const float* base = data + 2 * bx;
            Float4 acc = {0, 0, 0, 0};
            for (int zc = 0; zc < T; ++zc) {
                const float* plane = base + rz[zc];
                Float4 accZ = {0, 0, 0, 0};
                for (int yc = 0; yc < T; ++yc) {
                    const float* row = plane + ry[yc];
                    for (int v = 0; v < V; ++v) accZ += wxy[yc][v] * load4(row + 4 * v);
                }
                acc += (tz[zc] * wz[zc]) * accZ;
            }
            return {acc[0] + acc[2], acc[1] + acc[3]};
        }
    }

    /** The Hartley sample at k from its floor indices and fractions: interiorHartley's sum with
     *  every axis's stored index and period sign from the lookups. */
    template <int T, class Frac>
    [[gnu::always_inline]] float hartley(const std::int32_t* i, const Frac* fr) const {
        float wx[T], wy[T], wz[T];
        const std::int64_t bx = weights<T>(i[0], fr[0], wx), by = weights<T>(i[1], fr[1], wy),
                           bz = weights<T>(i[2], fr[2], wz);
        const std::int64_t *rx = ox + bx, *ry = oy + by, *rz = oz + bz;
        const float *tx = sx + bx, *ty = sy + by, *tz = sz + bz;
        for (int t = 0; t < T; ++t) wx[t] *= tx[t];
        // The x taps do not cross kx = 0 or a period's edge: 4 taps are one SIMD load, the rows
        // summed per lane and the lanes once at the end.
        const bool contiguous = rx[T - 1] == rx[0] + T - 1;
        if constexpr (T == 4 || T == 6) {
            if (contiguous) {
                // Taps 0-3 in one register; for 6 taps, taps 2-5 in a second (2 and 3 weighted
                // 0 there), so no load reaches past the last tap.
                const Float4 w4 = {wx[0], wx[1], wx[2], wx[3]};
                const Float4 w6 = {0.0f, 0.0f, wx[T - 2], wx[T - 1]};
                Float4 acc4 = {0, 0, 0, 0};
                for (int zc = 0; zc < T; ++zc) {
                    const float* plane = data + rz[zc] + rx[0];
                    Float4 accZ = {0, 0, 0, 0};
                    for (int yc = 0; yc < T; ++yc) {
                        const float w = ty[yc] * wy[yc];
                        accZ += (w * w4) * load4(plane + ry[yc]);
                        if constexpr (T == 6) accZ += (w * w6) * load4(plane + ry[yc] + 2);
                    }
                    acc4 += (tz[zc] * wz[zc]) * accZ;
                }
                return (acc4[0] + acc4[1]) + (acc4[2] + acc4[3]);
            }
        }
        float acc = 0.0f;
        for (int zc = 0; zc < T; ++zc) {
            const float* plane = data + rz[zc];
            float accZ = 0.0f;
            for (int yc = 0; yc < T; ++yc) {
                const float* row = plane + ry[yc];
                const float w = ty[yc] * wy[yc];
                float sum = 0.0f;
                for (int xc = 0; xc < T; ++xc) sum += wx[xc] * row[rx[xc]];
                accZ += w * sum;
            }
            acc += (tz[zc] * wz[zc]) * accZ;
        }
        return acc;
    }

    /** The Hartley value and E.grad of it at k from the same taps with the derivative weights
     *  (interpolateHartley<T, true>), every axis from the lookups. */
    template <int T>
    [[gnu::always_inline]] Sampled<float> hartleyDepth(const std::int32_t* i, const double* fr,
                                                       const float* E) const {
        float wx[T], dx[T], wy[T], dy[T], wz[T], dz[T];
        const std::int64_t bx = derivWeights<T>(i[0], fr[0], wx, dx);
        const std::int64_t by = derivWeights<T>(i[1], fr[1], wy, dy);
        const std::int64_t bz = derivWeights<T>(i[2], fr[2], wz, dz);
        const std::int64_t *rx = ox + bx, *ry = oy + by, *rz = oz + bz;
        for (int t = 0; t < T; ++t) {
            wx[t] *= sx[bx + t], dx[t] *= sx[bx + t];
            wy[t] *= sy[by + t], dy[t] *= sy[by + t];
            wz[t] *= sz[bz + t], dz[t] *= sz[bz + t];
        }
        if constexpr (T == 4 || T == 6) {
            if (rx[T - 1] == rx[0] + T - 1) { // contiguous x taps: SIMD lanes, as hartley()
                const Float4 w4 = {wx[0], wx[1], wx[2], wx[3]}, d4 = {dx[0], dx[1], dx[2], dx[3]};
                const Float4 w6 = {0.0f, 0.0f, wx[T - 2], wx[T - 1]};
                const Float4 d6 = {0.0f, 0.0f, dx[T - 2], dx[T - 1]};
                Float4 acc = {0, 0, 0, 0}, dacc = {0, 0, 0, 0};
                for (int zc = 0; zc < T; ++zc)
                    for (int yc = 0; yc < T; ++yc) {
                        const float* row = data + rz[zc] + ry[yc] + rx[0];
                        const Float4 x = load4(row);
                        Float4 sum = w4 * x, dsum = d4 * x;
                        if constexpr (T == 6) {
                            const Float4 x6 = load4(row + 2);
                            sum += w6 * x6;
                            dsum += d6 * x6;
                        }
                        acc += (wz[zc] * wy[yc]) * sum;
                        dacc += (wz[zc] * wy[yc] * E[0]) * dsum +
                                (E[1] * dy[yc] * wz[zc] + E[2] * wy[yc] * dz[zc]) * sum;
                    }
                return {(acc[0] + acc[1]) + (acc[2] + acc[3]),
                        (dacc[0] + dacc[1]) + (dacc[2] + dacc[3])};
            }
        }
        float acc = 0.0f, dacc = 0.0f;
        for (int zc = 0; zc < T; ++zc)
            for (int yc = 0; yc < T; ++yc) {
                const float* row = data + rz[zc] + ry[yc];
                float sum = 0.0f, dsum = 0.0f;
                for (int xc = 0; xc < T; ++xc) {
                    sum += wx[xc] * row[rx[xc]];
                    dsum += dx[xc] * row[rx[xc]];
                }
                acc += (wz[zc] * wy[yc]) * sum;
                dacc += (wz[zc] * wy[yc] * E[0]) * dsum +
                        (E[1] * dy[yc] * wz[zc] + E[2] * wy[yc] * dz[zc]) * sum;
            }
        return {acc, dacc};
    }

    /** Prefetches the T x T tap rows of the sample with these floor indices: the half
     *  spectrum's (Hartley: the full one's, x from its lookup), the first tap as weights()
     *  (derivWeights for depth cueing's linear, T = 3), reflected as tapsOf. */
    template <int T, bool Hartley = false, bool Reflect = false>
    [[gnu::always_inline]] void prefetch(const std::int32_t* i) const {
        const std::int64_t off = T >= 4 ? first : T == 3 ? -1 : 0;
        auto b = [&](int a) { return Reflect ? -(i[a] + off) - (T - 1) : i[a] + off; };
        const float* base = data + (Hartley ? ox[b(0)] : 2 * b(0));
        const std::int64_t *ry = oy + b(1), *rz = oz + b(2);
        for (int zc = 0; zc < T; ++zc)
            for (int yc = 0; yc < T; ++yc) __builtin_prefetch(base + rz[zc] + ry[yc]);
    }
};

/** What a row walk samples, for its prefetches: the half spectrum (plain, or with the taps
 *  reflected: Side::reflect), the Hartley spectrum, or the half spectrum with depth cueing. */
enum class Walk { Complex, ComplexReflected, Hartley, Depth };

/** Walks the columns m = m0 .. m1 of a row whose k(m) = m a + b (per axis): the floors and
 *  fractions of a chunk of columns are computed, and their rows prefetched, one chunk ahead of
 *  the sums; emit(m, floors, fractions) per column in order. */
template <int T, Walk W, class Emit>
[[gnu::always_inline]] inline void walkColumns(const FastTaps& taps, const double* a,
                                               const double* b, int m0, int m1, Emit&& emit) {
    using Frac = std::conditional_t<T <= 2, float, double>;
    constexpr int kChunk = 16;
    // Per chunk (two, alternating): per column the x, y, z floors and fractions.
    alignas(16) std::int32_t index[2][kChunk][3];
    alignas(16) Frac frac[2][kChunk][3];
    auto prepare = [&](int buf, int first) {
        const int count = std::min(kChunk, m1 - first + 1);
        alignas(16) std::int32_t ix[kChunk + 1];
        alignas(16) Frac fx[kChunk + 1];
        for (int axis = 0; axis < 3; ++axis) {
            floorChunk<T>(a[axis], b[axis], first, count, ix, fx);
            for (int j = 0; j < count; ++j) {
                index[buf][j][axis] = ix[j];
                frac[buf][j][axis] = fx[j];
            }
        }
        for (int j = 0; j < count; ++j)
            if (T <= 2 || j % 4 == 0) {
                taps.prefetch<T, W == Walk::Hartley, W == Walk::ComplexReflected>(index[buf][j]);
            }
    };
    prepare(0, m0);
    for (int first = m0, buf = 0; first <= m1; first += kChunk, buf ^= 1) {
        if (first + kChunk <= m1) prepare(buf ^ 1, first + kChunk);
        const int count = std::min(kChunk, m1 - first + 1);
        for (int j = 0; j < count; ++j) emit(first + j, index[buf][j], frac[buf][j]);
    }
}

/** What a fast row of the half slice needs besides the taps: k(m) = m a + b of one side
 *  (s k(m) - q P0 e_x = m (s A) + (s (n B) - q P0 e_x); for q = 0 exactly s k(m): negation is
 *  exact), and the model, filter and signs each column's value gets. */
struct ComplexRow {
    const FastTaps taps;
    double a[3], b[3];
    const float* transfer;
    const SliceFilterTable& filter;
    int n;
    bool conjugate;
    float scale;

    ComplexRow(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
               const SliceFilterTable& sliceFilter, const RowTransfer& model, int row, Side side)
        : taps(c, l), a{side.s * f.A[0], side.s * f.A[1], side.s * f.A[2]},
          b{side.s * (row * f.B[0]) - side.q * double(c.P0), side.s * (row * f.B[1]),
            side.s * (row * f.B[2])},
          transfer(c.model ? model.row.data() : nullptr), filter(sliceFilter), n(row),
          conjugate((side.s < 0) != side.reflect), scale(periodSign(c, side) * f.scale) {}

    /** sign_q: -1 for an odd number of periods along an antiperiodic x. */
    static float periodSign(const SliceContext& c, Side side) {
        return c.anti[0] && (side.q & 1) ? -1.0f : 1.0f;
    }

    /** sliceHalfComplex's value at column m from the sample at s k(m). */
    [[gnu::always_inline]] cfloat value(int m, cfloat v) const {
        if (conjugate) v = {v.real(), -v.imag()};
        if (transfer) v = {v.real() * transfer[m], v.imag() * transfer[m]};
        const float sign = ((n + m) & 1) ? -scale : scale;
        const float g = filter.on ? sign * filter(m, n) : sign;
        return {v.real() * g, v.imag() * g};
    }
};

/** Columns [m0, m1] of row n (fast columns of side s): sliceHalfComplex's values without the
 *  per-sample checks. */
template <int T>
void fastRowComplex(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
                    const SliceFilterTable& filter, const RowTransfer& model, int n, Side side,
                    int m0, int m1, cfloat* row) {
    const ComplexRow r(c, f, l, filter, model, n, side);
    auto walk = [&](auto reflect) {
        constexpr bool R = decltype(reflect)::value;
        walkColumns<T, R ? Walk::ComplexReflected : Walk::Complex>(
            r.taps, r.a, r.b, m0, m1, [&](int m, const std::int32_t* i, const auto* fr) {
                row[m] = r.value(m, r.taps.sample<T, R>(i, fr));
            });
    };
    if (side.reflect)
        walk(std::true_type{});
    else
        walk(std::false_type{});
}

// GCC on x86-64 (its target pragma; clang and other CPUs keep the baseline rows).
#if defined __x86_64__ && defined __GNUC__ && !defined __clang__
#define FVR_SLICE_AVX2 1
#pragma GCC push_options
#pragma GCC target("avx2,fma")
/** FastTaps::sample for 4 and 6 taps in x86-64-v3 code: a tap row's 4 complex values are one
 *  256-bit register (the 5th and 6th one 128-bit), summed with fused multiply-adds. Compiled for
 *  AVX2 and FMA here only (GCC's target pragma: no other code changes ISA) and run where the CPU
 *  has both (sliceAvx2). The same sums as FastTaps::sample, rounded once per multiply-add. */
template <int T, bool Reflect, class Frac>
inline cfloat sampleAvx2(const FastTaps& taps, const std::int32_t* i, const Frac* fr) {
    static_assert(T == 4 || T == 6);
    float wx[T], wy[T], wz[T];
    const std::int64_t bx = taps.tapsOf<T, Reflect>(i[0], fr[0], wx);
    const std::int64_t by = taps.tapsOf<T, Reflect>(i[1], fr[1], wy);
    const std::int64_t bz = taps.tapsOf<T, Reflect>(i[2], fr[2], wz);
    const std::int64_t *ry = taps.oy + by, *rz = taps.oz + bz;
    const float *ty = taps.sy + by, *tz = taps.sz + bz;
    const __m256 wlo = _mm256_setr_ps(wx[0], wx[0], wx[1], wx[1], wx[2], wx[2], wx[3], wx[3]);
    __m128 whi = _mm_setzero_ps();
    if constexpr (T == 6) whi = _mm_setr_ps(wx[4], wx[4], wx[5], wx[5]);
    const float* base = taps.data + 2 * bx;
    __m256 acc = _mm256_setzero_ps();
    __m128 accHi = _mm_setzero_ps();
    for (int zc = 0; zc < T; ++zc) {
        const float* plane = base + rz[zc];
        __m256 accZ = _mm256_setzero_ps();
        __m128 accZHi = _mm_setzero_ps();
        for (int yc = 0; yc < T; ++yc) {
            const float* row = plane + ry[yc];
            const float w = ty[yc] * wy[yc];
            accZ =
                _mm256_fmadd_ps(_mm256_mul_ps(_mm256_set1_ps(w), wlo), _mm256_loadu_ps(row), accZ);
            if constexpr (T == 6)
                accZHi =
                    _mm_fmadd_ps(_mm_mul_ps(_mm_set1_ps(w), whi), _mm_loadu_ps(row + 8), accZHi);
        }
        const float wzz = tz[zc] * wz[zc];
        acc = _mm256_fmadd_ps(_mm256_set1_ps(wzz), accZ, acc);
        if constexpr (T == 6) accHi = _mm_fmadd_ps(_mm_set1_ps(wzz), accZHi, accHi);
    }
    // (re, im) pairs: sum the four (six) complex lanes.
    __m128 sum = _mm_add_ps(_mm256_castps256_ps128(acc), _mm256_extractf128_ps(acc, 1));
    sum = _mm_add_ps(sum, accHi);
    sum = _mm_add_ps(sum, _mm_movehl_ps(sum, sum));
    return {_mm_cvtss_f32(sum), _mm_cvtss_f32(_mm_shuffle_ps(sum, sum, 1))};
}

/** fastRowComplex with sampleAvx2 (4 and 6 taps). */
template <int T>
void fastRowComplexAvx2(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
                        const SliceFilterTable& filter, const RowTransfer& model, int n, Side side,
                        int m0, int m1, cfloat* row) {
    const ComplexRow r(c, f, l, filter, model, n, side);
    auto walk = [&](auto reflect) {
        constexpr bool R = decltype(reflect)::value;
        walkColumns<T, R ? Walk::ComplexReflected : Walk::Complex>(
            r.taps, r.a, r.b, m0, m1, [&](int m, const std::int32_t* i, const double* fr) {
                row[m] = r.value(m, sampleAvx2<T, R>(r.taps, i, fr));
            });
    };
    if (side.reflect)
        walk(std::true_type{});
    else
        walk(std::false_type{});
}
#pragma GCC pop_options
#endif

/** Whether the CPU runs the slice's x86-64-v3 code (AVX2 and FMA), unless FVR_CPU_SIMD=baseline
 *  (read per frame: tests compare both). */
bool sliceAvx2() {
#ifdef FVR_SLICE_AVX2
    static const bool cpu = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    const char* env = std::getenv("FVR_CPU_SIMD");
    return cpu && !(env && std::string_view(env) == "baseline");
#else
    return false;
#endif
}

/** fastRowComplexAvx2 where it exists (4 and 6 taps on x86-64), fastRowComplex otherwise. */
template <int T>
void fastRowComplexWide(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
                        const SliceFilterTable& filter, const RowTransfer& model, int n, Side side,
                        int m0, int m1, cfloat* row) {
#ifdef FVR_SLICE_AVX2
    if constexpr (T == 4 || T == 6) {
        fastRowComplexAvx2<T>(c, f, l, filter, model, n, side, m0, m1, row);
        return;
    }
#endif
    fastRowComplex<T>(c, f, l, filter, model, n, side, m0, m1, row);
}

/** fastRowComplex with depth cueing: sampleComplex's a G + i E.grad G of the model's spectrum
 *  (the model's transfer function per sample, as RowTransfer::at). */
template <int T>
void fastRowComplexDepth(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
                         const SliceFilterTable& filter, const RowTransfer& model, int n, Side side,
                         int m0, int m1, cfloat* row) {
    const ComplexRow r(c, f, l, filter, model, n, side); // its taps, k(m) and signs
    const FastTaps& taps = r.taps;
    const double *a = r.a, *b = r.b;
    const float E[3] = {c.E[0], c.E[1], c.E[2]}, depthA = c.depthA;
    const bool modelled = c.model != nullptr, filtered = filter.on, conjugate = r.conjugate;
    const float scale = r.scale;
    walkColumns<T, Walk::Depth>(
        taps, a, b, m0, m1, [&](int m, const std::int32_t* i, const double* fr) {
            Sampled<cfloat> g = taps.depthSample<T>(i, fr, E);
            // G(k) = conj G(-k), and then grad G(k) = -conj grad G(-k).
            if (conjugate) g = {std::conj(g.v), -std::conj(g.dv)};
            if (modelled) {
                float t, gt;
                model.at<true>(m, n, m, t, gt);
                g.dv = t * g.dv + gt * g.v; // E.grad (T G)
                g.v *= t;
            }
            const cfloat v = {depthA * g.v.real() - g.dv.imag(), depthA * g.v.imag() + g.dv.real()};
            const float sign = ((n + m) & 1) ? -scale : scale;
            row[m] = v * (filtered ? sign * filter(m, n) : sign);
        });
}

/** Columns [m0, m1] of row n of the Hartley slice (signed m, all fast; stored at column m or
 *  m + M): sliceFullHartley's value, model and filter, without the per-sample checks. */
template <int T>
void fastRowHartley(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
                    const SliceFilterTable& filter, const RowTransfer& model, int M, int n, int m0,
                    int m1, float* row) {
    const FastTaps taps(c, l);
    const double b[3] = {n * f.B[0], n * f.B[1], n * f.B[2]};
    const float* transfer = c.model ? model.row.data() : nullptr;
    const bool filtered = filter.on;
    const float scale = f.scale;
    walkColumns<T, Walk::Hartley>(taps, f.A, b, m0, m1,
                                  [&](int m, const std::int32_t* i, const auto* fr) {
                                      const int col = m < 0 ? m + M : m;
                                      float v = taps.hartley<T>(i, fr);
                                      if (transfer) v = transfer[col] * v;
                                      const float sign = ((m + n) & 1) ? -scale : scale;
                                      row[col] = v * (filtered ? sign * filter(m, n) : sign);
                                  });
}

/** fastRowHartley with depth cueing: sampleHartley's a H_m(k) + E.grad H_m(-k), the value at k
 *  (linear's 2 taps for T = 3) and the derivative at -k = m (-A) + (-n B) from two walks of the
 *  same columns, chunk by chunk. */
template <int T>
void fastRowHartleyDepth(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
                         const SliceFilterTable& filter, const RowTransfer& model, int M, int n,
                         int m0, int m1, float* row) {
    constexpr int TV = T == 3 ? 2 : T; // the value's taps, as sampleHartley
    using FracV = std::conditional_t<TV <= 2, float, double>;
    constexpr int kChunk = 16;
    const FastTaps taps(c, l);
    const double b[3] = {n * f.B[0], n * f.B[1], n * f.B[2]};
    const float E[3] = {c.E[0], c.E[1], c.E[2]}, depthA = c.depthA;
    const bool modelled = c.model != nullptr, filtered = filter.on;
    const float scale = f.scale;
    // Two chunks' floors and fractions, alternating: the next chunk's are computed and its rows
    // prefetched before the sums of this one (as walkColumns).
    alignas(16) std::int32_t iv[2][3][kChunk + 1], im[2][3][kChunk + 1];
    alignas(16) FracV fv[2][3][kChunk + 1];
    alignas(16) double fm[2][3][kChunk + 1];
    auto prepare = [&](int buf, int first) {
        const int count = std::min(kChunk, m1 - first + 1);
        for (int a = 0; a < 3; ++a) {
            floorChunk<TV>(f.A[a], b[a], first, count, iv[buf][a], fv[buf][a]);
            floorChunk<T>(-f.A[a], -b[a], first, count, im[buf][a], fm[buf][a]);
        }
        for (int j = 0; j < count; ++j) {
            if (TV > 2 && j % 4 != 0) continue;
            const std::int32_t pv[3] = {iv[buf][0][j], iv[buf][1][j], iv[buf][2][j]};
            const std::int32_t pm[3] = {im[buf][0][j], im[buf][1][j], im[buf][2][j]};
            taps.prefetch<TV, true>(pv);
            taps.prefetch<T, true>(pm);
        }
    };
    prepare(0, m0);
    for (int first = m0, buf = 0; first <= m1; first += kChunk, buf ^= 1) {
        if (first + kChunk <= m1) prepare(buf ^ 1, first + kChunk);
        const int count = std::min(kChunk, m1 - first + 1);
        for (int j = 0; j < count; ++j) {
            const std::int32_t pv[3] = {iv[buf][0][j], iv[buf][1][j], iv[buf][2][j]};
            const FracV qv[3] = {fv[buf][0][j], fv[buf][1][j], fv[buf][2][j]};
            const std::int32_t pm[3] = {im[buf][0][j], im[buf][1][j], im[buf][2][j]};
            const double qm[3] = {fm[buf][0][j], fm[buf][1][j], fm[buf][2][j]};
            const int m = first + j, col = m < 0 ? m + M : m;
            const float h = taps.hartley<TV>(pv, qv);
            const Sampled<float> g = taps.hartleyDepth<T>(pm, qm, E); // H(-k), E.grad H(-k)
            float v;
            if (!modelled) {
                v = depthA * h + g.dv;
            } else {
                // T is even, grad T odd: E.grad (T H)(-k) = T(k) E.grad H(-k) - H(-k) E.grad T(k).
                float t, gt;
                model.at<true>(m, n, col, t, gt);
                v = depthA * t * h + t * g.dv - gt * g.v;
            }
            const float sign = ((m + n) & 1) ? -scale : scale;
            row[col] = v * (filtered ? sign * filter(m, n) : sign);
        }
    }
}

template <int T, bool Depth>
void sliceHalfComplex(const SliceContext& c, const FrameMapping& f, const SliceFilterTable& filter,
                      int M, cfloat* out, ThreadPool& pool) {
    const int H = M / 2 + 1;
    const FrameLookups& lookups = *c.lookups;
    const bool avx2 = (T == 4 || T == 6) && !Depth && sliceAvx2();
    // The periods along x the slice reaches (beyond the band: the compact voxel models), at most
    // the lookups' four.
    const int periods = int(std::min(
        4.0, std::ceil(((M / 2 + 1) * (std::abs(f.A[0]) + std::abs(f.B[0])) + T) / double(c.P0))));
    pool.parallelFor(M, 4, [&](std::int64_t r0, std::int64_t r1) {
        RowTransfer model(c, f, M);
        // Row n's fast spans, one per side (sign s, period q), in column order.
        std::vector<std::pair<Side, ColumnSpan>> spans;
        spans.reserve(std::size_t(4 * (periods + 1)));
        auto findSpans = [&](int n) {
            for (int q = 0; q <= periods; ++q)
                for (double s : {1.0, -1.0})
                    for (bool reflect : {false, true}) {
                        if (reflect && (q == 0 || Depth)) continue; // (depth cueing: not yet)
                        const Side side{s, q, reflect};
                        const ColumnSpan sp = fastColumns<T, Depth>(c, f, lookups, M, n, side);
                        if (sp.first() <= sp.last()) spans.push_back({side, sp});
                    }
            std::sort(spans.begin(), spans.end(), [](const auto& x, const auto& y) {
                return x.second.first() < y.second.first();
            });
        };
        auto sample = [&](double m, double n, int index) {
            return slicePoint<T, Depth, false>(c, f, model, m, n, index);
        };
        for (std::int64_t r = r0; r < r1; ++r) {
            const int n = int(r < M / 2 ? r : r - M);
            const bool nyqRow = (n == -M / 2);
            if (!Depth && !nyqRow) model.fill(0, 0, H, n);
            cfloat* row = out + r * H;
            auto general = [&](int m0, int m1) { // columns [m0, m1)
                for (int m = m0; m < m1; ++m) {
                    const float sign = ((n + m) & 1) ? -f.scale : f.scale;
                    cfloat v;
                    if (m == M / 2 || nyqRow) {
                        v = nyquistMean<cfloat>(sample, m, n, m == M / 2, nyqRow);
                    } else if (outOfBand(c, m * f.A[0] + n * f.B[0], m * f.A[1] + n * f.B[1],
                                         m * f.A[2] + n * f.B[2])) {
                        v = {}; // sampleComplex's value there, without the lookups
                    } else {
                        if (T <= 2 || m % 4 == 0) {
                            const double ma = m + kPrefetchAhead;
                            prefetchInterior<T>(c, ma * f.A[0] + n * f.B[0],
                                                ma * f.A[1] + n * f.B[1], ma * f.A[2] + n * f.B[2]);
                        }
                        v = sample(m, n, m);
                    }
                    row[m] = v * (filter.on ? sign * filter(m, n) : sign);
                }
            };
            int m = 0;
            spans.clear();
            if (!nyqRow) findSpans(n);
            for (const auto& [side, sp] : spans) {
                const int first = std::max(sp.first(), m);
                if (first > sp.last()) continue;
                general(m, first);
                if constexpr (Depth)
                    fastRowComplexDepth<T>(c, f, lookups, filter, model, n, side, first, sp.last(),
                                           row);
                else if (avx2)
                    fastRowComplexWide<T>(c, f, lookups, filter, model, n, side, first, sp.last(),
                                          row);
                else
                    fastRowComplex<T>(c, f, lookups, filter, model, n, side, first, sp.last(), row);
                m = sp.last() + 1;
            }
            general(m, H);
        }
    });
}

/** The fast columns among m = lo .. hi of row n of the Hartley slice: every tap inside the
 *  lookups, k inside the band. */
template <int T>
ColumnSpan hartleyColumns(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
                          int n, int lo, int hi) {
    ColumnSpan span(lo, hi);
    const double half[3] = {c.half0, c.half1, c.half2};
    const std::int64_t reach[3] = {l.x.reach(), l.y.reach(), l.z.reach()};
    for (int a = 0; a < 3; ++a) {
        const double lim = std::min(half[a], double(reach[a] - T - 2));
        span.require(n * f.B[a], f.A[a], -lim, lim);
    }
    return span;
}

template <int T, bool Depth>
void sliceFullHartley(const SliceContext& c, const FrameMapping& f, const SliceFilterTable& filter,
                      int M, float* out, ThreadPool& pool) {
    const FrameLookups& lookups = *c.lookups;
    pool.parallelFor(M, 4, [&](std::int64_t r0, std::int64_t r1) {
        RowTransfer model(c, f, M);
        auto sample = [&](double m, double n, int index) {
            return slicePoint<T, Depth, true>(c, f, model, m, n, index);
        };
        for (std::int64_t r = r0; r < r1; ++r) {
            const int n = int(r < M / 2 ? r : r - M);
            const bool nyqRow = (n == -M / 2);
            if (!Depth && !nyqRow) {
                model.fill(0, 0, M / 2, n); // columns 0 .. M/2-1: m = col
                model.fill(M / 2, -M / 2, M / 2, n); // columns M/2 .. M-1: m = col - M
            }
            float* row = out + r * M;
            auto general = [&](int col0, int col1) { // columns [col0, col1)
                for (int col = col0; col < col1; ++col) {
                    const int m = col < M / 2 ? col : col - M;
                    const float sign = (((m + n) & 1) ? -1.0f : 1.0f) * f.scale;
                    float v;
                    if (m == -M / 2 || nyqRow) {
                        v = nyquistMean<float>(sample, m, n, m == -M / 2, nyqRow);
                    } else if (outOfBand(c, m * f.A[0] + n * f.B[0], m * f.A[1] + n * f.B[1],
                                         m * f.A[2] + n * f.B[2])) {
                        v = 0.0f; // sampleHartley's value there, without the lookups
                    } else {
                        if constexpr (T <= 2) {
                            const double ma = m + kPrefetchAhead;
                            prefetchHartleyInterior<T>(c, ma * f.A[0] + n * f.B[0],
                                                       ma * f.A[1] + n * f.B[1],
                                                       ma * f.A[2] + n * f.B[2]);
                        }
                        v = sample(m, n, col);
                    }
                    row[col] = v * (filter.on ? sign * filter(m, n) : sign);
                }
            };
            int col = 0;
            {
                // m = 0 .. M/2-1 at columns m, m = -M/2+1 .. -1 at columns m + M (increasing).
                for (int part = 0; part < 2 && !nyqRow; ++part) {
                    const ColumnSpan sp = part == 0
                                              ? hartleyColumns<T>(c, f, lookups, n, 0, M / 2 - 1)
                                              : hartleyColumns<T>(c, f, lookups, n, -M / 2 + 1, -1);
                    if (sp.first() > sp.last()) continue;
                    const int offset = part == 0 ? 0 : M;
                    general(col, sp.first() + offset);
                    if constexpr (Depth)
                        fastRowHartleyDepth<T>(c, f, lookups, filter, model, M, n, sp.first(),
                                               sp.last(), row);
                    else
                        fastRowHartley<T>(c, f, lookups, filter, model, M, n, sp.first(), sp.last(),
                                          row);
                    col = sp.last() + offset + 1;
                }
            }
            general(col, M);
        }
    });
}

/** Calls f(taps, depth) with compile-time constants for the slice's tap count
 *  (SliceParams::taps: linear with depth cueing runs on 3 taps, the central difference on
 *  integer frequencies, axisDerivWeights). */
template <class F>
void dispatchTaps(int taps, bool depth, F&& f) {
    using std::integral_constant;
    using No = std::false_type;
    using Yes = std::true_type;
    if (!depth) {
        switch (taps) {
        case 1: return f(integral_constant<int, 1>{}, No{});
        case 2: return f(integral_constant<int, 2>{}, No{});
        case 6: return f(integral_constant<int, 6>{}, No{});
        default: return f(integral_constant<int, 4>{}, No{});
        }
    }
    switch (taps) {
    case 3: return f(integral_constant<int, 3>{}, Yes{});
    case 6: return f(integral_constant<int, 6>{}, Yes{});
    default: return f(integral_constant<int, 4>{}, Yes{});
    }
}

} // namespace

std::string CpuFourierRenderer::describe() const {
    return "CPU, " + std::to_string(m_threads) + (m_threads == 1 ? " thread" : " threads");
}

void validateRenderParams(const RenderParams& params) {
    validateImageGeometry(params.image);
    if (!(params.depthCue >= 0.0 && params.depthCue <= 1.0))
        throw SettingsError("depth cueing: strength must be in [0, 1], found " +
                            std::to_string(params.depthCue));
    if (params.depthCue > 0.0 && params.kernel == Kernel::Nearest)
        throw SettingsError(
            "depth cueing: needs the derivative of the interpolation kernel; nearest has none "
            "(choose linear or better)");
    validateSliceFilter(params.filter);
}

void checkFiniteImage(const ProjectionImage& image) {
    std::size_t bad = 0;
    for (const float p : image.pixels) bad += std::isfinite(p) ? 0 : 1;
    if (bad == 0) return;
    throw RenderError("rendered image: " + std::to_string(bad) + " of " +
                      std::to_string(image.pixels.size()) +
                      " pixels are not finite (NaN or infinite): the projection overflowed float "
                      "(voxel values or line integrals too large); nothing is output");
}

void validateRenderParams(const RenderParams& params, const Spectrum& spectrum) {
    validateImageGeometry(params.image, spectrum.volumeDims, spectrum.spacing);
    validateRenderParams(params);
}

namespace {

/** The per-sample context of one frame from its slice parameters. */
SliceContext makeSliceContext(const Spectrum& s, const SliceParams& sp, const KernelTable* table,
                              const TransferTable* model, const detail::CpuSliceLookups* lookups) {
    SliceContext c{};
    c.data = s.data.get();
    c.P0 = sp.padded[0];
    c.P1 = sp.padded[1];
    c.P2 = sp.padded[2];
    c.rs = s.rowStride();
    c.table = table;
    c.first = table->firstTapOffset();
    // The band edge with a tolerance for the slice's rounding (infinite half stays infinite).
    c.half0 = sp.half[0] + 1e-9;
    c.half1 = sp.half[1] + 1e-9;
    c.half2 = sp.half[2] + 1e-9;
    c.depthA = float(sp.depthA);
    for (int a = 0; a < 3; ++a) {
        c.anti[a] = sp.anti[a];
        c.invP[a] = sp.invP[a];
        c.E[a] = float(sp.E[a]);
    }
    c.model = model;
    c.lookups = lookups;
    return c;
}

FrameMapping frameMapping(const SliceParams& sp) {
    FrameMapping f{};
    for (int a = 0; a < 3; ++a) {
        f.A[a] = sp.A[a];
        f.B[a] = sp.B[a];
    }
    f.scale = float(sp.scale);
    return f;
}

ProjectionImage emptyImage(const RenderParams& params, const Spectrum& s) {
    ProjectionImage img;
    img.size = params.image.size;
    img.pixelSize = params.image.pixelSize;
    img.view = params.view;
    img.mapping = s.mapping;
    img.pixels.resize(std::size_t(img.size) * img.size);
    return img;
}

/** Samples the slice into `out`: the half complex slice (FFT, M x (M/2+1)) or the full
 *  Hartley slice (FHT, M x M), with the frame's tap count and depth cueing. */
void sampleSlice(const SliceContext& c, const FrameMapping& f, const SliceFilterTable& filter,
                 const SliceParams& sp, TransformKind kind, int M, float* out, ThreadPool& pool) {
    dispatchTaps(sp.taps, sp.depth, [&](auto taps, auto cued) {
        if (kind == TransformKind::Fft)
            sliceHalfComplex<taps(), cued()>(c, f, filter, M, reinterpret_cast<cfloat*>(out), pool);
        else
            sliceFullHartley<taps(), cued()>(c, f, filter, M, out, pool);
    });
}

} // namespace

const TransferTable* CpuFourierRenderer::transferTable(VoxelModel model, double maxCyclesPerVoxel) {
    if (model == VoxelModel::BandLimited) return nullptr;
    auto& table = m_transfer[model];
    if (!table) table = std::make_unique<TransferTable>(model);
    table->cover(maxCyclesPerVoxel);
    return table.get();
}

void CpuFourierRenderer::invertSlice(SizeResources& res, ProjectionImage& img) {
    detail::noteBusy();
    if (res.measured && res.measured->ready()) { // swap in the background planner's plan
        detail::Plan p = res.measured->take();
        res.measured.reset();
        if (p) {
            res.replaced = std::move(res.inverse);
            res.inverse = std::move(p);
        }
    }
    if (m_spectrum->kind == TransformKind::Fft) {
        fftwf_execute_dft_c2r(res.inverse.get(), reinterpret_cast<fftwf_complex*>(res.slice.get()),
                              res.image.get());
        std::memcpy(img.pixels.data(), res.image.get(), sizeof(float) * img.pixels.size());
    } else {
        fftwf_execute_dft_r2c(res.inverse.get(), res.slice.get(),
                              reinterpret_cast<fftwf_complex*>(res.image.get()));
        hartleyFromHalfSpectrum(res.image.get(), img.pixels.data(), img.size, m_pool);
    }
}

void CpuFourierRenderer::clipAndClamp(const RenderParams& params, ProjectionImage& img) {
    const Spectrum& s = *m_spectrum;
    const bool clamp = params.nonNegative && s.nonNegative;
    if (!params.clipToVolume && !clamp) return;
    const int M = img.size;
    const double d = img.pixelSize;
    const Vec3 half =
        supportHalfExtents(s.volumeDims, s.spacing, voxelModelReach(params.voxelModel));
    m_pool.parallelFor(M, 16, [&](std::int64_t r0, std::int64_t r1) {
        for (std::int64_t row = r0; row < r1; ++row) {
            float* p = img.pixels.data() + std::size_t(row) * M;
            ColumnRange hit{0, M - 1};
            if (params.clipToVolume) {
                hit = volumeShadowColumns(params.view, half, M, d, int(row));
                if (hit.first > hit.last) {
                    std::fill(p, p + M, 0.0f);
                    continue;
                }
                std::fill(p, p + hit.first, 0.0f);
                std::fill(p + hit.last + 1, p + M, 0.0f);
            }
            if (clamp)
                for (int col = hit.first; col <= hit.last; ++col) p[col] = std::max(p[col], 0.0f);
        }
    });
}

ProjectionImage CpuFourierRenderer::render(const RenderParams& params, StageTimes* times) {
    const PlannerBusyScope busy; // the background planner measures between frames, not during
    validateRenderParams(params, *m_spectrum);
    const auto t0 = Clock::now();
    const Spectrum& s = *m_spectrum;
    checkKernelMatchesSpectrum(s, params.kernel);
    const int M = params.image.size;
    SizeResources& res = resources(M);

    const SliceParams sp = sliceParams(s, params);
    const SliceContext c =
        makeSliceContext(s, sp, m_tables.at(params.kernel).get(),
                         transferTable(params.voxelModel, sp.maxCyclesPerVoxel), m_lookups.get());
    const SliceFilterTable filter(params.filter, params.pixelAperture, M, params.image.pixelSize);
    ProjectionImage img = emptyImage(params, s);

    sampleSlice(c, frameMapping(sp), filter, sp, s.kind, M, res.slice.get(), m_pool);
    const auto t1 = Clock::now();
    invertSlice(res, img);
    // The last pass: zero outside the model's support, and no negative line integrals of a
    // non-negative volume.
    clipAndClamp(params, img);
    const auto t2 = Clock::now();
    if (times) {
        auto ms = [](auto a, auto b) {
            return std::chrono::duration<double, std::milli>(b - a).count();
        };
        times->sliceMs = ms(t0, t1);
        times->inverseMs = ms(t1, t2);
        times->totalMs = ms(t0, t2);
    }
    checkFiniteImage(img);
    return img;
}

} // namespace fvr::core
