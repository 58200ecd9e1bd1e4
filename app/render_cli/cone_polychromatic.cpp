// fvr-render --geometry cone --kvp: one ray caster per material (the CPU's, or the GPU's per
// --backend), the spectral sum and noise per view (core::PolychromaticConeProjector), the
// writers and sidecar of the parallel --kvp run with the cone beam's camera blocks.
#include "cone_polychromatic.h"

#include <chrono>
#include <cstdio>

#include <fvr/core/errors.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/xray/polychromatic_cone.h>

#include "polychromatic.h"

namespace fvr::cli {

using namespace fvr::core;

namespace {

/** The casters of the materials, made by --backend's rule; after one material's fell back to
 *  the CPU (said once on stderr), the others are made there without asking again. */
struct MaterialCasters {
    const Options& options;
    Options::Backend backend;
    std::vector<std::unique_ptr<ConeCaster>> casters;

    PolychromaticConeProjector::MaterialCaster make(const Volume& v,
                                                    const ConeProjectorOptions& po) {
        Options o = options;
        o.backend = backend;
        casters.push_back(makeConeCaster(o, v, po));
        if (casters.back()->name() == "cpu") backend = Options::Backend::Cpu;
        ConeCaster* c = casters.back().get();
        return [c](const ConeCamera& camera) { return c->project(camera); };
    }
};

/** The sidecar: the cone beam's (settings, volume, image, views: the camera and P) with the
 *  polychromatic settings of the parallel --kvp run. */
Json sidecar(const ConeSession& s, const std::vector<ConeView>& views,
             const RenderedPolychromatic& rendered, const TubeSpectrum& spectrum,
             const SpectralResponse& response, const NoiseModel& noise) {
    const Options& o = s.options;
    const WrittenOutput output{"I/I0 (polychromatic, relative to the unattenuated beam)",
                               rendered.stacked, rendered.files, s.prepareMs, rendered.msPerView};
    Json j = coneSidecarJson(s, output, views);
    Json names = Json::array();
    for (Material m : o.materials) names.push_back(materialNistName(m));
    j["settings"]["values"] = "materials"; // one volume of densities (g/cm^3) per material
    j["settings"]["materials"] = names;
    j["settings"]["polychromatic"] = polychromaticJson(o, spectrum, response, noise);
    j["settings"]["polychromatic"]["noise_pixel"] =
        "the detector's pitch at its source-to-detector distance (fluence x (1000 mm / SID)^2)";
    j["output"]["spectral_sum_ms_per_view"] = rendered.spectralSumMs;
    j["output"]["spectral_sum_on"] = "cpu";
    return j;
}

} // namespace

int renderConePolychromatic(const Options& o, const Volume& volume,
                            const std::vector<ConeView>& views, const ConeFiles& files) {
    checkPolychromaticRun(o, volume, views.size());
    if (o.out.empty()) return 0; // --info alone (--bench is refused with --kvp)
    const TubeSpectrum spectrum = tubeSpectrum(*o.kvp, o.filtrationAlMm, o.filtrationCuMm);
    auto response = std::make_shared<SpectralResponse>(spectrum, o.detector, o.materials);
    const auto t0 = std::chrono::steady_clock::now();
    MaterialCasters made{o, o.backend, {}};
    PolychromaticConeProjector poly(
        volume, {o.materials, 70.0}, response, coneProjectorOptions(o),
        [&made](const Volume& v, const ConeProjectorOptions& po) { return made.make(v, po); });
    const double prepareMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const ConeSession s{o,
                        volume,
                        *made.casters.front(),
                        prepareMs,
                        o.threads > 0 ? o.threads : hardwareThreads(),
                        &files};
    const NoiseModel noise{o.noiseMas, 1000.0, 1.0, o.electronicNoise, o.seed};
    auto view = [&](std::size_t i, std::uint64_t seed, bool) {
        const ConeCamera& camera = views[i].camera;
        NoiseModel n = noise;
        n.seed = seed;
        std::vector<float> flat;
        if (o.cone.flatField) flat = detectorFlatField(camera);
        PolychromaticConeFrame f = poly.project(camera, n, SpectralResponse::Output::Transmission,
                                                o.cone.flatField ? &flat : nullptr);
        PolychromaticImages img{
            camera.width, camera.height, std::move(f.transmission.pixels), {}, f.spectralSumMs};
        for (auto& m : f.massThickness) img.materials.push_back(std::move(m.pixels));
        return img;
    };
    const ConeCamera& first = views.front().camera;
    writePolychromaticRun(
        o, views.size(), first.width, first.height, view,
        [&](const RenderedPolychromatic& rendered) {
            return sidecar(s, views, rendered, spectrum, *response, coneNoiseModel(noise, first));
        },
        [&](const RenderedPolychromatic& rendered) {
            std::fprintf(stderr,
                         "wrote %s (%zu view%s, %dx%d, pitch %.4g x %.4g mm, cone beam, %s, "
                         "%g kVp, %zu materials, I/I0, %s; %.2f ms per view)\n",
                         rendered.files.front().c_str(), views.size(), views.size() > 1 ? "s" : "",
                         first.width, first.height, first.pitchU, first.pitchV,
                         s.caster.description().c_str(), *o.kvp, o.materials.size(),
                         s.caster.name().c_str(), rendered.msPerView);
        });
    return 0;
}

} // namespace fvr::cli
