#pragma once
/** Planning of the GPU inverse FFT, apart from dispatch (as VkFFT separates plan management from
 *  execution): radix steps and twiddle tables computed in double on the CPU, validated at
 *  creation, and a CPU execution of exactly the algorithm the shaders run, so the plan is
 *  testable against FFTW without GL. */
#include <complex>
#include <vector>

namespace fvr::gpu {

/**
 * 1D complex FFT of size M (power of two, 2..4096) as the compute shaders run it: inputs loaded
 * in bit-reversed order into shared memory, then log2(M) in-place radix-2 butterfly stages
 * (Cooley-Tukey, decimation in time). Stage s pairs elements h = 2^s apart with twiddle
 * table[pos * (M / 2h)], table[k] = exp(sign * 2 pi i k / M), k < M/2.
 */
class FftPlan {
public:
    /** sign = +1: inverse (unnormalised, FFTW_BACKWARD); -1: forward. Throws std::invalid_argument. */
    FftPlan(int size, int sign);

    int size() const { return m_size; }
    int log2Size() const { return m_log2; }
    int sign() const { return m_sign; }
    /** Twiddles as interleaved (re, im) floats, M/2 entries, computed in double. */
    const std::vector<float>& twiddles() const { return m_twiddles; }
    /** Bit reversal of i over log2Size() bits. */
    int bitReverse(int i) const;

    /** Runs the shader algorithm on the CPU in float (reference for the shaders' arithmetic). */
    void execute(std::vector<std::complex<float>>& data) const;

private:
    int m_size;
    int m_log2;
    int m_sign;
    std::vector<float> m_twiddles;
};

} // namespace fvr::gpu
