#pragma once

// Private to the CPU renderer: the fast row walk of the slice (columns whose taps need no
// per-sample checks), shared by the baseline rows (cpu_slice_rows.cpp) and the AVX2 rows
// (cpu_slice_rows_avx2.cpp).

#include <cstdint>
#include <type_traits>

#include "cpu_slice_internal.h"

#ifdef __x86_64__
#include <immintrin.h>
#endif

#include "cpu_simd.h"

#ifdef FVR_CPU_AVX2 // (cpu_simd.h: GCC on x86-64; clang and other CPUs keep the baseline rows)
#define FVR_SLICE_AVX2 1
#endif

namespace fvr::core::detail {

using FrameLookups = CpuSliceLookups;

// Internal linkage, as in one file: each translation unit inlines these as it sees fit.
namespace {

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

} // namespace

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

// Internal linkage, as in one file: each translation unit inlines these as it sees fit.
namespace {

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

} // namespace

#ifdef FVR_SLICE_AVX2
/** fastRowComplex with sampleAvx2 (4 and 6 taps; cpu_slice_rows_avx2.cpp). */
template <int T>
void fastRowComplexAvx2(const SliceContext& c, const FrameMapping& f, const FrameLookups& l,
                        const SliceFilterTable& filter, const RowTransfer& model, int n, Side side,
                        int m0, int m1, cfloat* row);
#endif

} // namespace fvr::core::detail
