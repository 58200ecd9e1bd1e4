#pragma once

// Private to the CPU renderer (cpu_renderer.cpp, cpu_slice_rows*.cpp): the per-frame slice
// context and the per-sample interpolation of the spectrum. Templates and small hot functions
// stay here, inline, so that the row walks inline them per sample.

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/slice_params.h>

namespace fvr::core::detail {

using cfloat = std::complex<float>;

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

/** The lookups of the renderer's spectrum, out to four periods and the widest kernel's taps
 *  beyond them (samples further out take the general path): x for the Hartley spectrum only
 *  (the half spectrum's x is read directly), y and z for both. They depend on the spectrum
 *  alone, so every frame shares them. */
struct CpuSliceLookups {
    AxisLookup x, y, z;
    explicit CpuSliceLookups(const Spectrum& s);
};

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
    const CpuSliceLookups* lookups = nullptr;
};

/** k(m, n) = m * A + n * B in spectrum index units, m and n signed image frequencies. */
struct FrameMapping {
    double A[3], B[3];
    float scale;
};

// Internal linkage, as in one file: each translation unit inlines these as it sees fit.
namespace {

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

} // namespace

/** The voxel model's transfer function T(k) = prod_a t(k_a / P_a) and, with Depth, E.grad T.
 *  Outside the unnamed namespace: RowTransfer, shared by the translation units, calls it. */
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

// Internal linkage, as in one file (above).
namespace {

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

} // namespace

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

// Internal linkage, as in one file: each translation unit inlines these as it sees fit.
namespace {

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

} // namespace

/** Samples the slice into `out`: the half complex slice (FFT, M x (M/2+1)) or the full
 *  Hartley slice (FHT, M x M), with the frame's tap count and depth cueing. */
void sampleSlice(const SliceContext& c, const FrameMapping& f, const SliceFilterTable& filter,
                 const SliceParams& sp, TransformKind kind, int M, float* out, ThreadPool& pool);

} // namespace fvr::core::detail
