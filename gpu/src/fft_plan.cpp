#include <fvr/gpu/fft_plan.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace fvr::gpu {

FftPlan::FftPlan(int size, int sign) : m_size(size), m_log2(0), m_sign(sign) {
    if (size < 2 || size > 4096 || (size & (size - 1)) != 0)
        throw std::invalid_argument("FFT size: expected a power of two in 2..4096, found " +
                                    std::to_string(size));
    if (sign != 1 && sign != -1) throw std::invalid_argument("FFT sign: expected +1 or -1");
    while ((1 << m_log2) < size) ++m_log2;
    m_twiddles.resize(std::size_t(size));
    for (int k = 0; k < size / 2; ++k) {
        const double a = sign * 2.0 * std::numbers::pi * k / size;
        m_twiddles[2 * k] = float(std::cos(a));
        m_twiddles[2 * k + 1] = float(std::sin(a));
    }
}

int FftPlan::bitReverse(int i) const {
    int r = 0;
    for (int b = 0; b < m_log2; ++b) r |= ((i >> b) & 1) << (m_log2 - 1 - b);
    return r;
}

void FftPlan::execute(std::vector<std::complex<float>>& data) const {
    if (int(data.size()) != m_size) throw std::invalid_argument("FFT data size does not match the plan");
    std::vector<std::complex<float>> x(data.size());
    for (int i = 0; i < m_size; ++i) x[bitReverse(i)] = data[i];
    for (int h = 1; h < m_size; h <<= 1) {
        const int stride = m_size / (2 * h);
        for (int j = 0; j < m_size / 2; ++j) {
            const int pos = j % h;
            const int i0 = (j / h) * 2 * h + pos;
            const int i1 = i0 + h;
            const std::complex<float> w(m_twiddles[2 * pos * stride], m_twiddles[2 * pos * stride + 1]);
            // Same operation order as the shader: b * w as (b.x w.x - b.y w.y, b.x w.y + b.y w.x).
            const std::complex<float> b(x[i1].real() * w.real() - x[i1].imag() * w.imag(),
                                        x[i1].real() * w.imag() + x[i1].imag() * w.real());
            const std::complex<float> a = x[i0];
            x[i0] = a + b;
            x[i1] = a - b;
        }
    }
    data = std::move(x);
}

} // namespace fvr::gpu
