#pragma once
// The one check of the CPU's x86-64-v3 code paths (the slice rows' and the cone-beam packets'):
// GCC on x86-64 compiles them (its target pragma; clang and other CPUs keep the baseline code),
// and a CPU with AVX2 and FMA runs them unless FVR_CPU_SIMD=baseline.
#include <cstdlib>
#include <string_view>

#if defined __x86_64__ && defined __GNUC__ && !defined __clang__
#define FVR_CPU_AVX2 1
#endif

namespace fvr::core::detail {

/** Whether the AVX2 and FMA code runs: compiled in, the CPU has both, and FVR_CPU_SIMD is not
 *  "baseline" (read per call: tests compare both paths in one process). */
inline bool cpuRunsAvx2() {
#ifdef FVR_CPU_AVX2
    static const bool cpu = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    const char* env = std::getenv("FVR_CPU_SIMD");
    return cpu && !(env && std::string_view(env) == "baseline");
#else
    return false;
#endif
}

} // namespace fvr::core::detail
