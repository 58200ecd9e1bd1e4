// fvr-render --bench: stage timings of the Fourier renderer and the same views by ray casting.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <vector>

#include <fvr/core/render/image_metrics.h>
#include <fvr/core/render/spatial_projector.h>

#include "cone.h"
#include "session.h"

namespace fvr::cli {
namespace {

using namespace fvr::core;

struct Stat {
    double median, p95;
};

Stat stats(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    auto q = [&](double f) {
        return v[std::min(v.size() - 1, std::size_t(std::ceil(f * v.size())) - 1)];
    };
    return {v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]),
            q(0.95)};
}

Json statJson(const Stat& s) { return Json{{"median_ms", s.median}, {"p95_ms", s.p95}}; }

Json rateJson(const Stat& s) {
    Json j = statJson(s);
    j["fps"] = 1000.0 / s.median;
    return j;
}

/** Views over a cone of directions, so the spectrum is read along varied planes. */
ViewFrame benchView(const Session& s, int i) {
    return s.base.rotated({0.3, 1.0, 0.2}, 2.0 * std::numbers::pi * i / s.options.bench);
}

/** The same views by ray casting (the spatial reference projector, all cores), in this run,
 *  with the same voxel model, depth cueing and pixel sampling, and the accuracy against it.
 *  It cannot apply the slice filters: said in a note, and then only the timings compare. */
void addRayCasting(const Session& s, double fvrMs, Json& j) {
    const Options& o = s.options;
    const SpatialProjectorOptions spo =
        matchingProjectorOptions(s.params(s.base), o.settings.values, o.threads);
    SpatialProjector sp(s.volume, spo);
    std::vector<double> spatialMs;
    Json psnr = Json::array(), lowest = Json::array();
    const int spatialViews = std::min(o.bench, 3);
    for (int i = 0; i < spatialViews; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        const ProjectionImage ref = sp.project(benchView(s, i), s.geometry);
        spatialMs.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
        const ProjectionImage img = s.backend.renderer().render(s.params(benchView(s, i)));
        // Identical images have an infinite PSNR: written as null.
        psnr.push_back(std::round(compareImages(img.pixels, ref.pixels).psnr * 100) / 100);
        lowest.push_back(std::round(mostNegativeFraction(img.pixels) * 1e5) / 1e3);
    }
    const Stat st = stats(spatialMs);
    j["spatial_projector"] = {{"median_ms", st.median},
                              {"views", spatialViews},
                              {"reference", describeProjector(spo, o.settings.voxelModel)}};
    j["speedup_per_view"] = st.median / fvrMs;
    if (o.settings.filter.active())
        j["note"] =
            "the spatial projector cannot apply the slice filter (--sharpen, --band-limit): "
            "it ray-casts unfiltered images, so only the timings compare, not the images";
    else
        j["accuracy"] = {{"psnr_db", psnr}, {"most_negative_percent", lowest}};
}

} // namespace

void runBench(const Session& s) {
    const BenchFrames f = s.backend.timeFrames(
        s.params(s.base), [&](int i) { return s.params(benchView(s, i)); }, s.options.bench);
    const Stat total = stats(f.total);
    Json j{{"settings", settingsJson(s.facts())},
           {"frames", s.options.bench},
           {"preprocess", statJson({s.preprocessMs, s.preprocessMs})},
           {"slice", statJson(stats(f.slice))},
           {"inverse", statJson(stats(f.inverse))},
           {"total", rateJson(total)}};
    double fvrMs = total.median;
    if (!f.fusedTotal.empty()) {
        const Stat fused = stats(f.fusedTotal);
        fvrMs = fused.median;
        j["total_fused"] = rateJson(fused);
        j["total_fused"]["passes"] = std::string("slice+row FFT, column FFT") +
                                     (s.spectrum->kind == TransformKind::Fht ? ", eq. 4" : "") +
                                     "+display";
    }
    addRayCasting(s, fvrMs, j);
    printJson(j);
}

void runConeBench(const ConeSession& s, const std::vector<ConeView>& views) {
    const std::vector<ConeView> benchViews = coneBenchViews(s, views); // checked first
    std::vector<double> ms;
    for (const ConeView& v : benchViews) {
        const auto t0 = std::chrono::steady_clock::now();
        const DetectorImage img = s.caster.project(v.camera);
        ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
    }
    const ConeCamera& c = benchViews.front().camera;
    Json j{{"settings", coneSettingsJson(s)},
           {"frames", s.options.bench},
           {"detector", Json::array({c.width, c.height})},
           {"prepare", statJson({s.prepareMs, s.prepareMs})},
           {"ray_cast", rateJson(stats(ms))},
           {"views_ms", ms},
           {"first_view", coneViewJson(benchViews.front())}};
    printJson(j);
}

} // namespace fvr::cli
