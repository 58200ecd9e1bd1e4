/**
 * Polychromatic X-ray frames on the CPU, on the chest phantom (160^3, 420 mm) at
 * M = 512, AP view:
 *   BM_MonoFrame        one monochromatic frame (one spectrum, mu mapping), for comparison
 *   BM_PolyFrame/k      the polychromatic frame: k material frames + the spectral sum
 *                       (k = 3: air, soft, bone; TASMIP 80 kV + 2.5 mm Al, energy-integrating)
 *   BM_SpectralSum/t    the spectral sum alone on the frame's material images, t threads
 *   BM_ExactSum         the same sum in double over the 1-keV bins, per pixel (one thread)
 * Counter ms = wall time per iteration (UseRealTime).
 */
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <vector>

#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/xray/polychromatic_render.h>

using namespace fvr::core;

namespace {

constexpr int kM = 512;

struct Setup {
    Volume volume = makeChestPhantomVolume(160);
    MaterialMapping mapping;
    TubeSpectrum spectrum = tubeSpectrum(80.0, 2.5);
    std::shared_ptr<SpectralResponse> response =
        std::make_shared<SpectralResponse>(spectrum, DetectorModel{}, mapping.materials);
    std::vector<std::shared_ptr<const Spectrum>> spectra;
    std::shared_ptr<const Spectrum> mono;
    RenderParams params;
    Setup() {
        PreprocessOptions po;
        po.effort = PlannerEffort::Estimate;
        spectra = preprocessMaterials(volume, mapping, po);
        po.mapping = ValueMapping::Mu;
        mono = preprocess(volume, po);
        params = RenderParams{ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1}),
                              {kM, defaultPixelSize(volume.dims, volume.spacing, kM)}};
        params.voxelModel = VoxelModel::Trilinear;
        params.clipToVolume = true;
        params.nonNegative = true;
    }
    std::unique_ptr<PolychromaticRenderer> poly() const {
        std::vector<std::unique_ptr<Renderer>> r;
        for (const auto& s : spectra) r.push_back(std::make_unique<CpuFourierRenderer>(s));
        return std::make_unique<PolychromaticRenderer>(std::move(r), response);
    }
};

const Setup& setup() {
    static const Setup s;
    return s;
}

void BM_MonoFrame(benchmark::State& state) {
    CpuFourierRenderer r(setup().mono);
    r.render(setup().params); // plans
    for (auto _ : state) benchmark::DoNotOptimize(r.render(setup().params).pixels.data());
}

void BM_PolyFrame(benchmark::State& state) {
    auto poly = setup().poly();
    poly->render(setup().params);
    double sum = 0.0;
    for (auto _ : state) {
        const auto f = poly->render(setup().params);
        sum += f.spectralSumMs;
        benchmark::DoNotOptimize(f.transmission.pixels.data());
    }
    state.counters["spectral_sum_ms"] = sum / double(state.iterations());
}

void BM_SpectralSum(benchmark::State& state) {
    const auto frame = setup().poly()->render(setup().params);
    std::vector<const float*> rhoL;
    for (const auto& img : frame.massThickness) rhoL.push_back(img.pixels.data());
    std::vector<float> out(std::size_t(kM) * kM);
    ThreadPool pool(int(state.range(0)));
    for (auto _ : state) {
        setup().response->apply(rhoL, out.data(), std::int64_t(out.size()), &pool);
        benchmark::DoNotOptimize(out.data());
    }
}

void BM_ExactSum(benchmark::State& state) {
    const auto frame = setup().poly()->render(setup().params);
    std::vector<float> out(std::size_t(kM) * kM);
    for (auto _ : state) {
        for (std::size_t p = 0; p < out.size(); ++p) {
            double d[3];
            for (int m = 0; m < 3; ++m) d[m] = frame.massThickness[std::size_t(m)].pixels[p];
            out[p] = float(setup().response->exact(d));
        }
        benchmark::DoNotOptimize(out.data());
    }
}

} // namespace

BENCHMARK(BM_MonoFrame)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_PolyFrame)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SpectralSum)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ExactSum)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);
BENCHMARK_MAIN();
