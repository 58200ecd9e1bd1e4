// fvr-render --kvp: materials, one spectrum each, the spectral sum per view, outputs + sidecar.
#include "polychromatic.h"

#include <chrono>
#include <cmath>
#include <cstdio>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/xray/polychromatic_render.h>

#include "backend.h"
#include "json_output.h"
#include "output_files.h"

namespace fvr::cli {

using namespace fvr::core;

namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace

Json polychromaticJson(const Options& o, const TubeSpectrum& s, const SpectralResponse& r,
                       const NoiseModel& noise) {
    return Json{
        {"kvp", *o.kvp},
        {"spectrum_model", "TASMIP (Boone and Seibert 1997), 1-keV bins"},
        {"filtration_al_mm", o.filtrationAlMm},
        {"filtration_cu_mm", o.filtrationCuMm},
        {"hvl_al_mm", halfValueLayerAlMm(s)},
        {"mean_energy_kev", s.meanEnergy()},
        {"air_kerma_ugy_per_mas_at_1m", airKerma(s)},
        {"detector", o.detector.kind == DetectorKind::EnergyIntegrating ? "energy" : "counting"},
        {"csi_um", o.detector.csiUm},
        {"material_mapping", "smoothstep ramps, density from attenuation at 70 keV"},
        {"noise_mas", o.noiseMas},
        {"electronic_noise_quanta", o.electronicNoise},
        {"noise_quanta_per_pixel", noise.active() ? Json(unattenuatedQuanta(r, noise)) : Json()},
        {"seed", o.seed},
        {"material_out", o.materialOut}};
}

namespace {

std::string numbered(const std::string& out, std::size_t i) {
    const std::filesystem::path p(out);
    char num[32];
    std::snprintf(num, sizeof num, "_%04zu", i);
    return (p.parent_path() / (p.stem().string() + num + p.extension().string())).string();
}

/** Writes view i's I/I0 (staged in `files`): .npy/.pfm as is, .png as -ln(I/I0) auto-windowed
 *  (bone white). Returns its final path. */
std::string writeView(const Options& o, OutputFiles& files, std::size_t i, std::size_t count,
                      const PolychromaticImages& img) {
    const int W = img.width, H = img.height;
    ProjectionImage check;
    check.pixels = img.transmission;
    core::checkFiniteImage(check); // never a NaN in a file
    const std::string final = count > 1 ? numbered(o.out, i) : o.out;
    const std::filesystem::path path = files.staged(final);
    if (o.format == OutputFormat::Png) {
        std::vector<float> logs = img.transmission;
        negativeLogInPlace(logs);
        writePng(path, logs.data(), H, W, autoWindow(logs), o.bitDepth);
    } else if (o.format == OutputFormat::Pfm) {
        writePfm(path, img.transmission.data(), H, W);
    } else {
        writeNpy(path, img.transmission.data(), H, W);
    }
    return final;
}

void writeMaterials(const Options& o, OutputFiles& files, const PolychromaticImages& img) {
    std::vector<float> stack;
    for (const auto& m : img.materials) stack.insert(stack.end(), m.begin(), m.end());
    writeNpy(files.staged(o.materialOut), stack.data(), img.height, img.width,
             std::int64_t(img.materials.size()));
}

/** Renders and writes every view (several .npy views: one (n, H, W) stack, as without --kvp,
 *  unless --numbered); view i has its own noise seed (seed + i). */
RenderedPolychromatic renderViews(const Options& o, OutputFiles& files, std::size_t count,
                                  int width, int height, const PolychromaticViewFn& view) {
    RenderedPolychromatic out;
    out.stacked = count > 1 && o.format == OutputFormat::Npy && !o.numbered;
    std::unique_ptr<NpyStackWriter> stack;
    if (out.stacked)
        stack = std::make_unique<NpyStackWriter>(files.staged(o.out), height, width,
                                                 std::int64_t(count));
    const auto t0 = std::chrono::steady_clock::now();
    for (std::size_t i = 0; i < count; ++i) {
        const PolychromaticImages img = view(i, o.seed + i, !o.materialOut.empty());
        out.spectralSumMs += img.spectralSumMs / double(count);
        if (stack)
            stack->add(img.transmission.data());
        else
            out.files.push_back(writeView(o, files, i, count, img));
        if (!o.materialOut.empty()) writeMaterials(o, files, img);
        if (InterruptGuard::signal() != 0) // the staged files go: all or nothing
            throw Interrupted("interrupted after view " + std::to_string(i + 1) + " of " +
                              std::to_string(count) + ": " + o.out +
                              " not written (nothing of this run is kept; an earlier run's "
                              "files stay as they were)");
    }
    if (stack) {
        stack->finish();
        out.files.push_back(o.out);
    }
    out.msPerView = msSince(t0) / double(count);
    return out;
}

/** What the sidecar records of a run besides the options and the views. */
struct RunRecord {
    std::vector<std::shared_ptr<const Spectrum>> spectra;
    double preprocessMs = 0.0, pixelSize = 0.0;
    int threads = 0;
    std::string backendName;
    bool gpuSum = false;
};

/** The sidecar FILE.json of a rendered run. */
Json sidecar(const Options& o, const Volume& volume, const std::vector<ViewFrame>& views,
             const RunRecord& run, const RenderedPolychromatic& rendered,
             const TubeSpectrum& spectrum, const SpectralResponse& response,
             const NoiseModel& noise) {
    const WrittenOutput output{"I/I0 (polychromatic, relative to the unattenuated beam)",
                               rendered.stacked, rendered.files, run.preprocessMs,
                               rendered.msPerView};
    Json j =
        sidecarJson(RunFacts{o, *run.spectra.front(), run.pixelSize, run.threads, run.backendName},
                    volume, output, views);
    Json names = Json::array();
    for (Material m : o.materials) names.push_back(materialNistName(m));
    j["settings"]["values"] = "materials"; // one spectrum of densities (g/cm^3) per material
    j["settings"]["materials"] = names;
    j["settings"]["memory_spectra_mb"] =
        double(run.spectra.front()->bytes()) * double(run.spectra.size()) / (1 << 20);
    j["settings"]["polychromatic"] = polychromaticJson(o, spectrum, response, noise);
    j["output"]["spectral_sum_ms_per_view"] = rendered.spectralSumMs;
    j["output"]["spectral_sum_on"] = run.gpuSum ? "gpu" : "cpu";
    return j;
}

} // namespace

void checkPolychromaticRun(const Options& o, const Volume& volume, std::size_t views) {
    if (volume.units != ValueUnits::HounsfieldUnits)
        throw SettingsError(std::string("--kvp: the materials come from CT numbers, but INPUT "
                                        "holds ") +
                            unitsName(volume.units) + " (needs HU)");
    if (!o.materialOut.empty() && views != 1)
        throw SettingsError("--material-out: needs one view (found " + std::to_string(views) + ")");
}

int renderPolychromatic(const Options& o, const Volume& volume,
                        const std::vector<ViewFrame>& views) {
    if (views.empty()) return 0; // --info alone
    checkPolychromaticRun(o, volume, views.size());
    const TubeSpectrum spectrum = tubeSpectrum(*o.kvp, o.filtrationAlMm, o.filtrationCuMm);
    auto response = std::make_shared<SpectralResponse>(spectrum, o.detector, o.materials);
    PreprocessOptions po = o.settings.toPreprocessOptions(); // preprocessMaterials maps raw
    po.threads = o.threads;
    RunRecord run;
    const auto t0 = std::chrono::steady_clock::now();
    run.spectra = preprocessMaterials(volume, {o.materials, 70.0}, po);
    run.preprocessMs = msSince(t0);
    run.threads = o.threads > 0 ? o.threads : hardwareThreads();
    auto renderers = makeMaterialRenderers(o, run.spectra, run.backendName);
    // On the GPU the spectral sum runs there too (one read-back per view); else on the CPU.
    PolychromaticFrameFn frame = gpuPolychromaticFrames(renderers, response);
    run.gpuSum = bool(frame);
    PolychromaticRenderer poly(std::move(renderers), response, run.threads);
    if (!frame)
        frame = [&poly](const RenderParams& p, const NoiseModel& n, bool) {
            return poly.render(p, n);
        };
    const ImageGeometry geometry = o.settings.imageGeometry(volume);
    const double d = run.pixelSize = geometry.pixelSize;
    const NoiseModel noise{o.noiseMas, 1000.0, d * d, o.electronicNoise, o.seed};
    const int W = geometry.cols(), H = geometry.rows();
    auto view = [&](std::size_t i, std::uint64_t seed, bool materials) {
        NoiseModel n = noise;
        n.seed = seed;
        PolychromaticFrame f = frame(o.settings.toRenderParams(views[i], geometry), n, materials);
        PolychromaticImages img{W, H, std::move(f.transmission.pixels), {}, f.spectralSumMs};
        for (auto& m : f.massThickness) img.materials.push_back(std::move(m.pixels));
        return img;
    };
    writePolychromaticRun(
        o, views.size(), W, H, view,
        [&](const RenderedPolychromatic& rendered) {
            return sidecar(o, volume, views, run, rendered, spectrum, *response, noise);
        },
        [&](const RenderedPolychromatic& rendered) {
            std::fprintf(stderr,
                         "wrote %s (%zu view%s, %dx%d, %g kVp, %zu materials, I/I0; %.2f ms per "
                         "view)\n",
                         rendered.files.front().c_str(), views.size(), views.size() > 1 ? "s" : "",
                         W, H, *o.kvp, o.materials.size(), rendered.msPerView);
        });
    return 0;
}

void writePolychromaticRun(const Options& o, std::size_t count, int width, int height,
                           const PolychromaticViewFn& view,
                           const std::function<Json(const RenderedPolychromatic&)>& sidecar,
                           const std::function<void(const RenderedPolychromatic&)>& summary) {
    InterruptGuard interrupt; // before the first file is staged
    std::string interrupted = "interrupted after the last view"; // the files are complete
    try {
        OutputFiles files(o.out);
        RenderedPolychromatic rendered;
        try { // the messages name the final paths, not the staged ones
            rendered = renderViews(o, files, count, width, height, view);
            writeFileAtomic(files.staged(o.out + ".json"), jsonText(sidecar(rendered)));
        } catch (const WriteError& e) {
            throw WriteError(files.finalNames(e.what()));
        }
        files.commit(); // the images and their sidecar land together
        summary(rendered);
    } catch (const Interrupted& e) {
        interrupted = e.what();
    }
    interrupt.dieIfInterrupted(interrupted);
}

} // namespace fvr::cli
