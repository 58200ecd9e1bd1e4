#pragma once

// Private to the cone-beam ray caster (cone_projector.cpp): the exact models' walk (box and
// trilinear) for four rays at once in x86-64-v3 code (cone_packet_avx2.cpp), run where the CPU
// has AVX2 and FMA.

#include <cstdint>

#include "cpu_simd.h"

#ifdef FVR_CPU_AVX2 // (cpu_simd.h: GCC on x86-64; clang and other CPUs keep the scalar walk)
#define FVR_CONE_AVX2 1
#endif

namespace fvr::core::detail {

/** A grid of cells [0, cells) per axis: the box model's cell (x, y, z) holds v[x + y sy + z sz];
 *  the trilinear model's cell has its corner (0, 0, 0) there and the others +1 in each axis.
 *  At least one cell of zeros (corners too) lies on every side (a rounding step across the
 *  edge lands there). */
struct CellData {
    const float* v = nullptr;
    std::int64_t stride[3] = {1, 0, 0};
    std::int64_t cells[3] = {0, 0, 0};
};

/** Four rays o + t dir in the cells' coordinates (cell c spans [c, c + 1)), each clipped to
 *  [t0, t1] inside the grid (t1 <= t0: the ray is empty). */
struct RayPacket {
    double o[4][3];
    double dir[4][3];
    double t0[4], t1[4];
};

/** Whether the CPU runs the AVX2 walk (and FVR_CPU_SIMD is not "baseline"; read per call:
 *  tests compare both). */
bool coneAvx2();

/** The box model's integrals (sum of path length x value, t units) of the four rays of p into
 *  out, when every non-empty ray has the same major axis and direction along it; false (out
 *  untouched) otherwise, for the scalar walk. */
bool boxPacketAvx2(const CellData& c, const RayPacket& p, double out[4]);

/** The trilinear model's exact integrals of the four rays (t units), as boxPacketAvx2. */
bool trilinearPacketAvx2(const CellData& c, const RayPacket& p, double out[4]);

} // namespace fvr::core::detail
