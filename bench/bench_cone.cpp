/**
 * Cone-beam ray casting benchmarks (core::ConeProjector) on a real CT, in the geometry of the
 * speed target: a C-arm orbit at SID 1200 mm / SOD 750 mm about the volume's centre, the detector
 * framing the volume (framingPitch), one view per iteration, the primary angle advancing 4 degrees
 * per view (a 90-view orbit; every benchmark starts at 0 degrees).
 *
 *   BM_LoadCT                                 scan and decode of the CT (one iteration)
 *   BM_Prepare/<model>/<values>               ConeProjector's construction: the value mapping,
 *                                             the empty-block map, B-spline coefficients
 *   BM_ConeView/<model>/<values>/M<m>[/threads1]   one view per iteration, M x M detector
 *
 * models: box (exact path lengths, as plastimatch drr -i exact), trilinear-exact (per cell),
 * trilinear-step0.5 (midpoint samples every half voxel), bspline (the default step, a quarter
 * voxel). values: mu (fvr-render's default for HU: air is 0, so empty blocks are skipped) and,
 * for the box model, raw (HU as stored: nothing to skip, every voxel on a ray is visited, as
 * plastimatch visits them). threads1: one thread (a per-core comparison); the others run on
 * every hardware thread.
 *
 * Counters: ms_per_view (the mean over the iterations, our own clock) and views_per_s; the
 * time column is wall time per iteration (UseRealTime).
 *
 * The CT: FVR_BENCH_CT (a DICOM folder or a volume file), else the Philips phantom CT of
 * ../shared/data (FVR_SHARED_DATA_DIR at build time). bench/cone_vs_plastimatch.sh runs it.
 */
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/cone_projector.h>

namespace {

using namespace fvr::core;
using Clock = std::chrono::steady_clock;

constexpr double kSid = 1200.0;
constexpr double kSod = 750.0;
constexpr int kOrbitViews = 90;

std::filesystem::path ctPath() {
    if (const char* e = std::getenv("FVR_BENCH_CT")) return e;
    return std::filesystem::path(FVR_SHARED_DATA_DIR) / "dicom/ct_phantom_philips_512x512x140";
}

Volume loadCt() {
    const std::filesystem::path p = ctPath();
    if (!std::filesystem::exists(p))
        throw std::runtime_error("bench_cone: no CT at " + p.string() +
                                 " (set FVR_BENCH_CT to a DICOM folder or a volume file)");
    if (std::filesystem::is_directory(p)) return loadDicomFolder(p).volume;
    return loadVolume(p);
}

/** The CT, loaded once for every benchmark but BM_LoadCT. */
const Volume& ct() {
    static const std::unique_ptr<Volume> v = std::make_unique<Volume>(loadCt());
    return *v;
}

struct Model {
    const char* name;
    RayModel model;
    double step;
};
const Model kModels[] = {{"box", RayModel::Box, 0.0},
                         {"trilinear-exact", RayModel::Trilinear, 0.0},
                         {"trilinear-step0.5", RayModel::Trilinear, 0.5},
                         {"bspline", RayModel::BSpline, 0.0}};

ConeProjectorOptions options(const Model& m, ValueMapping values, int threads) {
    ConeProjectorOptions o;
    o.model = m.model;
    o.stepFraction = m.step;
    o.mapping = values;
    o.threads = threads;
    return o;
}

/** View k of the orbit on an M x M detector. */
ConeCamera orbitView(const Volume& v, int k, int m) {
    const double pitch = framingPitch(v, kSid, kSod, m, m);
    const double primary = std::remainder(360.0 * k / kOrbitViews, 360.0);
    return cArmCamera({primary, 0.0, kSid, kSod, volumeCentre(v)}, m, m, pitch, pitch);
}

void BM_LoadCT(benchmark::State& state) {
    for (auto _ : state) {
        Volume v = loadCt();
        benchmark::DoNotOptimize(v.voxels.data());
        state.SetLabel(std::to_string(v.dims[0]) + "x" + std::to_string(v.dims[1]) + "x" +
                       std::to_string(v.dims[2]));
    }
}

void BM_Prepare(benchmark::State& state, Model m, ValueMapping values) {
    const Volume& v = ct();
    for (auto _ : state) {
        ConeProjector p(v, options(m, values, 0));
        benchmark::DoNotOptimize(&p);
    }
}

void BM_ConeView(benchmark::State& state, Model m, ValueMapping values, int size, int threads) {
    const Volume& v = ct();
    ConeProjector projector(v, options(m, values, threads));
    int k = 0;
    double totalMs = 0.0;
    for (auto _ : state) {
        const ConeCamera cam = orbitView(v, k++, size);
        const auto t0 = Clock::now();
        DetectorImage img = projector.project(cam);
        totalMs += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        benchmark::DoNotOptimize(img.pixels.data());
    }
    const double ms = totalMs / double(std::max<benchmark::IterationCount>(1, state.iterations()));
    state.counters["ms_per_view"] = ms;
    state.counters["views_per_s"] = ms > 0.0 ? 1000.0 / ms : 0.0;
    state.SetLabel(describeConeProjector(projector.options()));
}

/** Views per benchmark: the whole 90-view orbit where a view is cheap, fewer where it is not,
 *  so that a plain run stays within a few minutes on 2 cores. */
benchmark::IterationCount viewsFor(const Model& m, int size, int threads) {
    const bool slow =
        m.model == RayModel::BSpline || (m.model == RayModel::Trilinear && m.step > 0);
    if (size <= 256) return slow ? 30 : kOrbitViews;
    if (threads == 1) return 15;
    return slow ? 10 : 30;
}

void registerAll() {
    benchmark::RegisterBenchmark("BM_LoadCT", BM_LoadCT)
        ->Iterations(1)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    for (const Model& m : kModels) {
        std::vector<ValueMapping> values{ValueMapping::Mu};
        if (m.model == RayModel::Box) values.push_back(ValueMapping::Raw);
        for (ValueMapping val : values) {
            const std::string tag = std::string(m.name) + "/" + valueMappingName(val);
            benchmark::RegisterBenchmark(("BM_Prepare/" + tag).c_str(), BM_Prepare, m, val)
                ->Iterations(1)
                ->Unit(benchmark::kMillisecond)
                ->UseRealTime();
            for (int size : {256, 512})
                for (int threads : {0, 1}) {
                    if (threads == 1 && (size != 512 || m.model != RayModel::Box)) continue;
                    const std::string name = "BM_ConeView/" + tag + "/M" + std::to_string(size) +
                                             (threads == 1 ? "/threads1" : "");
                    benchmark::RegisterBenchmark(name.c_str(), BM_ConeView, m, val, size, threads)
                        ->Iterations(viewsFor(m, size, threads))
                        ->Unit(benchmark::kMillisecond)
                        ->UseRealTime();
                }
        }
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
    if (!std::filesystem::exists(ctPath())) {
        std::fprintf(stderr,
                     "bench_cone: no CT at %s (set FVR_BENCH_CT to a DICOM folder or a volume "
                     "file)\n",
                     ctPath().string().c_str());
        return 2;
    }
    registerAll();
    benchmark::AddCustomContext("fvr_ct", ctPath().string());
    benchmark::AddCustomContext("fvr_geometry", "C-arm orbit, SID 1200 mm, SOD 750 mm, isocentre "
                                                "the volume centre, 4 degrees per view, detector "
                                                "framing the volume");
    benchmark::AddCustomContext("fvr_load_average_at_start", loadAverage());
    try {
        benchmark::RunSpecifiedBenchmarks();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_cone: %s\n", e.what());
        return 1;
    }
    benchmark::Shutdown();
    return 0;
}
