#pragma once
/** Planning of the GPU inverse FFT, apart from dispatch (as VkFFT separates plan management from
 *  execution): radix steps and twiddle tables computed in double on the CPU, validated at
 *  creation, and a CPU execution of exactly the algorithm the shaders run, so the plan is
 *  testable against FFTW without GL. */
#include <complex>
#include <vector>

namespace fvr::gpu {

/**
 * 1D complex FFT of size M (power of two, 2..4096) as the compute shaders run it in shared
 * memory: a Stockham autosort FFT (natural order in and out, no bit reversal), radix-4 stages
 * while they divide M and one radix-2 stage for odd log2 M (M = 512: 4, 4, 4, 4, 2), after
 * Govindaraju et al. 2008. Stage with span Ns (the product of the earlier radices) and radix R
 * takes butterfly j's inputs x[j + r M/R] times the twiddle table[(j mod Ns) r M/(Ns R)], runs
 * the R-point DFT in registers and writes output r to (j div Ns) Ns R + (j mod Ns) + r Ns.
 * table[k] = exp(sign 2 pi i k / M), k < M. Every thread reads its inputs before a barrier and
 * writes after it, so one shared array suffices (32 KiB at M = 4096).
 */
class FftPlan {
public:
    /** sign = +1: inverse (unnormalised, FFTW_BACKWARD); -1: forward. Throws std::invalid_argument.
     */
    FftPlan(int size, int sign);

    int size() const { return m_size; }
    int log2Size() const { return m_log2; }
    int sign() const { return m_sign; }
    /** The radix of every stage, first to last (4s, then a 2 when log2 M is odd). */
    const std::vector<int>& radices() const { return m_radices; }
    /** Twiddles as interleaved (re, im) floats, M entries, computed in double. */
    const std::vector<float>& twiddles() const { return m_twiddles; }

    /** Runs the shader algorithm on the CPU in float (reference for the shaders' arithmetic). */
    void execute(std::vector<std::complex<float>>& data) const;

private:
    int m_size;
    int m_log2;
    int m_sign;
    std::vector<int> m_radices;
    std::vector<float> m_twiddles;
};

} // namespace fvr::gpu
