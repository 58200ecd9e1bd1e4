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
    int span = 1;
    for (; span * 4 <= size; span *= 4) m_radices.push_back(4);
    if (span < size) m_radices.push_back(2);
    m_twiddles.resize(2 * std::size_t(size));
    for (int k = 0; k < size; ++k) {
        const double a = sign * 2.0 * std::numbers::pi * k / size;
        m_twiddles[2 * k] = float(std::cos(a));
        m_twiddles[2 * k + 1] = float(std::sin(a));
    }
}

namespace {
using cf = std::complex<float>;
// The shader's operations, in its order: complex products as (a.x b.x - a.y b.y, a.x b.y + a.y
// b.x).
cf cmul(cf a, cf b) {
    return {a.real() * b.real() - a.imag() * b.imag(), a.real() * b.imag() + a.imag() * b.real()};
}
} // namespace

void FftPlan::execute(std::vector<std::complex<float>>& data) const {
    if (int(data.size()) != m_size)
        throw std::invalid_argument("FFT data size does not match the plan");
    const int M = m_size;
    auto tw = [&](int k) {
        return cf(m_twiddles[2 * std::size_t(k)], m_twiddles[2 * std::size_t(k) + 1]);
    };
    const float s = float(m_sign); // sign * i multiplies as s * (-y, x)
    std::vector<cf> out(data.size());
    int Ns = 1;
    for (int R : m_radices) {
        const int q = M / R, stride = M / (Ns * R);
        for (int j = 0; j < q; ++j) {
            const int k = j % Ns;
            cf v[4];
            for (int r = 0; r < R; ++r)
                v[r] = r == 0 ? data[std::size_t(j)]
                              : cmul(data[std::size_t(j + r * q)], tw(k * r * stride));
            const int d = (j - k) * R + k;
            if (R == 4) {
                const cf t0 = v[0] + v[2], t1 = v[0] - v[2], t2 = v[1] + v[3];
                const cf u = v[1] - v[3];
                const cf t3(-s * u.imag(), s * u.real());
                out[std::size_t(d)] = t0 + t2;
                out[std::size_t(d + Ns)] = t1 + t3;
                out[std::size_t(d + 2 * Ns)] = t0 - t2;
                out[std::size_t(d + 3 * Ns)] = t1 - t3;
            } else {
                out[std::size_t(d)] = v[0] + v[1];
                out[std::size_t(d + Ns)] = v[0] - v[1];
            }
        }
        data.swap(out);
        Ns *= R;
    }
}

} // namespace fvr::gpu
