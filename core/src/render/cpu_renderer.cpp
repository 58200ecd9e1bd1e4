#include <fvr/core/render/cpu_renderer.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string_view>
#include <type_traits>

#include <fvr/core/errors.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/slice_params.h>

#include "cpu_slice_internal.h"
#include "fftw_support.h"

namespace fvr::core {

using Clock = std::chrono::steady_clock;
using cfloat = std::complex<float>;

std::string projectionUnits(ValueMapping mapping, ValueUnits source) {
    if (mapping == ValueMapping::Mu) return "mm (mu/mu_water x mm)";
    if (mapping == ValueMapping::MuBone) return "mm (bone-enhanced mu/mu_water x mm)";
    if (source == ValueUnits::HounsfieldUnits) return "HU x mm";
    return "value x mm";
}

struct CpuFourierRenderer::SizeResources {
    int size = 0;
    FftwBuffer slice; // Fft: M rows x (M/2+1) complex; Fht: M x M real
    FftwBuffer image; // Fft: M x M real output; Fht: M rows x (M/2+1) complex
    /** Fft: complex-to-real, slice -> image. Fht: real-to-complex, slice -> image, whose
     *  Re - Im is the 2D Hartley transform (hartleyFromHalfSpectrum): FFTW_DHT plans are 5x
     *  slower from ESTIMATE and 4x slower measured, and give the separable transform. */
    detail::Plan inverse;
    /** The measured plan the background planner is making (null: the plan above is final),
     *  and the estimate plan it replaced (kept: destroying it would wait for the planner). */
    std::shared_ptr<detail::PlanSlot> measured;
    detail::Plan replaced;
};

CpuFourierRenderer::CpuFourierRenderer(std::shared_ptr<const Spectrum> spectrum, int threads)
    : m_spectrum(std::move(spectrum)), m_pool(threads),
      m_threads(threads > 0 ? threads : hardwareThreads()) {
    if (!m_spectrum || !m_spectrum->data) throw SettingsError("renderer: no spectrum");
    m_lookups = std::make_unique<const detail::CpuSliceLookups>(*m_spectrum);
    const double sigma = kernelOversampling(m_spectrum->volumeDims, m_spectrum->padded);
    for (Kernel k : allKernels()) m_tables.emplace(k, std::make_unique<KernelTable>(k, sigma));
}

CpuFourierRenderer::~CpuFourierRenderer() = default;

namespace {
/** The inverse 2D transform of an M x M slice, out of place (SizeResources::inverse). */
fftwf_plan planInverse(bool hartley, int M, float* slice, float* image, unsigned flags) {
    if (hartley)
        return fftwf_plan_dft_r2c_2d(M, M, slice, reinterpret_cast<fftwf_complex*>(image), flags);
    return fftwf_plan_dft_c2r_2d(M, M, reinterpret_cast<fftwf_complex*>(slice), image, flags);
}

/** The 2D Hartley transform H = Re F - Im F of an M x M real image from its r2c transform F
 *  (M rows of M/2+1; F(-k) = conj F(k) gives the columns beyond M/2). */
void hartleyFromHalfSpectrum(const float* F, float* H, int M, ThreadPool& pool) {
    const std::int64_t h = M / 2 + 1;
    pool.parallelFor(M, 16, [&](std::int64_t r0, std::int64_t r1) {
        for (std::int64_t y = r0; y < r1; ++y) {
            const float* row = F + 2 * h * y;
            const float* mirror = F + 2 * h * ((M - y) % M);
            float* out = H + std::int64_t(M) * y;
            for (std::int64_t x = 0; x < h; ++x) out[x] = row[2 * x] - row[2 * x + 1];
            for (std::int64_t x = h; x < M; ++x)
                out[x] = mirror[2 * (M - x)] + mirror[2 * (M - x) + 1];
        }
    });
}
} // namespace

CpuFourierRenderer::SizeResources& CpuFourierRenderer::resources(int M) {
    auto it = m_resources.find(M);
    if (it != m_resources.end()) return *it->second;
    detail::ensureFftwInitialised();
    auto r = std::make_unique<SizeResources>();
    r->size = M;
    const bool hartley = m_spectrum->kind == TransformKind::Fht;
    const std::size_t half = std::size_t(M) * (M / 2 + 1) * 2, full = std::size_t(M) * M;
    const std::size_t sliceFloats = hartley ? full : half, imageFloats = hartley ? half : full;
    r->slice = allocateFftw(sliceFloats);
    r->image = allocateFftw(imageFloats);
    const int threads = M >= 512 ? m_threads : 1;
    detail::QuickPlan q;
    {
        std::lock_guard lock(detail::planMutex());
        fftwf_plan_with_nthreads(threads);
        q = detail::planQuickly(true, [&](unsigned flags) {
            return planInverse(hartley, M, r->slice.get(), r->image.get(), flags);
        });
    }
    r->inverse = detail::Plan(q.plan);
    if (!q.plan) throw std::runtime_error("FFTW could not plan the inverse 2D transform");
    if (q.measureLater) {
        // Measured on buffers of its own (MEASURE overwrites them), executed on ours: both come
        // from fftwf_malloc, so their alignment agrees (new-array execution is legal).
        r->measured = std::make_shared<detail::PlanSlot>();
        detail::planInBackground(
            [slot = r->measured, hartley, M, threads, sliceFloats, imageFloats] {
                FftwBuffer slice = allocateFftw(sliceFloats);
                FftwBuffer image = allocateFftw(imageFloats);
                std::lock_guard lock(detail::planMutex());
                fftwf_plan_with_nthreads(threads);
                slot->set(
                    planInverse(hartley, M, slice.get(), image.get(), detail::plannerFlags(true)));
            });
    }
    detail::saveWisdom();
    return *m_resources.emplace(M, std::move(r)).first->second;
}

using detail::FrameMapping;
using detail::SliceContext;

std::string CpuFourierRenderer::describe() const {
    return "CPU, " + std::to_string(m_threads) + (m_threads == 1 ? " thread" : " threads");
}

namespace {

/** The per-sample context of one frame from its slice parameters. */
SliceContext makeSliceContext(const Spectrum& s, const SliceParams& sp, const KernelTable* table,
                              const TransferTable* model, const detail::CpuSliceLookups* lookups) {
    SliceContext c{};
    c.data = s.data.get();
    c.P0 = sp.padded[0];
    c.P1 = sp.padded[1];
    c.P2 = sp.padded[2];
    c.rs = s.rowStride();
    c.table = table;
    c.first = table->firstTapOffset();
    // The band edge with a tolerance for the slice's rounding (infinite half stays infinite).
    c.half0 = sp.half[0] + 1e-9;
    c.half1 = sp.half[1] + 1e-9;
    c.half2 = sp.half[2] + 1e-9;
    c.depthA = float(sp.depthA);
    for (int a = 0; a < 3; ++a) {
        c.anti[a] = sp.anti[a];
        c.invP[a] = sp.invP[a];
        c.E[a] = float(sp.E[a]);
    }
    c.model = model;
    c.lookups = lookups;
    return c;
}

FrameMapping frameMapping(const SliceParams& sp) {
    FrameMapping f{};
    for (int a = 0; a < 3; ++a) {
        f.A[a] = sp.A[a];
        f.B[a] = sp.B[a];
    }
    f.scale = float(sp.scale);
    return f;
}

/** The M x M image the square transform fills. */
ProjectionImage emptyImage(const RenderParams& params, const Spectrum& s, int M) {
    ProjectionImage img;
    img.width = img.height = M;
    img.pixelSize = params.image.pixelSize;
    img.view = params.view;
    img.mapping = s.mapping;
    img.pixels.resize(std::size_t(M) * M);
    return img;
}

} // namespace

const TransferTable* CpuFourierRenderer::transferTable(VoxelModel model, double maxCyclesPerVoxel) {
    if (model == VoxelModel::BandLimited) return nullptr;
    auto& table = m_transfer[model];
    if (!table) table = std::make_unique<TransferTable>(model);
    table->cover(maxCyclesPerVoxel);
    return table.get();
}

void CpuFourierRenderer::invertSlice(SizeResources& res, ProjectionImage& img) {
    detail::noteBusy();
    if (res.measured && res.measured->ready()) { // swap in the background planner's plan
        detail::Plan p = res.measured->take();
        res.measured.reset();
        if (p) {
            res.replaced = std::move(res.inverse);
            res.inverse = std::move(p);
        }
    }
    if (m_spectrum->kind == TransformKind::Fft) {
        fftwf_execute_dft_c2r(res.inverse.get(), reinterpret_cast<fftwf_complex*>(res.slice.get()),
                              res.image.get());
        std::memcpy(img.pixels.data(), res.image.get(), sizeof(float) * img.pixels.size());
    } else {
        fftwf_execute_dft_r2c(res.inverse.get(), res.slice.get(),
                              reinterpret_cast<fftwf_complex*>(res.image.get()));
        hartleyFromHalfSpectrum(res.image.get(), img.pixels.data(), img.width, m_pool);
    }
}

void CpuFourierRenderer::clipAndClamp(const RenderParams& params, ProjectionImage& img) {
    const Spectrum& s = *m_spectrum;
    const bool clamp = params.nonNegative && s.nonNegative;
    if (!params.clipToVolume && !clamp) return;
    const int M = img.width; // the square transform's side
    const double d = img.pixelSize;
    const Vec3 half =
        supportHalfExtents(s.volumeDims, s.spacing, voxelModelReach(params.voxelModel));
    m_pool.parallelFor(M, 16, [&](std::int64_t r0, std::int64_t r1) {
        for (std::int64_t row = r0; row < r1; ++row) {
            float* p = img.pixels.data() + std::size_t(row) * M;
            ColumnRange hit{0, M - 1};
            if (params.clipToVolume) {
                hit = volumeShadowColumns(params.view, half, M, d, int(row));
                if (hit.first > hit.last) {
                    std::fill(p, p + M, 0.0f);
                    continue;
                }
                std::fill(p, p + hit.first, 0.0f);
                std::fill(p + hit.last + 1, p + M, 0.0f);
            }
            if (clamp)
                for (int col = hit.first; col <= hit.last; ++col) p[col] = std::max(p[col], 0.0f);
        }
    });
}

ProjectionImage CpuFourierRenderer::render(const RenderParams& params, StageTimes* times) {
    const PlannerBusyScope busy; // the background planner measures between frames, not during
    validateRenderParams(params, *m_spectrum);
    const auto t0 = Clock::now();
    const Spectrum& s = *m_spectrum;
    checkKernelMatchesSpectrum(s, params.kernel);
    // A W x H image is the centred crop of a square of FFTW's fast side M >= W, H (the same
    // pixel size: the crop changes neither the values nor their positions).
    const int W = params.image.cols(), H = params.image.rows();
    RenderParams square = params;
    square.image = {fourierSide(params.image, s.volumeDims, s.spacing, false),
                    params.image.pixelSize};
    const int M = square.image.size;
    SizeResources& res = resources(M);

    const SliceParams sp = sliceParams(s, square);
    const SliceContext c =
        makeSliceContext(s, sp, m_tables.at(params.kernel).get(),
                         transferTable(params.voxelModel, sp.maxCyclesPerVoxel), m_lookups.get());
    const SliceFilterTable filter(params.filter, params.pixelAperture, M, params.image.pixelSize);
    ProjectionImage img = emptyImage(params, s, M);

    detail::sampleSlice(c, frameMapping(sp), filter, sp, s.kind, M, res.slice.get(), m_pool);
    const auto t1 = Clock::now();
    invertSlice(res, img);
    // The last pass: zero outside the model's support, and no negative line integrals of a
    // non-negative volume.
    clipAndClamp(square, img);
    if (W != M || H != M) img = cropProjection(std::move(img), W, H);
    const auto t2 = Clock::now();
    if (times) {
        auto ms = [](auto a, auto b) {
            return std::chrono::duration<double, std::milli>(b - a).count();
        };
        times->sliceMs = ms(t0, t1);
        times->inverseMs = ms(t1, t2);
        times->totalMs = ms(t0, t2);
    }
    return img;
}

} // namespace fvr::core
