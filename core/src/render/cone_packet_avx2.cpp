// The box model's walk for four rays at once (cone_packet.h), in AVX2 and FMA code.
#include "cone_packet.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <string_view>

#ifdef FVR_CONE_AVX2
#include <immintrin.h>
#endif

namespace fvr::core::detail {

bool coneAvx2() { return cpuRunsAvx2(); }

#ifndef FVR_CONE_AVX2

bool boxPacketAvx2(const CellData&, const RayPacket&, double*) { return false; }
bool trilinearPacketAvx2(const CellData&, const RayPacket&, double*) { return false; }

#else

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/** How many slabs ahead each lane's next reads are prefetched (gathers train no hardware
 *  prefetcher; 24 measured best of 4 to 32 on a 512 x 512 x 140 CT, 2 Zen 4 cores). */
constexpr int kPrefetch = 24;

/** floor(q) as a cell index clamped to [0, n - 1]. */
std::int64_t clampedCell(double q, std::int64_t n) {
    return std::clamp(std::int64_t(std::floor(q)), std::int64_t(0), n - 1);
}

} // namespace

#pragma GCC push_options
#pragma GCC target("avx2,fma")

/** What a packet's walk starts from: the rays' common major axis m and direction s along it
 *  (w = s m grows along every ray), the slabs W to walk, and per lane its range [w0, w1] in
 *  w, its cells in the other axes a and b (as offsets and as numbers), the w where it leaves
 *  them, and its line a = cA + kA w, b = cB + kB w. */
struct PacketStart {
    bool empty = false;
    int m = 0;
    double s = 1.0;
    std::int64_t wFirst = 0, wLast = -1;
    __m256d w0, w1, nextA, nextB, deltaA, deltaB, kA, kB, cA, cB, cellA, cellB, signA, signB;
    __m256d strideA, strideB;
    __m256i offset, stepA, stepB;
    double adm[4] = {1, 1, 1, 1};
};

/** The major axis m and the direction s along it that the non-empty rays share (any: there
 *  is one); false where they differ. */
bool commonMajorAxis(const RayPacket& p, int& m, double& s, bool& any) {
    any = false;
    for (int r = 0; r < 4; ++r) {
        if (!(p.t1[r] > p.t0[r])) continue;
        const double ax = std::abs(p.dir[r][0]), ay = std::abs(p.dir[r][1]),
                     az = std::abs(p.dir[r][2]);
        const int mr = ax >= ay ? (ax >= az ? 0 : 2) : (ay >= az ? 1 : 2);
        const double sr = p.dir[r][mr] > 0.0 ? 1.0 : -1.0;
        if (any && (mr != m || sr != s)) return false;
        m = mr;
        s = sr;
        any = true;
    }
    return true;
}

/** False where the non-empty rays differ in major axis or direction along it. */
bool packetStart(const CellData& c, const RayPacket& p, PacketStart& st) {
    int m = 0;
    double s = 1.0;
    bool any = false;
    if (!commonMajorAxis(p, m, s, any)) return false;
    st.empty = !any;
    if (!any) return true;
    st.m = m;
    st.s = s;
    const int axes[2] = {m == 0 ? 1 : 0, m == 2 ? 1 : 2};
    // Empty lanes: a range of zero length where the others start, at cell (M, 0, 0).
    double w0[4], w1[4], next[2][4], delta[2][4], k[2][4], c0[2][4], cell[2][4], sign[2][4];
    long long offset[4], step[2][4];
    double wLo = kInf, wHi = -kInf;
    for (int r = 0; r < 4; ++r) {
        const bool live = p.t1[r] > p.t0[r];
        const double adm = live ? std::abs(p.dir[r][m]) : 1.0;
        st.adm[r] = adm;
        w0[r] = live ? s * (p.o[r][m] + p.t0[r] * p.dir[r][m]) : 0.0;
        w1[r] = live ? s * (p.o[r][m] + p.t1[r] * p.dir[r][m]) : 0.0;
        if (live) {
            wLo = std::min(wLo, w0[r]);
            wHi = std::max(wHi, w1[r]);
        }
        offset[r] = 0;
        for (int i = 0; i < 2; ++i) {
            const int a = axes[i];
            const double ka = live ? p.dir[r][a] / adm : 0.0; // per unit w
            const double pa = p.o[r][a] + p.t0[r] * p.dir[r][a];
            const std::int64_t ci = live ? clampedCell(pa, c.cells[a]) : 0;
            offset[r] += ci * c.stride[a];
            cell[i][r] = double(ci);
            k[i][r] = ka;
            // The line a(w) = o_a + dir_a t with t = (s w - o_m) / dir_m.
            c0[i][r] = live ? p.o[r][a] - ka * s * p.o[r][m] : 0.0;
            next[i][r] = kInf;
            delta[i][r] = 0.0;
            step[i][r] = 0;
            sign[i][r] = 0.0;
            if (ka != 0.0) {
                sign[i][r] = ka > 0.0 ? 1.0 : -1.0;
                step[i][r] = (ka > 0.0 ? 1 : -1) * c.stride[a];
                delta[i][r] = 1.0 / std::abs(ka);
                next[i][r] = w0[r] + std::max(0.0, (double(ci + (ka > 0.0 ? 1 : 0)) - pa) / ka);
            }
        }
    }
    for (int r = 0; r < 4; ++r)
        if (!(p.t1[r] > p.t0[r])) w0[r] = w1[r] = wLo;
    // The slabs W (w in [W, W + 1)) whose cell M = W (s > 0) or -W - 1 (s < 0) is in the grid.
    const std::int64_t n = c.cells[m];
    const std::int64_t wMin = s > 0 ? 0 : -n, wMax = s > 0 ? n - 1 : -1;
    st.wFirst = std::clamp(std::int64_t(std::floor(wLo)), wMin, wMax);
    st.wLast = std::clamp(std::int64_t(std::floor(wHi)), st.wFirst, wMax);
    st.w0 = _mm256_loadu_pd(w0);
    st.w1 = _mm256_loadu_pd(w1);
    st.nextA = _mm256_loadu_pd(next[0]);
    st.nextB = _mm256_loadu_pd(next[1]);
    st.deltaA = _mm256_loadu_pd(delta[0]);
    st.deltaB = _mm256_loadu_pd(delta[1]);
    st.kA = _mm256_loadu_pd(k[0]);
    st.kB = _mm256_loadu_pd(k[1]);
    st.cA = _mm256_loadu_pd(c0[0]);
    st.cB = _mm256_loadu_pd(c0[1]);
    st.cellA = _mm256_loadu_pd(cell[0]);
    st.cellB = _mm256_loadu_pd(cell[1]);
    st.signA = _mm256_loadu_pd(sign[0]);
    st.signB = _mm256_loadu_pd(sign[1]);
    st.strideA = _mm256_set1_pd(double(c.stride[axes[0]]));
    st.strideB = _mm256_set1_pd(double(c.stride[axes[1]]));
    st.offset = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(offset));
    st.stepA = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(step[0]));
    st.stepB = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(step[1]));
    return true;
}

/** Gathers train no hardware prefetcher: each lane's cell kPrefetch slabs ahead of slab W (at
 *  the ray's position there, from its line) is fetched, and the one `extra` further (0: none).
 *  An address only: a prefetch outside the array reads nothing and never faults. */
inline void prefetchAhead(const PacketStart& st, __m256d W, const float* base, std::int64_t mStep,
                          std::int64_t extra) {
    const __m256d wp = _mm256_add_pd(W, _mm256_set1_pd(kPrefetch + 0.5));
    const __m256d fa = _mm256_floor_pd(_mm256_fmadd_pd(st.kA, wp, st.cA));
    const __m256d fb = _mm256_floor_pd(_mm256_fmadd_pd(st.kB, wp, st.cB));
    const __m128i off =
        _mm256_cvttpd_epi32(_mm256_fmadd_pd(fa, st.strideA, _mm256_mul_pd(fb, st.strideB)));
    alignas(16) int ia[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(ia), off);
    const std::uintptr_t ahead =
        reinterpret_cast<std::uintptr_t>(base) + std::uintptr_t(kPrefetch * mStep * 4);
    for (int r = 0; r < 4; ++r) {
        const std::uintptr_t at = ahead + std::uintptr_t(std::int64_t(ia[r]) * 4);
        _mm_prefetch(reinterpret_cast<const char*>(at), _MM_HINT_T0);
        if (extra != 0)
            _mm_prefetch(reinterpret_cast<const char*>(at + std::uintptr_t(extra * 4)),
                         _MM_HINT_T0);
    }
}

/** The walk by slabs along the rays' common major axis m (the largest |dir| component): the
 *  planes m = integer are the same for every ray, so one slab (cell M in m) is one step for
 *  all four, with no branch on the data (where Amanatides and Woo's walk of one ray branches
 *  three ways per cell); per lane the ray's part of it, [max(W, w0), min(W + 1, w1)], crosses
 *  at most one boundary in each other axis (a and b: their slopes per unit m are at most 1),
 *  found by comparing where the ray leaves its cell in a and b with the slab's end, so the
 *  slab holds at most three pieces, in cells (M, a, b), then (M, a', b) or (M, a, b'), then
 *  (M, a', b'). Lanes outside their range have pieces of zero length (their reads stay inside
 *  the grid: M within it, their a and b cells where they enter or leave). The pieces' values
 *  are gathered, their lengths summed by fused multiply-adds in double. */
bool boxPacketAvx2(const CellData& c, const RayPacket& p, double out[4]) {
    PacketStart st;
    if (!packetStart(c, p, st)) return false;
    if (st.empty) {
        for (int r = 0; r < 4; ++r) out[r] = 0.0;
        return true;
    }
    const int m = st.m;
    const std::int64_t mStep = st.s > 0 ? c.stride[m] : -c.stride[m];
    const float* base = c.v + (st.s > 0 ? st.wFirst : -st.wFirst - 1) * c.stride[m];
    __m256d nextA = st.nextA, nextB = st.nextB;
    __m256i iA = st.offset;
    __m256d sum = _mm256_setzero_pd();
    __m256d W = _mm256_set1_pd(double(st.wFirst));
    const __m256d one = _mm256_set1_pd(1.0);
    for (std::int64_t w = st.wFirst; w <= st.wLast; ++w) {
        // The lane's part of the slab; of zero length before its start and after its end,
        // where no crossing is taken either (next >= w0 before, >= w1 after).
        const __m256d hi = _mm256_min_pd(_mm256_add_pd(W, one), st.w1);
        const __m256d lo = _mm256_min_pd(_mm256_max_pd(W, st.w0), hi);
        const __m256d ca = _mm256_cmp_pd(nextA, hi, _CMP_LT_OQ);
        const __m256d cb = _mm256_cmp_pd(nextB, hi, _CMP_LT_OQ);
        const __m256d cy = _mm256_max_pd(_mm256_min_pd(nextA, hi), lo);
        const __m256d cz = _mm256_max_pd(_mm256_min_pd(nextB, hi), lo);
        const __m256d aFirst = _mm256_cmp_pd(cy, cz, _CMP_LT_OQ); // then ca holds too
        const __m256d u1 = _mm256_min_pd(cy, cz), u2 = _mm256_max_pd(cy, cz);
        const __m256i mA = _mm256_castpd_si256(ca), mB = _mm256_castpd_si256(cb),
                      mF = _mm256_castpd_si256(aFirst);
        const __m256i dA = _mm256_and_si256(st.stepA, mA), dB = _mm256_and_si256(st.stepB, mB);
        const __m256i iD = _mm256_add_epi64(iA, _mm256_add_epi64(dA, dB));
        const __m256i iM = _mm256_add_epi64(
            iA, _mm256_add_epi64(_mm256_and_si256(st.stepA, mF), _mm256_andnot_si256(mF, dB)));
        const __m256d vA = _mm256_cvtps_pd(_mm256_i64gather_ps(base, iA, 4));
        const __m256d vM = _mm256_cvtps_pd(_mm256_i64gather_ps(base, iM, 4));
        const __m256d vD = _mm256_cvtps_pd(_mm256_i64gather_ps(base, iD, 4));
        sum = _mm256_fmadd_pd(_mm256_sub_pd(u1, lo), vA, sum);
        sum = _mm256_fmadd_pd(_mm256_sub_pd(u2, u1), vM, sum);
        sum = _mm256_fmadd_pd(_mm256_sub_pd(hi, u2), vD, sum);
        nextA = _mm256_add_pd(nextA, _mm256_and_pd(st.deltaA, ca));
        nextB = _mm256_add_pd(nextB, _mm256_and_pd(st.deltaB, cb));
        iA = iD;
        prefetchAhead(st, W, base, mStep, 0);
        W = _mm256_add_pd(W, one);
        base += mStep;
    }
    alignas(32) double sums[4];
    _mm256_store_pd(sums, sum);
    for (int r = 0; r < 4; ++r) out[r] = p.t1[r] > p.t0[r] ? sums[r] / st.adm[r] : 0.0;
    return true;
}

namespace {

/** The four corners' pairs (x = 0, x = 1) gathered as 64-bit words, split into the x = 0 and
 *  x = 1 values of the four lanes, in double. */
inline void gatherPairs(const float* base, __m256i idx, __m256d& x0, __m256d& x1) {
    const __m256d g = _mm256_i64gather_pd(reinterpret_cast<const double*>(base), idx, 4);
    const __m256 f =
        _mm256_permutevar8x32_ps(_mm256_castpd_ps(g), _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7));
    x0 = _mm256_cvtps_pd(_mm256_castps256_ps128(f));
    x1 = _mm256_cvtps_pd(_mm256_extractf128_ps(f, 1));
}

/** The trilinear interpolant's integral over one piece per lane: in the cell whose corner
 *  (0, 0, 0) is at offset idx, from w = u0 over a length L, the ray's local coordinates at w
 *  being (lm, la, lb) = (s w - M, cA + kA w - ya, cB + kB w - zb) in axes (m, a, b). Two-point
 *  Gauss-Legendre: exact, the interpolant being a cubic along the ray within the cell. */
template <int Major>
inline __m256d trilinearPiece(const float* base, __m256i idx, std::int64_t sy, std::int64_t sz,
                              __m256d u0, __m256d L, double s, double M, __m256d cA, __m256d kA,
                              __m256d ya, __m256d cB, __m256d kB, __m256d zb) {
    __m256d r0, r1, r2, r3, q0, q1, q2, q3; // rows (y, z) = (0, 0), (1, 0), (0, 1), (1, 1)
    gatherPairs(base, idx, r0, q0);
    gatherPairs(base, _mm256_add_epi64(idx, _mm256_set1_epi64x(sy)), r1, q1);
    gatherPairs(base, _mm256_add_epi64(idx, _mm256_set1_epi64x(sz)), r2, q2);
    gatherPairs(base, _mm256_add_epi64(idx, _mm256_set1_epi64x(sy + sz)), r3, q3);
    q0 = _mm256_sub_pd(q0, r0);
    q1 = _mm256_sub_pd(q1, r1);
    q2 = _mm256_sub_pd(q2, r2);
    q3 = _mm256_sub_pd(q3, r3);
    constexpr double g = 0.28867513459481288225; // 1 / (2 sqrt 3)
    auto at = [&](__m256d w) {
        const __m256d lm = _mm256_sub_pd(_mm256_mul_pd(_mm256_set1_pd(s), w), _mm256_set1_pd(M));
        const __m256d la = _mm256_sub_pd(_mm256_fmadd_pd(kA, w, cA), ya);
        const __m256d lb = _mm256_sub_pd(_mm256_fmadd_pd(kB, w, cB), zb);
        const __m256d lx = Major == 0 ? lm : la;
        const __m256d ly = Major == 0 ? la : Major == 1 ? lm : lb;
        const __m256d lz = Major == 2 ? lm : lb;
        const __m256d e0 = _mm256_fmadd_pd(lx, q0, r0), e1 = _mm256_fmadd_pd(lx, q1, r1);
        const __m256d e2 = _mm256_fmadd_pd(lx, q2, r2), e3 = _mm256_fmadd_pd(lx, q3, r3);
        const __m256d z0 = _mm256_fmadd_pd(ly, _mm256_sub_pd(e1, e0), e0);
        const __m256d z1 = _mm256_fmadd_pd(ly, _mm256_sub_pd(e3, e2), e2);
        return _mm256_fmadd_pd(lz, _mm256_sub_pd(z1, z0), z0);
    };
    const __m256d mid = _mm256_fmadd_pd(L, _mm256_set1_pd(0.5), u0);
    const __m256d h = _mm256_mul_pd(L, _mm256_set1_pd(g));
    const __m256d f = _mm256_add_pd(at(_mm256_sub_pd(mid, h)), at(_mm256_add_pd(mid, h)));
    return _mm256_mul_pd(_mm256_mul_pd(L, _mm256_set1_pd(0.5)), f);
}

} // namespace

/** The trilinear model's walk: boxPacketAvx2's slabs, each piece's integral by trilinearPiece
 *  (its 8 corners gathered as four pairs adjacent in x). */
template <int Major>
bool trilinearPacket(const CellData& c, const RayPacket& p, const PacketStart& st, double out[4]) {
    constexpr int A = Major == 0 ? 1 : 0, B = Major == 2 ? 1 : 2;
    const std::int64_t sy = c.stride[1], sz = c.stride[2];
    const double s = st.s;
    const std::int64_t mStep = s > 0 ? c.stride[Major] : -c.stride[Major];
    const float* base = c.v + (s > 0 ? st.wFirst : -st.wFirst - 1) * c.stride[Major];
    double M = double(s > 0 ? st.wFirst : -st.wFirst - 1);
    __m256d nextA = st.nextA, nextB = st.nextB;
    __m256i iA = st.offset;
    __m256d ya = st.cellA, zb = st.cellB;
    __m256d sum = _mm256_setzero_pd();
    __m256d W = _mm256_set1_pd(double(st.wFirst));
    const __m256d one = _mm256_set1_pd(1.0);
    (void)A;
    (void)B;
    for (std::int64_t w = st.wFirst; w <= st.wLast; ++w) {
        const __m256d hi = _mm256_min_pd(_mm256_add_pd(W, one), st.w1);
        const __m256d lo = _mm256_min_pd(_mm256_max_pd(W, st.w0), hi);
        const __m256d ca = _mm256_cmp_pd(nextA, hi, _CMP_LT_OQ);
        const __m256d cb = _mm256_cmp_pd(nextB, hi, _CMP_LT_OQ);
        const __m256d cy = _mm256_max_pd(_mm256_min_pd(nextA, hi), lo);
        const __m256d cz = _mm256_max_pd(_mm256_min_pd(nextB, hi), lo);
        const __m256d aFirst = _mm256_cmp_pd(cy, cz, _CMP_LT_OQ);
        const __m256d u1 = _mm256_min_pd(cy, cz), u2 = _mm256_max_pd(cy, cz);
        const __m256i mA = _mm256_castpd_si256(ca), mB = _mm256_castpd_si256(cb),
                      mF = _mm256_castpd_si256(aFirst);
        const __m256i dA = _mm256_and_si256(st.stepA, mA), dB = _mm256_and_si256(st.stepB, mB);
        const __m256i iD = _mm256_add_epi64(iA, _mm256_add_epi64(dA, dB));
        const __m256i iM = _mm256_add_epi64(
            iA, _mm256_add_epi64(_mm256_and_si256(st.stepA, mF), _mm256_andnot_si256(mF, dB)));
        const __m256d yD = _mm256_add_pd(ya, _mm256_and_pd(st.signA, ca));
        const __m256d zD = _mm256_add_pd(zb, _mm256_and_pd(st.signB, cb));
        const __m256d yM = _mm256_add_pd(ya, _mm256_and_pd(st.signA, aFirst));
        const __m256d zM = _mm256_add_pd(zb, _mm256_andnot_pd(aFirst, _mm256_and_pd(st.signB, cb)));
        sum = _mm256_add_pd(sum, trilinearPiece<Major>(base, iA, sy, sz, lo, _mm256_sub_pd(u1, lo),
                                                       s, M, st.cA, st.kA, ya, st.cB, st.kB, zb));
        // The middle and last pieces only where some lane has one (a branch: half the time
        // neither; the first piece is almost always there).
        const __m256d lM = _mm256_sub_pd(u2, u1), lD = _mm256_sub_pd(hi, u2);
        const __m256d zero = _mm256_setzero_pd();
        if (_mm256_movemask_pd(_mm256_cmp_pd(lM, zero, _CMP_GT_OQ)) != 0)
            sum = _mm256_add_pd(sum, trilinearPiece<Major>(base, iM, sy, sz, u1, lM, s, M, st.cA,
                                                           st.kA, yM, st.cB, st.kB, zM));
        if (_mm256_movemask_pd(_mm256_cmp_pd(lD, zero, _CMP_GT_OQ)) != 0)
            sum = _mm256_add_pd(sum, trilinearPiece<Major>(base, iD, sy, sz, u2, lD, s, M, st.cA,
                                                           st.kA, yD, st.cB, st.kB, zD));
        nextA = _mm256_add_pd(nextA, _mm256_and_pd(st.deltaA, ca));
        nextB = _mm256_add_pd(nextB, _mm256_and_pd(st.deltaB, cb));
        iA = iD;
        ya = yD;
        zb = zD;
        prefetchAhead(st, W, base, mStep, sz + sy);
        W = _mm256_add_pd(W, one);
        base += mStep;
        M += s;
    }
    alignas(32) double sums[4];
    _mm256_store_pd(sums, sum);
    for (int r = 0; r < 4; ++r) out[r] = p.t1[r] > p.t0[r] ? sums[r] / st.adm[r] : 0.0;
    return true;
}

bool trilinearPacketAvx2(const CellData& c, const RayPacket& p, double out[4]) {
    PacketStart st;
    if (!packetStart(c, p, st)) return false;
    if (st.empty) {
        for (int r = 0; r < 4; ++r) out[r] = 0.0;
        return true;
    }
    switch (st.m) {
    case 0: return trilinearPacket<0>(c, p, st, out);
    case 1: return trilinearPacket<1>(c, p, st, out);
    default: return trilinearPacket<2>(c, p, st, out);
    }
}

#pragma GCC pop_options

#endif

} // namespace fvr::core::detail
