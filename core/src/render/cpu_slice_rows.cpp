#include <cstdlib>
#include <string_view>

#include "cpu_slice_fast.h"

namespace fvr::core::detail {

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

CpuSliceLookups::CpuSliceLookups(const Spectrum& s)
    : x(s.padded[0], s.volumeDims[0] % 2 == 0, 1,
        s.kind == TransformKind::Fht ? 4 * s.padded[0] + KernelTable::kMaxTaps + 2 : 0),
      y(s.padded[1], s.volumeDims[1] % 2 == 0, s.rowStride(),
        4 * s.padded[1] + KernelTable::kMaxTaps + 2),
      z(s.padded[2], s.volumeDims[2] % 2 == 0, s.rowStride() * s.padded[1],
        4 * s.padded[2] + KernelTable::kMaxTaps + 2) {}

namespace {

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

/** Whether the CPU runs the slice's x86-64-v3 code (AVX2 and FMA), unless FVR_CPU_SIMD=baseline
 *  (read per frame: tests compare both). */
bool sliceAvx2() { return cpuRunsAvx2(); }

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

} // namespace fvr::core::detail
