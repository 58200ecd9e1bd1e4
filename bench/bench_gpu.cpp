/**
 * GPU benchmarks in the layout of Table 1 of Viola et al. 2004: per slice size M and
 * kernel, the slicing pass and the inverse 2D transform measured separately with GL timer
 * queries (slice pass unfused), and the end-to-end frame as the workstation renders it (slice
 * fused into the row FFT pass, display mapping into the last pass: line integrals to an 8-bit
 * texture), for the FFT and the FHT representation.
 *
 *   BM_GpuStages/N<n>/<fft|fht>/M<m>/<kernel>   unfused: slice_ms, inverse_ms, slice_fps,
 * inverse_fps BM_GpuFrame/N<n>/<fft|fht>/M<m>/<kernel>    fused end-to-end to the display texture:
 *                                               gpu_ms (timer queries), fps,
 *                                               and wall_fps (frames issued back to back, one
 *                                               wait per batch of 16: what an interactive loop
 * gets)
 *
 * And the cone-beam ray caster (gpu::ConeRayCaster) on the same phantom at N = 256 (mu values),
 * a C-arm orbit (SID 1200, SOD 750, 20 degrees cranial, the detector framing the volume):
 *
 *   BM_ConeGpu/N<n>/<W>x<W>/[noskip-]<model>/<fetch>
 *                                             (noskip-: without leaving out blocks of air)
 *                                             views_per_s and view_ms: one view per dispatch,
 *                                             back to back, one wait per batch (no read-back);
 *                                             grouped_views_per_s: views_per_dispatch views in
 *                                             one dispatch (projectMany's way);
 *                                             readback_views_per_s: one view, read back
 *
 * Needs an OpenGL 4.3 context: a headless EGL one (gpu::EglContext, no X server; a hardware EGL
 * device, else Mesa llvmpipe, whose numbers are a sanity check only). N is 256 unless
 * FVR_BENCH_GPU_N says otherwise (e.g. 128,256,512). The 3D Shepp-Logan phantom, mu values, no
 * oversampling: the paper's setup.
 */
#include <epoxy/gl.h>

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include <fvr/core/geometry/camera.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/gpu/cone_ray_caster.h>
#include <fvr/gpu/egl_context.h>
#include <fvr/gpu/gpu_renderer.h>

namespace {

using namespace fvr::core;
using fvr::gpu::GpuFourierRenderer;

const Volume& phantom(int n) {
    static std::map<int, std::unique_ptr<Volume>> cache;
    auto& v = cache[n];
    if (!v) v = std::make_unique<Volume>(makeSheppLoganVolume(n));
    return *v;
}

GpuFourierRenderer& renderer(int n, TransformKind kind) {
    static std::map<std::pair<int, TransformKind>, std::unique_ptr<GpuFourierRenderer>> cache;
    auto& r = cache[{n, kind}];
    if (!r) {
        PreprocessOptions o;
        o.mapping = ValueMapping::Mu;
        o.transform = kind;
        o.oversampling = 1.0;
        r = std::make_unique<GpuFourierRenderer>();
        r->setSpectrum(preprocess(phantom(n), o));
    }
    return *r;
}

const std::vector<ViewFrame>& views() {
    static const std::vector<ViewFrame> v = [] {
        std::vector<ViewFrame> out;
        const ViewFrame base = ViewFrame::fromDirUp({0.3, -1.0, 0.2}, {0.0, 0.1, 1.0});
        const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
        for (int i = 0; i < 64; ++i) out.push_back(base.rotated({0.25, 0.35, 1.0}, golden * i));
        return out;
    }();
    return v;
}

/** The median: on a real GPU the first frames after an idle spell run at a low clock, and one
 *  such frame among 30 moved a mean by up to 5x (an H100, 2026-11-26). */
double median(std::vector<double> x) {
    if (x.empty()) return 0.0;
    const auto mid = x.begin() + std::ptrdiff_t(x.size() / 2);
    std::nth_element(x.begin(), mid, x.end());
    if (x.size() % 2 == 1) return *mid;
    return 0.5 * (*mid + *std::max_element(x.begin(), mid));
}

/** Renders a few untimed frames, waiting for them: compiles the variant and wakes the GPU. */
void warmUp(GpuFourierRenderer& r, const RenderParams& p, const DisplayWindow* window = nullptr) {
    for (int i = 0; i < 8; ++i) r.renderToGpu(p, window);
    glFinish();
    r.lastTimes();
}

void BM_GpuStages(benchmark::State& state, int n, TransformKind kind, int M, Kernel kernel) {
    GpuFourierRenderer& r = renderer(n, kind);
    const ImageGeometry g{M, defaultPixelSize(phantom(n).dims, phantom(n).spacing, M)};
    r.setFuseSlice(false);
    warmUp(r, {views()[0], g, kernel});
    std::vector<double> slice, inverse;
    std::size_t i = 0;
    for (auto _ : state) {
        r.renderToGpu({views()[i++ % views().size()], g, kernel});
        const auto t = r.lastTimes();
        slice.push_back(t.sliceMs);
        inverse.push_back(t.inverseMs);
    }
    r.setFuseSlice(true);
    const double s = median(slice), inv = median(inverse);
    state.counters["slice_ms"] = s;
    state.counters["inverse_ms"] = inv;
    state.counters["slice_fps"] = s > 0 ? 1000.0 / s : 0.0;
    state.counters["inverse_fps"] = inv > 0 ? 1000.0 / inv : 0.0;
}

void BM_GpuFrame(benchmark::State& state, int n, TransformKind kind, int M, Kernel kernel) {
    GpuFourierRenderer& r = renderer(n, kind);
    const ImageGeometry g{M, defaultPixelSize(phantom(n).dims, phantom(n).spacing, M)};
    r.setFuseSlice(true);
    const DisplayWindow window{0.0, 0.5 * phantom(n).dims[0] * phantom(n).spacing[0], true, {}};
    warmUp(r, {views()[0], g, kernel}, &window);
    std::vector<double> gpu, wall;
    std::size_t i = 0;
    constexpr int kBatch = 16;
    for (auto _ : state) {
        r.renderToGpu({views()[i++ % views().size()], g, kernel}, &window);
        gpu.push_back(r.lastTimes().totalMs);
        // Back to back: kBatch frames, one wait at the end.
        const auto t0 = std::chrono::steady_clock::now();
        for (int b = 0; b < kBatch; ++b)
            r.renderToGpu({views()[(i + b) % views().size()], g, kernel}, &window);
        glFinish();
        wall.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count() /
            kBatch);
    }
    const double gm = median(gpu), wm = median(wall);
    state.counters["gpu_ms"] = gm;
    state.counters["fps"] = gm > 0 ? 1000.0 / gm : 0.0;
    state.counters["wall_ms"] = wm;
    state.counters["wall_fps"] = wm > 0 ? 1000.0 / wm : 0.0;
}

/** The orbit's views: 64 primary angles, 20 degrees cranial, the detector framing the volume. */
std::vector<ConeCamera> coneOrbit(const Volume& v, int size) {
    std::vector<ConeCamera> out;
    for (int i = 0; i < 64; ++i) {
        CArm arm;
        arm.primaryDeg = -180.0 + 360.0 * i / 64;
        arm.secondaryDeg = 20.0;
        arm.sid = 1200.0;
        arm.sod = 750.0;
        arm.isocentre = volumeCentre(v);
        const double pitch = framingPitch(v, arm.sid, arm.sod, size, size);
        out.push_back(cArmCamera(arm, size, size, pitch, pitch));
    }
    return out;
}

/** One cone-beam ray caster per volume size, model and fetch (the upload is not timed). */
fvr::gpu::ConeRayCaster& coneCaster(int n, const ConeProjectorOptions& o,
                                    fvr::gpu::TrilinearFetch fetch) {
    static std::map<std::string, std::unique_ptr<fvr::gpu::ConeRayCaster>> cache;
    auto& c = cache[std::to_string(n) + fvr::gpu::describeConeRayCaster(o, fetch)];
    if (!c) c = std::make_unique<fvr::gpu::ConeRayCaster>(phantom(n), o, fetch);
    return *c;
}

void BM_ConeGpu(benchmark::State& state, int n, int size, ConeProjectorOptions o,
                fvr::gpu::TrilinearFetch fetch) {
    using Clock = std::chrono::steady_clock;
    auto ms = [](Clock::time_point t0) {
        return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    };
    auto& caster = coneCaster(n, o, fetch);
    const auto cams = coneOrbit(phantom(n), size);
    // Untimed: wakes the GPU, and sizes the batches to about 0.2 s (1 on a software renderer).
    auto t0 = Clock::now();
    caster.project(cams[0]);
    const int batch = std::clamp(int(200.0 / std::max(ms(t0), 1e-3)), 1, 256);
    const int perDispatch = std::min<int>(batch, int(cams.size()));
    const std::vector<ConeCamera> group(cams.begin(), cams.begin() + perDispatch);
    caster.projectToGpu(group);
    glFinish();
    std::vector<double> single, grouped, readBack;
    std::size_t i = 0;
    for (auto _ : state) {
        t0 = Clock::now();
        for (int b = 0; b < batch; ++b) caster.projectToGpu(cams[i++ % cams.size()]);
        glFinish();
        single.push_back(ms(t0) / batch);
        t0 = Clock::now();
        caster.projectToGpu(group);
        glFinish();
        grouped.push_back(ms(t0) / perDispatch);
        t0 = Clock::now();
        caster.project(cams[i++ % cams.size()]);
        readBack.push_back(ms(t0));
    }
    const double sm = median(single), gm = median(grouped), rm = median(readBack);
    state.counters["view_ms"] = sm;
    state.counters["views_per_s"] = sm > 0 ? 1000.0 / sm : 0.0;
    state.counters["grouped_views_per_s"] = gm > 0 ? 1000.0 / gm : 0.0;
    state.counters["readback_views_per_s"] = rm > 0 ? 1000.0 / rm : 0.0;
    state.counters["views_per_dispatch"] = perDispatch;
    state.SetLabel(fvr::gpu::describeConeRayCaster(o, fetch));
}

void registerConeBenchmarks() {
    using fvr::gpu::TrilinearFetch;
    struct Variant {
        const char* name;
        RayModel model;
        double step;
        TrilinearFetch fetch;
        bool skipEmpty = true;
    };
    const Variant variants[] = {
        {"box", RayModel::Box, 0.0, TrilinearFetch::Manual},
        {"trilinear-exact/manual", RayModel::Trilinear, 0.0, TrilinearFetch::Manual},
        {"trilinear-exact/hardware", RayModel::Trilinear, 0.0, TrilinearFetch::Hardware},
        {"trilinear-step0.5/manual", RayModel::Trilinear, 0.5, TrilinearFetch::Manual},
        {"trilinear-step0.5/hardware", RayModel::Trilinear, 0.5, TrilinearFetch::Hardware},
        // What leaving out the blocks of air gains (the default above).
        {"noskip-box", RayModel::Box, 0.0, TrilinearFetch::Manual, false},
        {"noskip-trilinear-step0.5/hardware", RayModel::Trilinear, 0.5, TrilinearFetch::Hardware,
         false}};
    constexpr int n = 256;
    for (int size : {256, 1024})
        for (const Variant& v : variants) {
            ConeProjectorOptions o;
            o.model = v.model;
            o.stepFraction = v.step;
            o.mapping = ValueMapping::Mu;
            o.skipEmpty = v.skipEmpty;
            const std::string name = "BM_ConeGpu/N" + std::to_string(n) + "/" +
                                     std::to_string(size) + "x" + std::to_string(size) + "/" +
                                     v.name;
            benchmark::RegisterBenchmark(name.c_str(), BM_ConeGpu, n, size, o, v.fetch)
                ->Iterations(size <= 256 ? 10 : 5)
                ->Unit(benchmark::kMillisecond)
                ->UseRealTime();
        }
}

std::vector<int> volumeSizes() {
    std::vector<int> out;
    if (const char* e = std::getenv("FVR_BENCH_GPU_N")) {
        std::stringstream ss(e);
        std::string tok;
        while (std::getline(ss, tok, ','))
            if (!tok.empty()) out.push_back(std::stoi(tok));
    }
    if (out.empty()) out.push_back(256);
    return out;
}

} // namespace

int main(int argc, char** argv) {
    std::unique_ptr<fvr::gpu::EglContext> ctx;
    try {
        ctx = std::make_unique<fvr::gpu::EglContext>();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fvr_bench_gpu: %s\n", e.what());
        return 1;
    }
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    {
        GpuFourierRenderer probe;
        benchmark::AddCustomContext("gl_renderer", probe.rendererInfo());
    }
    for (int n : volumeSizes())
        for (TransformKind kind : {TransformKind::Fft, TransformKind::Fht})
            for (int M : {256, 512, 1024})
                for (Kernel k : allKernels()) {
                    const std::string suffix = "/N" + std::to_string(n) + "/" +
                                               transformName(kind) + "/M" + std::to_string(M) +
                                               "/" + kernelName(k);
                    const int iters = M <= 512 ? 30 : 15;
                    benchmark::RegisterBenchmark(("BM_GpuStages" + suffix).c_str(), BM_GpuStages, n,
                                                 kind, M, k)
                        ->Iterations(iters)
                        ->Unit(benchmark::kMillisecond)
                        ->UseRealTime();
                    benchmark::RegisterBenchmark(("BM_GpuFrame" + suffix).c_str(), BM_GpuFrame, n,
                                                 kind, M, k)
                        ->Iterations(iters)
                        ->Unit(benchmark::kMillisecond)
                        ->UseRealTime();
                }
    registerConeBenchmarks();
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
