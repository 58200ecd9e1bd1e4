/**
 * FVR benchmarks (docs/dev/performance.md), in the layout of Table 1 of
 * Viola et al. 2004: per slice size M, per interpolation kernel, the slicing stage and the inverse
 * 2D transform, for the FFT and the FHT representation.
 *
 *   BM_Preprocess/N<n>/<fft|fht-fromfft|fht-dht>   3D transform of the Shepp-Logan phantom
 *   BM_Frame/N<n>/<fft|fht>/M<m>/<kernel>         one projection per iteration, rotating view
 *   BM_RayCast/N128/M<m>/step<0.25vox|1vox>       spatial ray casting (trilinear), same views
 *   BM_Size/N256/<W>x<H>/d<m>/<kernel>             one W x H frame, pixel = diagonal / m (a
 *                                                  cropped square of FFTW's fast side): sizes
 *                                                  other than powers of two
 *   BM_BareFft/M<m>                                one in-place M x M complex FFT (FFTW, MEASURE):
 *                                                  the yardstick a frame is measured in (frame /
 * bare FFT) BM_Effects/N256/<fft|fht>/M512/<kernel>/<effect> the per-frame cost of depth cueing and
 * the slice filters (plain, depth, filters, both) and of the clip to the volume
 *
 * Per-frame counters are real measurements (StageTimes of every iteration): slice_ms, inverse_ms,
 * total_ms are means over the iterations (frames), *_p50 the medians; fps = 1000 / total_ms,
 * slice_fps and inverse_fps are the per-stage rates of the paper's Table 1. The benchmark's own
 * time column is wall time per iteration (UseRealTime; the renderers are multi-threaded).
 *
 * Volumes, spectra, renderers and FFTW plans are built once, outside the timed loops, and cached
 * in static storage across benchmarks. N = 512 benchmarks (a 512^3 phantom, 0.5 GiB per spectrum)
 * are left out of a plain run: they are registered when the --benchmark_filter contains N512
 * (e.g. --benchmark_filter=N512, --benchmark_filter=BM_Preprocess/N512) or FVR_BENCH_LARGE=1.
 */
#include <benchmark/benchmark.h>
#include <fftw3.h>

#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/fftw_planning.h>
#include <fvr/core/render/kernels.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/core/render/view.h>
#include <fvr/core/xray/phantom.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include <unistd.h>

namespace {

using namespace fvr::core;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

bool largeEnabled() {
    const char* e = std::getenv("FVR_BENCH_LARGE");
    return e && std::string_view(e) == "1";
}

// --- Cached setup -----------------------------------------------------------------------------

/** The Shepp-Logan phantom, N^3 voxels over 256 mm, voxelised once per N. */
const Volume& phantom(int n) {
    static std::map<int, std::unique_ptr<Volume>> cache;
    auto& v = cache[n];
    if (!v) v = std::make_unique<Volume>(makeSheppLoganVolume(n));
    return *v;
}

PreprocessOptions preprocessOptions(TransformKind kind, HartleyMethod method) {
    PreprocessOptions o;
    o.mapping = ValueMapping::Raw;
    o.transform = kind;
    o.hartleyMethod = method;
    o.oversampling = 1.0; // the paper's setting
    o.threads = 0; // all hardware threads
    o.effort = PlannerEffort::Measure;
    return o;
}

/** The spectrum the renderers read (Fht from the default FromFft method; both give the same). */
std::shared_ptr<const Spectrum> spectrum(int n, TransformKind kind) {
    static std::map<std::pair<int, TransformKind>, std::shared_ptr<const Spectrum>> cache;
    auto& s = cache[{n, kind}];
    if (!s) s = preprocess(phantom(n), preprocessOptions(kind, HartleyMethod::FromFft));
    return s;
}

/** One renderer per (N, transform): it keeps its per-M plans and buffers across benchmarks. */
CpuFourierRenderer& renderer(int n, TransformKind kind) {
    static std::map<std::pair<int, TransformKind>, std::unique_ptr<CpuFourierRenderer>> cache;
    auto& r = cache[{n, kind}];
    if (!r) r = std::make_unique<CpuFourierRenderer>(spectrum(n, kind), 0);
    return *r;
}

/** 64 views rotating about a tilted axis by the golden angle: every frame reads the spectrum
 *  along a different oblique plane (never an axis-aligned, cache-friendly one). */
const std::vector<ViewFrame>& views() {
    static const std::vector<ViewFrame> v = [] {
        std::vector<ViewFrame> out;
        const ViewFrame base = ViewFrame::fromDirUp({0.3, -1.0, 0.2}, {0.0, 0.1, 1.0});
        const Vec3 axis{0.25, 0.35, 1.0};
        const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
        for (int i = 0; i < 64; ++i) out.push_back(base.rotated(axis, golden * i));
        return out;
    }();
    return v;
}

ImageGeometry geometry(int n, int M) {
    const Volume& v = phantom(n);
    return ImageGeometry{M, defaultPixelSize(v.dims, v.spacing, M)};
}

// --- Interference --------------------------------------------------------------------------

/**
 * CPU time other processes used while a benchmark ran, in cores (0 = machine to ourselves; on a
 * 2-core machine 1 = a whole core taken), from /proc/stat minus this process's own time, hypervisor
 * steal included. Reported as the counter other_cores so that runs disturbed by other work (builds,
 * tests) can be told apart. -1 where /proc is not available.
 */
class LoadProbe {
public:
    LoadProbe() : m_start(Clock::now()), m_busy(machineBusyTicks()), m_self(selfTicks()) {}
    double otherCores() const {
        const double busy = machineBusyTicks(), self = selfTicks();
        const double seconds = std::chrono::duration<double>(Clock::now() - m_start).count();
        if (busy < 0 || self < 0 || m_busy < 0 || m_self < 0 || seconds <= 0) return -1.0;
        const double ticks = (busy - m_busy) - (self - m_self);
        return std::max(0.0, ticks / double(sysconf(_SC_CLK_TCK)) / seconds);
    }

private:
    static double machineBusyTicks() {
        std::ifstream f("/proc/stat");
        std::string cpu;
        double user, nice, system, idle, iowait, irq, softirq, steal;
        if (!(f >> cpu >> user >> nice >> system >> idle >> iowait >> irq >> softirq >> steal) ||
            cpu != "cpu")
            return -1.0;
        return user + nice + system + irq + softirq + steal;
    }
    static double selfTicks() {
        std::ifstream f("/proc/self/stat");
        std::string line;
        if (!std::getline(f, line)) return -1.0;
        const auto close = line.rfind(')'); // the command name may hold spaces
        if (close == std::string::npos) return -1.0;
        std::istringstream rest(line.substr(close + 2));
        std::string field;
        double utime = -1, stime = -1;
        for (int i = 3; i <= 15 && rest >> field; ++i) { // fields 14, 15: utime, stime
            if (i == 14) utime = std::stod(field);
            if (i == 15) stime = std::stod(field);
        }
        return utime < 0 || stime < 0 ? -1.0 : utime + stime;
    }

    Clock::time_point m_start;
    double m_busy, m_self;
};

// --- Statistics -------------------------------------------------------------------------------

double mean(const std::vector<double>& x) {
    return x.empty() ? 0.0 : std::accumulate(x.begin(), x.end(), 0.0) / double(x.size());
}

double median(std::vector<double> x) {
    if (x.empty()) return 0.0;
    const auto h = std::ptrdiff_t(x.size() / 2);
    std::nth_element(x.begin(), x.begin() + h, x.end());
    const double upper = x[std::size_t(h)];
    if (x.size() % 2 == 1) return upper;
    return 0.5 * (upper + *std::max_element(x.begin(), x.begin() + h)); // lower middle
}

// --- 1. Preprocessing ---------------------------------------------------------------------------

struct PreprocessCase {
    const char* name;
    TransformKind kind;
    HartleyMethod method;
};
constexpr PreprocessCase kPreprocessCases[] = {
    {"fft", TransformKind::Fft, HartleyMethod::FromFft},
    {"fht-fromfft", TransformKind::Fht, HartleyMethod::FromFft},
    {"fht-dht", TransformKind::Fht, HartleyMethod::Dht},
};

void BM_Preprocess(benchmark::State& state, int n, PreprocessCase c) {
    const Volume& vol = phantom(n);
    const PreprocessOptions opt = preprocessOptions(c.kind, c.method);
    // Warm-up once per case: FFTW MEASURE planning (up to a few seconds per new size) goes into
    // the wisdom, so the timed runs see what a repeated study load sees.
    static std::map<std::tuple<int, TransformKind, HartleyMethod>, bool> warmed;
    if (!warmed[{n, c.kind, c.method}]) {
        benchmark::DoNotOptimize(preprocess(vol, opt).get());
        warmed[{n, c.kind, c.method}] = true;
    }

    // Stage breakdown from the progress callback (stage names of preprocess()).
    std::vector<double> plan, pad, transform, post, total;
    Clock::time_point stageStart;
    std::string current;
    auto closeStage = [&](Clock::time_point now) {
        const double ms = std::chrono::duration<double, std::milli>(now - stageStart).count();
        if (current == "planning")
            plan.back() += ms;
        else if (current == "mapping and padding")
            pad.back() += ms;
        else if (current.starts_with("3D transform"))
            transform.back() += ms;
        else if (!current.empty())
            post.back() += ms;
    };
    const ProgressFn progress = [&](double, std::string_view stage) {
        if (stage == current) return;
        const auto now = Clock::now();
        closeStage(now);
        current = stage;
        stageStart = now;
    };

    const LoadProbe probe;
    for (auto _ : state) {
        plan.push_back(0);
        pad.push_back(0);
        transform.push_back(0);
        post.push_back(0);
        current.clear();
        const auto t0 = Clock::now();
        auto s = preprocess(vol, opt, progress);
        const auto t1 = Clock::now();
        closeStage(t1);
        benchmark::DoNotOptimize(s->data.get());
        total.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
        s.reset(); // freeing the spectrum counts in the iteration's wall time, not in total_ms
    }
    state.counters["total_ms"] = mean(total);
    state.counters["plan_ms"] = mean(plan); // planning from wisdom + buffer allocation
    state.counters["pad_ms"] = mean(pad);
    state.counters["transform3d_ms"] = mean(transform);
    state.counters["post_ms"] = mean(post);
    state.counters["other_cores"] = probe.otherCores();
    const Dims3 padded = paddedDimsFor(vol.dims, opt);
    state.SetLabel("padded " + std::to_string(padded[0]) + "x" + std::to_string(padded[1]) + "x" +
                   std::to_string(padded[2]) + ", " + std::to_string(spectrumBytes(padded) >> 20) +
                   " MiB");
}

// --- 2. Per-frame stages (Table 1) ------------------------------------------------------------

void BM_Frame(benchmark::State& state, int n, TransformKind kind, int M, Kernel kernel) {
    CpuFourierRenderer& r = renderer(n, kind);
    const ImageGeometry g = geometry(n, M);
    const auto& vs = views();
    // Plans for this M (FFTW MEASURE) are made on the renderer's first frame of that size.
    static std::map<std::tuple<int, TransformKind, int>, bool> planned;
    if (!planned[{n, kind, M}]) {
        benchmark::DoNotOptimize(r.render(RenderParams{vs[0], g, kernel}).pixels.data());
        planned[{n, kind, M}] = true;
    }

    std::vector<double> slice, inverse, total;
    const auto reserve = std::size_t(state.max_iterations);
    slice.reserve(reserve);
    inverse.reserve(reserve);
    total.reserve(reserve);
    std::size_t i = 0;
    const LoadProbe probe;
    for (auto _ : state) {
        StageTimes t;
        ProjectionImage img = r.render(RenderParams{vs[i++ % vs.size()], g, kernel}, &t);
        benchmark::DoNotOptimize(img.pixels.data());
        slice.push_back(t.sliceMs);
        inverse.push_back(t.inverseMs);
        total.push_back(t.totalMs);
    }
    const double sm = mean(slice), im = mean(inverse), tm = mean(total);
    state.counters["slice_ms"] = sm;
    state.counters["inverse_ms"] = im;
    state.counters["total_ms"] = tm;
    state.counters["slice_p50"] = median(slice);
    state.counters["inverse_p50"] = median(inverse);
    state.counters["total_p50"] = median(total);
    state.counters["slice_fps"] = sm > 0 ? 1000.0 / sm : 0.0;
    state.counters["inverse_fps"] = im > 0 ? 1000.0 / im : 0.0;
    state.counters["fps"] = tm > 0 ? 1000.0 / tm : 0.0;
    state.counters["other_cores"] = probe.otherCores();
}

// --- 2b. Beyond the paper: depth cueing and slice filters per frame ----------------------------

enum class Effect { Plain, Depth, Filters, Both, Clip };
const char* effectName(Effect e) {
    switch (e) {
    case Effect::Plain: return "plain";
    case Effect::Depth: return "depthcue";
    case Effect::Filters: return "filters";
    case Effect::Both: return "depthcue+filters";
    case Effect::Clip: return "clip";
    }
    return "?";
}

/** Times frames of `p` over the rotating views (plans for this M made first) and sets the
 *  per-stage counters: the loop of BM_Effects and BM_VoxelModel. */
void timeFrames(benchmark::State& state, CpuFourierRenderer& r, RenderParams p) {
    benchmark::DoNotOptimize(r.render(p).pixels.data()); // plans for this M
    std::vector<double> slice, inverse, total;
    std::size_t i = 0;
    const LoadProbe probe;
    for (auto _ : state) {
        StageTimes t;
        p.view = views()[i++ % views().size()];
        ProjectionImage img = r.render(p, &t);
        benchmark::DoNotOptimize(img.pixels.data());
        slice.push_back(t.sliceMs);
        inverse.push_back(t.inverseMs);
        total.push_back(t.totalMs);
    }
    state.counters["slice_ms"] = mean(slice);
    state.counters["inverse_ms"] = mean(inverse);
    state.counters["total_ms"] = mean(total);
    state.counters["total_p50"] = median(total);
    state.counters["fps"] = mean(total) > 0 ? 1000.0 / mean(total) : 0.0;
    state.counters["other_cores"] = probe.otherCores();
}

/** One W x H frame (any size: the renderer transforms a square of fourierSide() and crops it),
 *  against the power-of-two squares around it: what a size other than a power of two costs. */
void BM_Size(benchmark::State& state, int n, int W, int H, int pixelOf, Kernel kernel) {
    CpuFourierRenderer& r = renderer(n, TransformKind::Fft);
    const Volume& v = phantom(n);
    const ImageGeometry g{W, defaultPixelSize(v.dims, v.spacing, pixelOf), H};
    state.SetLabel("transform " + std::to_string(fourierSide(g, v.dims, v.spacing, false)) +
                   "^2 (GPU " + std::to_string(fourierSide(g, v.dims, v.spacing, true)) + "^2)");
    // The first frame of a side queues its measured plan; waiting for it times every side with
    // the plan it keeps (the first size to need a side would time the estimate plan instead).
    const RenderParams p{views()[0], g, kernel};
    benchmark::DoNotOptimize(r.render(p).pixels.data());
    finishBackgroundPlanning();
    timeFrames(state, r, p);
}

void BM_Effects(benchmark::State& state, int n, TransformKind kind, int M, Kernel kernel,
                Effect e) {
    RenderParams p{views()[0], geometry(n, M), kernel};
    if (e == Effect::Depth || e == Effect::Both) p.depthCue = 0.7;
    if (e == Effect::Filters || e == Effect::Both) p.filter = {1.5, 2.0, 0.5};
    p.clipToVolume = e == Effect::Clip;
    timeFrames(state, renderer(n, kind), p);
}

// --- 2c. Voxel models: the band cut against the transfer function over the whole slice ----------

void BM_VoxelModel(benchmark::State& state, int n, TransformKind kind, int M, Kernel kernel,
                   VoxelModel model, double pixelScale) {
    RenderParams p{views()[0], geometry(n, M), kernel};
    p.image.pixelSize *= pixelScale;
    p.voxelModel = model;
    p.clipToVolume = true;
    timeFrames(state, renderer(n, kind), p);
}

// --- 3. Spatial ray casting ---------------------------------------------------------------------

SpatialProjector& projector(int n, double stepFraction) {
    static std::map<std::pair<int, double>, std::unique_ptr<SpatialProjector>> cache;
    auto& p = cache[{n, stepFraction}];
    if (!p) {
        SpatialProjectorOptions o;
        o.stepFraction = stepFraction;
        o.mapping = ValueMapping::Raw;
        o.threads = 0;
        p = std::make_unique<SpatialProjector>(phantom(n), o);
    }
    return *p;
}

// --- 2c. The yardstick: one bare 2D FFT ------------------------------------------------------

/** One in-place M x M complex FFTW transform (forward, FFTW_MEASURE, the renderer's thread count
 *  for that M): the unit a frame's cost is measured in (frame ms / bare FFT ms). */
void BM_BareFft(benchmark::State& state, int M) {
    static std::once_flag init;
    std::call_once(init, [] { fftwf_init_threads(); });
    const int threads = M >= 512 ? hardwareThreads() : 1;
    auto* data = fftwf_alloc_complex(std::size_t(M) * M);
    fftwf_plan_with_nthreads(threads);
    fftwf_plan plan = fftwf_plan_dft_2d(M, M, data, data, FFTW_FORWARD, FFTW_MEASURE);
    for (std::size_t i = 0; i < std::size_t(M) * M; ++i) {
        data[i][0] = float(i % 7) - 3.0f; // planning overwrote the buffer
        data[i][1] = float(i % 5) - 2.0f;
    }
    std::vector<double> ms;
    const LoadProbe probe;
    for (auto _ : state) {
        const auto t0 = Clock::now();
        fftwf_execute(plan);
        ms.push_back(msSince(t0));
        benchmark::DoNotOptimize(data[0][0]);
    }
    fftwf_destroy_plan(plan);
    fftwf_free(data);
    state.counters["fft_ms"] = mean(ms);
    state.counters["fft_p50"] = median(ms);
    state.counters["threads"] = threads;
    state.counters["other_cores"] = probe.otherCores();
}

void BM_RayCast(benchmark::State& state, int n, int M, double stepFraction) {
    SpatialProjector& p = projector(n, stepFraction);
    const ImageGeometry g = geometry(n, M);
    const auto& vs = views();
    std::vector<double> total;
    std::size_t i = 0;
    const LoadProbe probe;
    for (auto _ : state) {
        const auto t0 = Clock::now();
        ProjectionImage img = p.project(vs[i++ % vs.size()], g);
        total.push_back(msSince(t0));
        benchmark::DoNotOptimize(img.pixels.data());
    }
    const double tm = mean(total);
    state.counters["total_ms"] = tm;
    state.counters["total_p50"] = median(total);
    state.counters["fps"] = tm > 0 ? 1000.0 / tm : 0.0;
    state.counters["other_cores"] = probe.otherCores();
}

// --- Registration -------------------------------------------------------------------------------

/** Frames per benchmark: enough for stable means, small enough that a plain run stays within a
 *  few minutes on 2 cores. Use --benchmark_repetitions for more. */
benchmark::IterationCount framesFor(int M) { return M <= 256 ? 200 : M <= 512 ? 100 : 40; }

void registerAll(const std::vector<int>& sizes) {
    for (int n : sizes) {
        for (const PreprocessCase& c : kPreprocessCases) {
            const std::string name = "BM_Preprocess/N" + std::to_string(n) + "/" + c.name;
            benchmark::RegisterBenchmark(name.c_str(), BM_Preprocess, n, c)
                ->Iterations(n <= 128   ? 5
                             : n <= 256 ? 3
                                        : 2)
                ->Unit(benchmark::kMillisecond)
                ->UseRealTime();
        }
    }
    for (int n : sizes)
        for (TransformKind kind : {TransformKind::Fft, TransformKind::Fht})
            for (int M : {256, 512, 1024})
                for (Kernel k : allKernels()) {
                    const std::string name = "BM_Frame/N" + std::to_string(n) + "/" +
                                             transformName(kind) + "/M" + std::to_string(M) + "/" +
                                             kernelName(k);
                    benchmark::RegisterBenchmark(name.c_str(), BM_Frame, n, kind, M, k)
                        ->Iterations(framesFor(M))
                        ->Unit(benchmark::kMillisecond)
                        ->UseRealTime();
                }
    if (std::find(sizes.begin(), sizes.end(), 256) != sizes.end())
        for (TransformKind kind : {TransformKind::Fft, TransformKind::Fht})
            for (Kernel k : {Kernel::Linear, Kernel::KaiserBessel4})
                for (Effect e :
                     {Effect::Plain, Effect::Depth, Effect::Filters, Effect::Both, Effect::Clip}) {
                    const std::string name = std::string("BM_Effects/N256/") + transformName(kind) +
                                             "/M512/" + kernelName(k) + "/" + effectName(e);
                    benchmark::RegisterBenchmark(name.c_str(), BM_Effects, 256, kind, 512, k, e)
                        ->Iterations(framesFor(512))
                        ->Unit(benchmark::kMillisecond)
                        ->UseRealTime();
                }
    if (std::find(sizes.begin(), sizes.end(), 256) != sizes.end())
        for (TransformKind kind : {TransformKind::Fft, TransformKind::Fht})
            for (Kernel k : {Kernel::Linear, Kernel::KaiserBessel4})
                for (double scale : {1.0, 2.0})
                    for (VoxelModel m : allVoxelModels()) {
                        // Pixel 1x: the default (0.87 voxel: a quarter of the slice lies beyond the
                        // band); 2x: the whole slice lies inside it, so every model samples the
                        // same.
                        const std::string name = std::string("BM_VoxelModel/N256/") +
                                                 transformName(kind) + "/M512/" + kernelName(k) +
                                                 "/pixel" + (scale == 1.0 ? "1x/" : "2x/") +
                                                 voxelModelName(m);
                        benchmark::RegisterBenchmark(name.c_str(), BM_VoxelModel, 256, kind, 512, k,
                                                     m, scale)
                            ->Iterations(framesFor(512))
                            ->Unit(benchmark::kMillisecond)
                            ->UseRealTime();
                    }
    // Each size at its default pixel size (the diagonal over min(W, H)), beside the squares
    // around it at the same pixel size: the slice's cost depends on the pixel size (how much of
    // it lies in the volume's band), so only equal pixel sizes compare.
    for (auto [W, H, pixelOf] : {std::tuple{200, 200, 200},
                                 {256, 256, 200},
                                 {224, 224, 224},
                                 {256, 256, 224},
                                 {976, 976, 976},
                                 {1024, 1024, 976},
                                 {1240, 960, 960},
                                 {1250, 1250, 960},
                                 {2048, 2048, 960}})
        for (Kernel k : {Kernel::Linear, Kernel::KaiserBessel4}) {
            const std::string name = "BM_Size/N256/" + std::to_string(W) + "x" + std::to_string(H) +
                                     "/d" + std::to_string(pixelOf) + "/" + kernelName(k);
            benchmark::RegisterBenchmark(name.c_str(), BM_Size, 256, W, H, pixelOf, k)
                ->Iterations(framesFor(std::max(W, H)))
                ->Unit(benchmark::kMillisecond)
                ->UseRealTime();
        }
    for (int M : {256, 512, 1024}) {
        const std::string name = "BM_BareFft/M" + std::to_string(M);
        benchmark::RegisterBenchmark(name.c_str(), BM_BareFft, M)
            ->Iterations(framesFor(M) * 5)
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime();
    }
    for (int M : {256, 512})
        for (double step : {0.25, 1.0}) {
            const std::string name = "BM_RayCast/N128/M" + std::to_string(M) + "/step" +
                                     (step == 0.25 ? "0.25vox" : "1vox");
            const int frames = (M == 256 ? 8 : 4) * (step == 0.25 ? 1 : 2);
            benchmark::RegisterBenchmark(name.c_str(), BM_RayCast, 128, M, step)
                ->Iterations(frames)
                ->Unit(benchmark::kMillisecond)
                ->UseRealTime();
        }
}

std::string loadAverage() {
    std::ifstream f("/proc/loadavg");
    std::string a, b, c;
    if (f >> a >> b >> c) return a + " " + b + " " + c;
    return "unknown";
}

} // namespace

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    // N = 512 (a 512^3 phantom and two 0.5 GiB spectra, ~1 min of setup) is registered only when
    // asked for: FVR_BENCH_LARGE=1, or a --benchmark_filter that contains N512.
    const bool large =
        largeEnabled() || benchmark::GetBenchmarkFilter().find("N512") != std::string::npos;
    registerAll(large ? std::vector<int>{128, 256, 512} : std::vector<int>{128, 256});
    // Plans measured at once (a warm workstation's plans), unless FVR_FFTW_PLANNING says
    // otherwise: the background planner would otherwise measure FFTW plans on a thread of this
    // process whenever it has been 2 s without a frame (between benchmarks, during BM_BareFft:
    // it doubled the bare FFT's time in a run), which other_cores cannot see.
    if (!std::getenv("FVR_FFTW_PLANNING")) setFftwPlanning(FftwPlanning::Foreground);
    benchmark::AddCustomContext("fvr_load_average_at_start", loadAverage());
    benchmark::AddCustomContext("fvr_counters",
                                "slice_ms/inverse_ms/total_ms: means of StageTimes over the "
                                "iterations (= frames); *_p50: medians; fps = 1000/total_ms; "
                                "other_cores: CPU used by other processes meanwhile (cores)");
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
