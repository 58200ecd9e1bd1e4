#include <fvr/core/render/preprocess.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>
#include <vector>

#include <fvr/core/errors.h>
#include <fvr/core/memory_budget.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/xray/xray.h>

#include "fftw_support.h"

namespace fvr::core {

using detail::Plan;

// ---------------------------------------------------------------------------------------------
// Spectrum helpers

void FftwFree::operator()(float* p) const { fftwf_free(p); }

FftwBuffer allocateFftw(std::size_t floats) {
    auto* p = static_cast<float*>(fftwf_malloc(floats * sizeof(float)));
    if (!p) throw std::bad_alloc();
    return FftwBuffer(p);
}

const char* valueMappingName(ValueMapping m) {
    switch (m) {
    case ValueMapping::Raw: return "raw";
    case ValueMapping::Mu: return "mu";
    case ValueMapping::MuBone: return "mu-bone";
    }
    return "?";
}
ValueMapping parseValueMapping(const std::string& s) {
    if (s == "raw") return ValueMapping::Raw;
    if (s == "mu") return ValueMapping::Mu;
    if (s == "mu-bone") return ValueMapping::MuBone;
    throw SettingsError("values: expected raw|mu|mu-bone, found '" + s + "'");
}
const char* transformName(TransformKind t) { return t == TransformKind::Fht ? "fht" : "fft"; }
TransformKind parseTransform(const std::string& s) {
    if (s == "fft") return TransformKind::Fft;
    if (s == "fht") return TransformKind::Fht;
    throw SettingsError("transform: expected fft|fht, found '" + s + "'");
}

namespace {
std::int64_t wrap(std::int64_t k, std::int64_t p) {
    k %= p;
    return k < 0 ? k + p : k;
}

/** The signed index in (-P/2, P/2] that stores frequency k, and the parity of the periods between
 *  them: the spectrum changes sign from one period to the next along an axis of an even voxel
 *  count (its centre lies half-way between two voxels). */
std::int64_t signedIndex(std::int64_t k, std::int64_t p, bool& oddPeriods) {
    std::int64_t r = wrap(k, p);
    if (r > p / 2) r -= p;
    oddPeriods = ((k - r) / p) % 2 != 0;
    return r;
}
} // namespace

std::complex<double> Spectrum::valueAt(std::int64_t kx, std::int64_t ky, std::int64_t kz) const {
    if (kind == TransformKind::Fht) {
        // G = E - i O with E, O the even and odd parts of H.
        const double h = hartleyAt(kx, ky, kz);
        const double hm = hartleyAt(-kx, -ky, -kz);
        return {0.5 * (h + hm), -0.5 * (h - hm)};
    }
    std::int64_t r[3];
    double sign = 1.0;
    const std::int64_t k[3] = {kx, ky, kz};
    for (int a = 0; a < 3; ++a) {
        bool odd;
        r[a] = signedIndex(k[a], padded[a], odd);
        if (odd && volumeDims[a] % 2 == 0) sign = -sign;
    }
    bool conj = false;
    if (r[0] < 0) { // G(k) = conj G(-k); -P/2 is stored as +P/2, one period away
        conj = true;
        for (int a = 0; a < 3; ++a) {
            r[a] = -r[a];
            if (padded[a] % 2 == 0 && r[a] == -padded[a] / 2) {
                r[a] = padded[a] / 2;
                if (volumeDims[a] % 2 == 0) sign = -sign;
            }
        }
    }
    const float* p = data.get() +
                     (wrap(r[1], padded[1]) + padded[1] * wrap(r[2], padded[2])) * rowStride() +
                     2 * r[0];
    return sign * std::complex<double>(p[0], conj ? -p[1] : p[1]);
}

double Spectrum::hartleyAt(std::int64_t kx, std::int64_t ky, std::int64_t kz) const {
    if (kind == TransformKind::Fft) {
        const auto g = valueAt(kx, ky, kz);
        return g.real() - g.imag();
    }
    double sign = 1.0;
    const std::int64_t k[3] = {kx, ky, kz};
    std::int64_t r[3];
    for (int a = 0; a < 3; ++a) {
        bool odd;
        r[a] = wrap(signedIndex(k[a], padded[a], odd), padded[a]);
        if (odd && volumeDims[a] % 2 == 0) sign = -sign;
    }
    return sign * data.get()[(r[1] + padded[1] * r[2]) * rowStride() + r[0]];
}

// ---------------------------------------------------------------------------------------------
// Sizes

std::int64_t nextFftSize(std::int64_t n) {
    if (n <= 1) return 1;
    for (std::int64_t m = n;; ++m) {
        std::int64_t r = m;
        for (std::int64_t f : {2, 3, 5, 7})
            while (r % f == 0) r /= f;
        if (r == 1) return m;
    }
}

Dims3 paddedDimsFor(const Dims3& dims, const PreprocessOptions& options) {
    Dims3 p{};
    if (options.paddedDims) {
        p = *options.paddedDims;
        for (int a = 0; a < 3; ++a)
            if (p[a] < dims[a] || p[a] > kMaxDimPerAxis)
                throw SettingsError("padded size axis " + std::to_string(a) + ": expected " +
                                    std::to_string(dims[a]) + ".." +
                                    std::to_string(kMaxDimPerAxis) + ", found " +
                                    std::to_string(p[a]));
        return p;
    }
    const double f = options.oversampling;
    if (!(f >= 1.0 && f <= 2.0))
        throw SettingsError("oversampling: expected a factor in [1, 2], found " +
                            std::to_string(f));
    for (int a = 0; a < 3; ++a) p[a] = nextFftSize(std::int64_t(std::ceil(f * dims[a] - 1e-9)));
    return p;
}

std::vector<float> deapodizationFactors(Kernel k, std::int64_t n, std::int64_t p,
                                        double oversampling) {
    std::vector<float> f(std::size_t(std::max<std::int64_t>(p, 0)), 1.0f);
    const std::int64_t m = n / 2;
    for (std::int64_t x = 0; x < n && x < p; ++x) {
        const std::int64_t j = x >= m ? x - m : x - m + p;
        const double u = (double(x) - double(n - 1) / 2.0) / double(p);
        f[std::size_t(j)] = float(1.0 / kernelFourier(k, u, oversampling));
    }
    return f;
}

std::size_t spectrumBytes(const Dims3& padded) {
    return std::size_t(2 * (padded[0] / 2 + 1)) * padded[1] * padded[2] * sizeof(float);
}

void CancelToken::check() const {
    if (cancelled()) throw Cancelled();
}

// ---------------------------------------------------------------------------------------------
// The preprocessing pipeline

namespace {

/** Reports monotone progress over weighted stages. */
class ProgressReporter {
public:
    ProgressReporter(const ProgressFn& fn, const CancelToken* cancel)
        : m_fn(fn), m_cancel(cancel) {}
    void stage(std::string_view name, double start, double end) {
        m_name = name;
        m_start = start;
        m_end = end;
        report(0.0);
    }
    void report(double withinStage) {
        if (m_cancel) m_cancel->check();
        detail::noteBusy(); // the background planner waits for a quiet moment
        const double f = std::clamp(m_start + (m_end - m_start) * withinStage, m_last, 1.0);
        m_last = f;
        if (m_fn) m_fn(f, m_name);
    }

private:
    const ProgressFn& m_fn;
    const CancelToken* m_cancel;
    std::string_view m_name;
    double m_start = 0, m_end = 0, m_last = 0;
};

/** Per-axis centring phase: the FFT origin holds voxel floor(N/2), the true centre is (N-1)/2,
 *  so G = F * exp(-2 pi i k sigma / P) with sigma = floor(N/2) - (N-1)/2 in {0, 1/2}, for the
 *  signed index k in (-P/2, P/2] (the Nyquist index of an even P holds +P/2). G is then the
 *  centred spectrum itself at every stored index; beyond them it repeats with the sign
 *  (-1)^(periods) where sigma = 1/2 (Spectrum). */
std::vector<std::complex<double>> centringPhase(std::int64_t n, std::int64_t p) {
    const double sigma = double(n / 2) - double(n - 1) / 2.0;
    std::vector<std::complex<double>> ph(std::size_t(p), {1.0, 0.0});
    if (sigma == 0.0) return ph;
    for (std::int64_t k = 0; k < p; ++k) {
        const std::int64_t ks = k <= p / 2 ? k : k - p;
        ph[k] = std::polar(1.0, -2.0 * std::numbers::pi * double(ks) * sigma / double(p));
    }
    return ph;
}

/** What the 3D transform's plans depend on (copied into background planning jobs). */
struct TransformShape {
    Dims3 P{};
    std::int64_t rs = 0;
    bool dht = false;
    int threads = 1;
};

/** The columns pass transforms a block of kBlockFloats neighbouring floats of one y row at a
 *  time along z, gathered into a small contiguous buffer (one transform after the other): its
 *  plan is cheap to measure and fast even from FFTW_ESTIMATE, whereas a plan that strides
 *  through the whole spectrum is 10x slower from ESTIMATE and takes ~0.5 s to measure. */
constexpr std::int64_t kBlockFloats = 32;
std::size_t columnBufferFloats(const TransformShape& s) {
    return std::size_t(kBlockFloats * s.P[2]);
}

/** In-place 2D transforms of `howmany` consecutive planes at p. */
fftwf_plan makePlanePlan(const TransformShape& s, float* p, int howmany, unsigned flags) {
    const int n[2] = {int(s.P[1]), int(s.P[0])};
    const int rs = int(s.rs), P1 = int(s.P[1]);
    if (s.dht) {
        const int embed[2] = {P1, rs};
        const fftwf_r2r_kind kinds[2] = {FFTW_DHT, FFTW_DHT};
        return fftwf_plan_many_r2r(2, n, howmany, p, embed, 1, rs * P1, p, embed, 1, rs * P1, kinds,
                                   flags);
    }
    const int iembed[2] = {P1, rs};
    const int oembed[2] = {P1, rs / 2};
    return fftwf_plan_many_dft_r2c(2, n, howmany, p, iembed, 1, rs * P1,
                                   reinterpret_cast<fftwf_complex*>(p), oembed, 1, (rs / 2) * P1,
                                   flags);
}

/** In-place 1D transforms along z of one gathered column block (columnBufferFloats). */
fftwf_plan makeColumnPlan(const TransformShape& s, float* buf, unsigned flags) {
    const int n[1] = {int(s.P[2])};
    if (s.dht) {
        const fftwf_r2r_kind kinds[1] = {FFTW_DHT};
        return fftwf_plan_many_r2r(1, n, int(kBlockFloats), buf, nullptr, 1, n[0], buf, nullptr, 1,
                                   n[0], kinds, flags);
    }
    auto* c = reinterpret_cast<fftwf_complex*>(buf);
    return fftwf_plan_many_dft(1, n, int(kBlockFloats / 2), c, nullptr, 1, n[0], c, nullptr, 1,
                               n[0], FFTW_FORWARD, flags);
}

/** Makes the measured versions of the plans on scratch buffers, for the wisdom of the next
 *  run. `planes`: (howmany, alignment) of each plane plan. One plan per lock, so that
 *  foreground planning waits for one plan at most. */
void measureInBackground(const TransformShape& s, std::vector<std::pair<int, int>> planes,
                         bool columns) {
    detail::planInBackground([s, planes = std::move(planes), columns] {
        for (const auto& [howmany, alignment] : planes) {
            const std::size_t floats = std::size_t(howmany * s.rs * s.P[1]);
            FftwBuffer scratch = allocateFftw(floats + 16);
            float* p = scratch.get() + alignment / int(sizeof(float));
            std::lock_guard lock(detail::planMutex());
            fftwf_plan_with_nthreads(s.threads);
            if (fftwf_plan plan = makePlanePlan(s, p, howmany, detail::plannerFlags(true)))
                fftwf_destroy_plan(plan);
        }
        if (!columns) return;
        FftwBuffer scratch = allocateFftw(columnBufferFloats(s));
        std::lock_guard lock(detail::planMutex());
        fftwf_plan_with_nthreads(1);
        if (fftwf_plan plan = makeColumnPlan(s, scratch.get(), detail::plannerFlags(true)))
            fftwf_destroy_plan(plan);
    });
}

/** Copies the block of `floats` floats at column x0 of every plane of row y into buf (block
 *  element e of plane z at buf[(e * P2 + z) * W + c]) or back (toBuffer false). */
template <int W>
void copyColumnBlock(float* row, std::int64_t planeFloats, std::int64_t P2, std::int64_t floats,
                     float* buf, bool toBuffer) {
    for (std::int64_t z = 0; z < P2; ++z) {
        float* s = row + z * planeFloats;
        for (std::int64_t f = 0; f < floats; f += W)
            for (int c = 0; c < W; ++c) {
                float& b = buf[((f / W) * P2 + z) * W + c];
                if (toBuffer)
                    b = s[f + c];
                else
                    s[f + c] = b;
            }
    }
}

class Transformer {
public:
    Transformer(Spectrum& s, const PreprocessOptions& o, ThreadPool& pool)
        : m_s(s), m_opt(o), m_pool(pool), m_P(s.padded), m_rs(s.rowStride()),
          m_threads(o.threads > 0 ? o.threads : hardwareThreads()) {}

    /** Plans everything first: MEASURE scribbles on the buffer, so this precedes the fill.
     *  Plans wisdom lacks are made ESTIMATE now and measured in the background (policy:
     *  detail::planQuickly). */
    void plan() {
        detail::ensureFftwInitialised();
        m_shape = {m_P, m_rs,
                   m_s.kind == TransformKind::Fht && m_opt.hartleyMethod == HartleyMethod::Dht,
                   m_threads};
        const std::int64_t P1 = m_P[1], P2 = m_P[2];
        m_planesPerChunk = std::max<std::int64_t>(1, (P2 + 15) / 16);
        m_rowsPerChunk = std::max<std::int64_t>(1, (P1 + 15) / 16);
        const bool measure = m_opt.effort == PlannerEffort::Measure;
        std::vector<std::pair<int, int>> planesLater;
        bool columnsLater = false;
        {
            std::lock_guard lock(detail::planMutex());
            fftwf_plan_with_nthreads(m_threads);
            for (std::int64_t z0 = 0; z0 < P2; z0 += m_planesPerChunk) {
                float* p = planeChunkPtr(z0);
                const auto key =
                    std::make_pair(int(std::min(m_planesPerChunk, P2 - z0)), fftwf_alignment_of(p));
                if (m_planes.count(key)) continue;
                const auto q = detail::planQuickly(
                    measure, [&](unsigned f) { return makePlanePlan(m_shape, p, key.first, f); });
                if (!q.plan)
                    throw std::runtime_error("FFTW could not plan the 2D plane transforms");
                m_planes.emplace(key, Plan(q.plan));
                if (q.measureLater) planesLater.push_back(key);
            }
            fftwf_plan_with_nthreads(1); // the columns pass runs blocks in parallel itself
            FftwBuffer buf = allocateFftw(columnBufferFloats(m_shape));
            const auto q = detail::planQuickly(
                measure, [&](unsigned f) { return makeColumnPlan(m_shape, buf.get(), f); });
            if (!q.plan) throw std::runtime_error("FFTW could not plan the 1D column transforms");
            m_column = Plan(q.plan);
            columnsLater = q.measureLater;
        }
        if (!planesLater.empty() || columnsLater)
            measureInBackground(m_shape, std::move(planesLater), columnsLater);
    }

    void planesPass(ProgressReporter& pr) {
        const std::int64_t P2 = m_P[2];
        for (std::int64_t z0 = 0; z0 < P2; z0 += m_planesPerChunk) {
            const int n = int(std::min(m_planesPerChunk, P2 - z0));
            float* p = planeChunkPtr(z0);
            const fftwf_plan plan = m_planes.at({n, fftwf_alignment_of(p)}).get();
            if (m_shape.dht)
                fftwf_execute_r2r(plan, p, p);
            else
                fftwf_execute_dft_r2c(plan, p, reinterpret_cast<fftwf_complex*>(p));
            pr.report(double(z0 + n) / P2);
        }
    }

    void columnsPass(ProgressReporter& pr) {
        const std::int64_t P1 = m_P[1];
        for (std::int64_t y0 = 0; y0 < P1; y0 += m_rowsPerChunk) {
            const std::int64_t y1 = std::min(P1, y0 + m_rowsPerChunk);
            m_pool.parallelFor(y1 - y0, 1, [&](std::int64_t a, std::int64_t b) {
                FftwBuffer buf = allocateFftw(columnBufferFloats(m_shape));
                std::fill(buf.get(), buf.get() + columnBufferFloats(m_shape), 0.0f);
                for (std::int64_t y = y0 + a; y < y0 + b; ++y) columnsOfRow(y, buf.get());
            });
            pr.report(double(y1) / P1);
        }
    }

    bool dht() const { return m_shape.dht; }

private:
    float* planeChunkPtr(std::int64_t z0) const { return m_s.data.get() + z0 * m_rs * m_P[1]; }

    /** The 1D transforms along z of row y, a gathered block at a time (kBlockFloats). */
    void columnsOfRow(std::int64_t y, float* buf) const {
        float* row = m_s.data.get() + y * m_rs;
        const std::int64_t planeFloats = m_rs * m_P[1], P2 = m_P[2];
        for (std::int64_t x0 = 0; x0 < m_rs; x0 += kBlockFloats) {
            const std::int64_t n = std::min(kBlockFloats, m_rs - x0);
            if (m_shape.dht) {
                copyColumnBlock<1>(row + x0, planeFloats, P2, n, buf, true);
                fftwf_execute_r2r(m_column.get(), buf, buf);
                copyColumnBlock<1>(row + x0, planeFloats, P2, n, buf, false);
            } else {
                auto* c = reinterpret_cast<fftwf_complex*>(buf);
                copyColumnBlock<2>(row + x0, planeFloats, P2, n, buf, true);
                fftwf_execute_dft(m_column.get(), c, c);
                copyColumnBlock<2>(row + x0, planeFloats, P2, n, buf, false);
            }
        }
    }

    Spectrum& m_s;
    const PreprocessOptions& m_opt;
    ThreadPool& m_pool;
    Dims3 m_P;
    std::int64_t m_rs;
    int m_threads;
    TransformShape m_shape;
    std::int64_t m_planesPerChunk = 1, m_rowsPerChunk = 1;
    /** One plane plan per (howmany, alignment) so new-array execution is always legal. */
    std::map<std::pair<int, int>, Plan> m_planes;
    Plan m_column;
};

/** Zero-pads and centres the mapped volume into the transform buffer (wrap-around); with
 *  deapodization also divides by the kernel's separable Fourier transform (one multiply per
 *  voxel with three 1D tables). */
void fillPadded(const Volume& v, Spectrum& s, ValueMapping mapping, ThreadPool& pool,
                ProgressReporter& pr) {
    std::vector<float> dx, dy, dz;
    if (s.deapodizedFor) {
        const double sigma = kernelOversampling(v.dims, s.padded);
        dx = deapodizationFactors(*s.deapodizedFor, v.dims[0], s.padded[0], sigma);
        dy = deapodizationFactors(*s.deapodizedFor, v.dims[1], s.padded[1], sigma);
        dz = deapodizationFactors(*s.deapodizedFor, v.dims[2], s.padded[2], sigma);
    }
    const bool deapodize = s.deapodizedFor.has_value();
    const auto& N = v.dims;
    const auto& P = s.padded;
    const std::int64_t rs = s.rowStride();
    const std::int64_t m[3] = {N[0] / 2, N[1] / 2, N[2] / 2};
    float* data = s.data.get();
    // Whole padded planes with no voxel are zeroed; planes with voxels are written row by row.
    std::vector<std::int64_t> srcZ(std::size_t(P[2]), -1);
    for (std::int64_t z = 0; z < N[2]; ++z) srcZ[std::size_t(wrap(z - m[2], P[2]))] = z;
    std::vector<std::int64_t> srcY(std::size_t(P[1]), -1);
    for (std::int64_t y = 0; y < N[1]; ++y) srcY[std::size_t(wrap(y - m[1], P[1]))] = y;
    std::atomic<std::int64_t> done{0};
    pool.parallelFor(P[2], 1, [&](std::int64_t z0, std::int64_t z1) {
        for (std::int64_t jz = z0; jz < z1; ++jz) {
            float* plane = data + jz * rs * P[1];
            const std::int64_t z = srcZ[std::size_t(jz)];
            if (z < 0) {
                std::memset(plane, 0, sizeof(float) * std::size_t(rs * P[1]));
                continue;
            }
            for (std::int64_t jy = 0; jy < P[1]; ++jy) {
                float* row = plane + jy * rs;
                const std::int64_t y = srcY[std::size_t(jy)];
                std::memset(row, 0, sizeof(float) * std::size_t(rs));
                if (y < 0) continue;
                const float* src = v.voxels.data() + v.index(0, y, z);
                // x in [m, N) -> [0, N - m); x in [0, m) -> [P - m, P).
                if (!deapodize) {
                    for (std::int64_t x = 0; x < N[0]; ++x) {
                        const std::int64_t jx = x >= m[0] ? x - m[0] : x - m[0] + P[0];
                        const float val = src[x];
                        row[jx] = mapValue(mapping, val);
                    }
                    continue;
                }
                const float fyz = dy[std::size_t(jy)] * dz[std::size_t(jz)];
                for (std::int64_t x = 0; x < N[0]; ++x) {
                    const std::int64_t jx = x >= m[0] ? x - m[0] : x - m[0] + P[0];
                    const float val = src[x];
                    row[jx] = mapValue(mapping, val) * (fyz * dx[std::size_t(jx)]);
                }
            }
        }
        done += z1 - z0;
    });
    pr.report(1.0);
}

/** Fft kind: G = F * phase, in place. */
void applyPhaseComplex(Spectrum& s, const Dims3& N, ThreadPool& pool) {
    const auto& P = s.padded;
    const auto px = centringPhase(N[0], P[0]), py = centringPhase(N[1], P[1]),
               pz = centringPhase(N[2], P[2]);
    const bool any = N[0] % 2 == 0 || N[1] % 2 == 0 || N[2] % 2 == 0;
    if (!any) return;
    const std::int64_t rs = s.rowStride(), H = P[0] / 2 + 1;
    pool.parallelFor(P[2], 1, [&](std::int64_t z0, std::int64_t z1) {
        for (std::int64_t z = z0; z < z1; ++z)
            for (std::int64_t y = 0; y < P[1]; ++y) {
                const std::complex<double> fyz = py[y] * pz[z];
                auto* row =
                    reinterpret_cast<std::complex<float>*>(s.data.get() + (y + P[1] * z) * rs);
                for (std::int64_t x = 0; x < H; ++x)
                    row[x] = std::complex<float>(std::complex<double>(row[x]) * (px[x] * fyz));
            }
    });
}

/** Fht from the r2c result: G = F * phase, then H = Re G - Im G over the full kx range.
 *  Rows (y, z) and (-y, -z) are converted together so the conversion is in place. */
void complexToHartley(Spectrum& s, const Dims3& N, ThreadPool& pool) {
    const auto& P = s.padded;
    const auto px = centringPhase(N[0], P[0]), py = centringPhase(N[1], P[1]),
               pz = centringPhase(N[2], P[2]);
    const std::int64_t rs = s.rowStride(), H = P[0] / 2 + 1, rows = P[1] * P[2];
    pool.parallelFor(rows, 64, [&](std::int64_t r0, std::int64_t r1) {
        std::vector<std::complex<double>> a(static_cast<std::size_t>(H)),
            b(static_cast<std::size_t>(H));
        for (std::int64_t r = r0; r < r1; ++r) {
            const std::int64_t y = r % P[1], z = r / P[1];
            const std::int64_t my = wrap(-y, P[1]), mz = wrap(-z, P[2]);
            const std::int64_t rm = my + P[1] * mz;
            if (rm < r) continue; // handled with its partner
            float* ra = s.data.get() + r * rs;
            float* rb = s.data.get() + rm * rs;
            // The unphased F is periodic and Hermitian: F(kx > P0/2, y, z) = conj F(P0 - kx, -y,
            // -z), read from the partner row; the phase then follows each stored index
            // (centringPhase).
            for (std::int64_t x = 0; x < H; ++x) {
                a[x] = std::complex<double>(ra[2 * x], ra[2 * x + 1]);
                b[x] = std::complex<double>(rb[2 * x], rb[2 * x + 1]);
            }
            auto hartley = [&](const std::vector<std::complex<double>>& own,
                               const std::vector<std::complex<double>>& other, std::int64_t yy,
                               std::int64_t zz, float* out) {
                const std::complex<double> fyz = py[yy] * pz[zz];
                for (std::int64_t x = 0; x < P[0]; ++x) {
                    const std::complex<double> f = x < H ? own[x] : std::conj(other[P[0] - x]);
                    const std::complex<double> g = f * (px[x] * fyz);
                    out[x] = float(g.real() - g.imag());
                }
            };
            hartley(a, b, y, z, ra);
            if (rm != r) hartley(b, a, my, mz, rb);
        }
    });
}

/** Fht via FFTW_DHT: the separable product T becomes the 3D Hartley transform through the
 *  paper's eq. 5, H(u,v,w) = 1/2 (T(-u,v,w) + T(u,-v,w) + T(u,v,-w) - T(-u,-v,-w)), then the
 *  centring phase is applied in the Hartley domain. The 8 mirror points (+-u, +-v, +-w) are read
 *  and written together, so the pass is in place. */
void hartleyCorrection(Spectrum& s, const Dims3& N, ThreadPool& pool) {
    const auto& P = s.padded;
    const auto px = centringPhase(N[0], P[0]), py = centringPhase(N[1], P[1]),
               pz = centringPhase(N[2], P[2]);
    const std::int64_t rs = s.rowStride();
    float* d = s.data.get();
    pool.parallelFor(P[2] / 2 + 1, 1, [&](std::int64_t w0, std::int64_t w1) {
        for (std::int64_t w = w0; w < w1; ++w)
            for (std::int64_t v = 0; v <= P[1] / 2; ++v)
                for (std::int64_t u = 0; u <= P[0] / 2; ++u) {
                    const std::int64_t ix[2] = {u, wrap(-u, P[0])};
                    const std::int64_t iy[2] = {v, wrap(-v, P[1])};
                    const std::int64_t iz[2] = {w, wrap(-w, P[2])};
                    double t[2][2][2], h[2][2][2];
                    for (int c = 0; c < 2; ++c)
                        for (int b = 0; b < 2; ++b)
                            for (int a = 0; a < 2; ++a)
                                t[c][b][a] = d[(iy[b] + P[1] * iz[c]) * rs + ix[a]];
                    for (int c = 0; c < 2; ++c)
                        for (int b = 0; b < 2; ++b)
                            for (int a = 0; a < 2; ++a)
                                h[c][b][a] = 0.5 * (t[c][b][1 - a] + t[c][1 - b][a] +
                                                    t[1 - c][b][a] - t[1 - c][1 - b][1 - a]);
                    // Centring phase G' = G (c + i s): H' = E (c - s) + O (c + s).
                    double out[2][2][2];
                    for (int c = 0; c < 2; ++c)
                        for (int b = 0; b < 2; ++b)
                            for (int a = 0; a < 2; ++a) {
                                const std::complex<double> f = px[ix[a]] * py[iy[b]] * pz[iz[c]];
                                const double hk = h[c][b][a], hm = h[1 - c][1 - b][1 - a];
                                const double e = 0.5 * (hk + hm), o = 0.5 * (hk - hm);
                                out[c][b][a] =
                                    e * (f.real() - f.imag()) + o * (f.real() + f.imag());
                            }
                    for (int c = 0; c < 2; ++c)
                        for (int b = 0; b < 2; ++b)
                            for (int a = 0; a < 2; ++a)
                                d[(iy[b] + P[1] * iz[c]) * rs + ix[a]] = float(out[c][b][a]);
                }
    });
}

/** Float holds 3.4e38. The unnormalised 3D transform sums the mapped voxels (|G| <= sum |f|),
 *  and the slice, its scale and the inverse 2D transform need room above that: a volume whose
 *  sum comes within this factor of the float range is refused before the transform instead of
 *  filling the spectrum, and then every image, with inf and NaN. */
constexpr double kSpectrumHeadroom = double(1 << 24);

/** Refuses values whose spectrum would overflow float (kSpectrumHeadroom), naming the numbers:
 *  one parallel pass over the mapped voxels in double. */
void checkSpectrumRange(const Volume& v, ValueMapping mapping, ThreadPool& pool) {
    std::mutex m;
    double sum = 0.0, largest = 0.0;
    pool.parallelFor(std::int64_t(v.voxels.size()), 1 << 16, [&](std::int64_t b, std::int64_t e) {
        double s = 0.0, l = 0.0;
        for (std::int64_t i = b; i < e; ++i) {
            const double a = std::abs(double(mapValue(mapping, v.voxels[std::size_t(i)])));
            s += a;
            l = std::max(l, a);
        }
        const std::lock_guard lock(m);
        sum += s;
        largest = std::max(largest, l);
    });
    const double limit = double(std::numeric_limits<float>::max()) / kSpectrumHeadroom;
    if (sum <= limit) return; // also false for a sum that overflowed double to inf or is NaN
    char msg[512];
    std::snprintf(msg, sizeof msg,
                  "%s: values too large for float: |value| up to %g (mapping %s) sums to %g over "
                  "%zu voxels, and the 3D spectrum (sums of the values) with room for the "
                  "projection must stay below %g (float's %g / 2^24); rescale the values (a mean "
                  "|value| of at most %g fits)",
                  v.name.empty() ? "volume" : v.name.c_str(), largest, valueMappingName(mapping),
                  sum, v.voxels.size(), limit, double(std::numeric_limits<float>::max()),
                  limit / double(v.voxels.size()));
    throw SettingsError(msg);
}

/** The spectrum's buffer must fit in the memory this process may take (memory_budget.h):
 *  refused with the sizes before allocating, instead of an allocation that the kernel's
 *  overcommit lets through and its OOM killer ends. */
void checkSpectrumMemory(const Spectrum& s) {
    const auto dims = [](const Dims3& d) {
        return std::to_string(d[0]) + " x " + std::to_string(d[1]) + " x " + std::to_string(d[2]);
    };
    checkMemoryFor(s.bytes(), s.name.empty() ? "volume" : s.name,
                   "the spectrum of " + dims(s.volumeDims) + " voxels padded to " + dims(s.padded) +
                       " (a smaller oversampling needs less)");
}

} // namespace

std::shared_ptr<const Spectrum> preprocess(const Volume& volume, const PreprocessOptions& options,
                                           const ProgressFn& progress, const CancelToken* cancel) {
    validateGeometry(volume.dims, volume.spacing, volume.name.empty() ? "volume" : volume.name);
    if (std::int64_t(volume.voxels.size()) != volume.voxelCount())
        throw SettingsError(volume.name + ": voxel buffer holds " +
                            std::to_string(volume.voxels.size()) + " values, dims need " +
                            std::to_string(volume.voxelCount()));
    ThreadPool pool(options.threads);
    checkSpectrumRange(volume, options.mapping, pool);
    const PlannerBusyScope busy; // no background measuring while the 3D transform runs
    ProgressReporter pr(progress, cancel);
    pr.stage("planning", 0.0, 0.02);

    auto s = std::make_shared<Spectrum>();
    s->kind = options.transform;
    s->mapping = options.mapping;
    s->sourceUnits = volume.units;
    s->volumeDims = volume.dims;
    s->spacing = volume.spacing;
    s->padded = paddedDimsFor(volume.dims, options);
    s->name = volume.name;
    s->deapodizedFor = options.deapodizeFor;
    s->nonNegative = isAttenuation(options.mapping) || volume.valueRange().first >= 0.0f;
    checkSpectrumMemory(*s);
    s->data = allocateFftw(s->floatCount());

    Transformer tr(*s, options, pool);
    tr.plan();
    pr.report(1.0);

    pr.stage("mapping and padding", 0.02, 0.12);
    fillPadded(volume, *s, options.mapping, pool, pr);

    pr.stage("3D transform: planes", 0.12, 0.57);
    tr.planesPass(pr);
    pr.stage("3D transform: columns", 0.57, 0.92);
    tr.columnsPass(pr);

    pr.stage(options.transform == TransformKind::Fht ? "Hartley conversion" : "centring phase",
             0.92, 1.0);
    if (options.transform == TransformKind::Fft)
        applyPhaseComplex(*s, volume.dims, pool);
    else if (tr.dht())
        hartleyCorrection(*s, volume.dims, pool);
    else
        complexToHartley(*s, volume.dims, pool);
    pr.report(1.0);
    detail::noteBusy();
    detail::saveWisdom();
    return s;
}

// ---------------------------------------------------------------------------------------------

PreprocessJob::PreprocessJob(std::shared_ptr<const Volume> volume, PreprocessOptions options)
    : m_volume(std::move(volume)), m_options(std::move(options)) {
    m_thread = std::thread([this] {
        try {
            auto result = preprocess(
                *m_volume, m_options,
                [this](double f, std::string_view stage) {
                    m_fraction.store(f);
                    std::lock_guard lock(m_mutex);
                    m_stage = stage;
                },
                &m_cancel);
            std::lock_guard lock(m_mutex);
            m_result = std::move(result);
        } catch (...) {
            std::lock_guard lock(m_mutex);
            m_error = std::current_exception();
        }
        m_finished.store(true);
    });
}

PreprocessJob::~PreprocessJob() {
    m_cancel.cancel();
    if (m_thread.joinable()) m_thread.join();
}

std::string PreprocessJob::stage() const {
    std::lock_guard lock(m_mutex);
    return m_stage;
}

std::shared_ptr<const Spectrum> PreprocessJob::get() {
    if (m_thread.joinable()) m_thread.join();
    std::lock_guard lock(m_mutex);
    if (m_error) std::rethrow_exception(m_error);
    return m_result;
}

} // namespace fvr::core
