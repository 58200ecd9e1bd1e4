// fvr-render's run: load, preprocess, choose the renderer, then --info, --bench and --out.
#include "run.h"

#include <chrono>
#include <cstdio>

#include <unistd.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/xray/patient_views.h>

#include "cone.h"
#include "input.h"
#include "pacs.h"
#include "polychromatic.h"
#include "session.h"

namespace fvr::cli {

core::RenderParams renderParams(const Options& o, const core::ViewFrame& view,
                                const core::ImageGeometry& geometry) {
    return o.settings.toRenderParams(view, geometry);
}

core::PreprocessOptions preprocessOptions(const Options& o) {
    core::PreprocessOptions po = o.settings.toPreprocessOptions();
    po.threads = o.threads;
    return po;
}

core::ViewFrame baseView(const Options& o, const core::Volume& volume) {
    return o.dirUpGiven ? core::ViewFrame::fromDirUp(o.dir, o.up)
                        : core::patientViewFrame(volume, o.settings.view);
}

core::ImageGeometry imageGeometry(const Options& o, const core::Volume& volume) {
    return o.settings.imageGeometry(volume);
}

core::RenderParams Session::params(const core::ViewFrame& view) const {
    return renderParams(options, view, geometry);
}

RunFacts Session::facts() const {
    return RunFacts{options, *spectrum, geometry.pixelSize, threads, backend.name()};
}

Options resolvedForVolume(const Options& asked, const core::Volume& volume) {
    // Attenuation only for Hounsfield data: others integrate their raw values (said when the
    // values were asked for; the sidecar records what was used).
    Options o = asked;
    std::string note;
    o.settings = asked.settings.forVolume(volume, &note);
    if (!note.empty() && o.beerLambert)
        throw core::SettingsError("--beer-lambert: " + note +
                                  ", and a transmission needs attenuation");
    if (!note.empty() && o.valuesGiven)
        std::fprintf(stderr, "fvr-render: warning: --values %s: %s\n",
                     core::valueMappingName(asked.settings.values), note.c_str());
    return o;
}

namespace {

using namespace fvr::core;

/** The volume's spectrum, with a progress line on a terminal; `ms` gets the time it took. */
std::shared_ptr<const Spectrum> preprocessVolume(const Options& o, const Volume& volume,
                                                 double& ms) {
    const PreprocessOptions po = preprocessOptions(o);
    if (!po.deapodizeFor && o.kaiserBessel())
        std::fprintf(stderr, "fvr-render: warning: kaiser-bessel without deapodization is less "
                             "accurate than trilinear\n");
    const auto t0 = std::chrono::steady_clock::now();
    int lastPct = -1;
    const bool tty = isatty(2);
    auto spectrum = preprocess(volume, po, [&](double f, std::string_view stage) {
        const int pct = int(f * 100);
        if (tty && pct != lastPct) {
            std::fprintf(stderr, "\rpreprocessing %3d%% %-28.*s", pct, int(stage.size()),
                         stage.data());
            lastPct = pct;
        }
    });
    if (tty) std::fprintf(stderr, "\r%60s\r", "");
    ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return spectrum;
}

/** Renders what the options ask for from the loaded volume. */
int renderVolume(const Options& asked, const Volume& volume,
                 const std::vector<ViewFrame>& fileViews, const DicomExportInfo& exportInfo) {
    const Options o = resolvedForVolume(asked, volume);
    const ViewFrame base = baseView(o, volume);
    // The views first: their errors (a sweep along its axis) before the work.
    const std::vector<ViewFrame> views =
        o.out.empty() ? std::vector<ViewFrame>{} : outputViews(o, volume, base, fileViews);
    if (o.polychromatic()) return renderPolychromatic(o, volume, views);
    double preprocessMs = 0.0;
    auto spectrum = preprocessVolume(o, volume, preprocessMs);
    const ImageGeometry geometry = imageGeometry(o, volume);
    auto backend = makeRenderBackend(o, spectrum);
    const Session s{o,        volume,
                    spectrum, preprocessMs,
                    geometry, o.threads > 0 ? o.threads : hardwareThreads(),
                    base,     *backend};
    validateRenderParams(s.params(base));
    if (o.bench > 0) runBench(s);
    if (!o.out.empty()) writeOutputs(s, views, exportInfo);
    return 0;
}

} // namespace

int run(const Options& o) {
    if (o.gpuInfo) {
        printJson(gpuInfoJson());
        return 0;
    }
    if (o.queryGiven) return runQuery(o); // INPUT is a PACS: the matching studies as JSON
    // The views file is read before the input, so that its errors come before the loading.
    const std::vector<ViewFrame> fileViews = !o.out.empty() && !o.viewsFile.empty()
                                                 ? readViewsFile(o.viewsFile)
                                                 : std::vector<ViewFrame>{};
    // So are the matrix file and the X-ray of --geometry-from.
    const ConeFiles coneFiles = o.cone.enabled ? readConeFiles(o) : ConeFiles{};
    const LoadedInput in = loadInput(o);
    for (const auto& w : in.warnings) std::fprintf(stderr, "fvr-render: warning: %s\n", w.c_str());
    if (in.seriesList) { // DICOM folder --info: the series list
        printJson(seriesListJson(*in.seriesList));
        return 0;
    }
    const Volume& volume = *in.volume;
    if (o.info) {
        printJson(volumeInfoJson(volume));
        if (o.out.empty() && o.bench <= 0) return 0;
    }
    if (o.cone.enabled) return renderCone(o, volume, coneFiles, in.exportInfo);
    return renderVolume(o, volume, fileViews, in.exportInfo);
}

} // namespace fvr::cli
