#include "cpu_slice_fast.h"

#ifdef FVR_SLICE_AVX2

namespace fvr::core::detail {

#pragma GCC push_options
#pragma GCC target("avx2,fma")
namespace {

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
} // namespace

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

template void fastRowComplexAvx2<4>(const SliceContext&, const FrameMapping&, const FrameLookups&,
                                    const SliceFilterTable&, const RowTransfer&, int, Side, int,
                                    int, cfloat*);
template void fastRowComplexAvx2<6>(const SliceContext&, const FrameMapping&, const FrameLookups&,
                                    const SliceFilterTable&, const RowTransfer&, int, Side, int,
                                    int, cfloat*);

} // namespace fvr::core::detail

#endif
