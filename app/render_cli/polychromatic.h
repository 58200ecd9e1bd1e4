#pragma once
/** fvr-render --kvp: the polychromatic run (parallel views here, cone-beam views in
 *  cone_polychromatic.cpp), and what both write with. */
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <fvr/core/render/view.h>
#include <fvr/core/volume.h>
#include <fvr/core/xray/polychromatic.h>

#include "json_output.h"
#include "options.h"

namespace fvr::cli {

/** Preprocesses one spectrum per material, renders `views` (CPU), writes I/I0 (and
 *  --material-out) with the JSON sidecar FILE.json. Returns the exit status. */
int renderPolychromatic(const Options& o, const core::Volume& volume,
                        const std::vector<core::ViewFrame>& views);

/** SettingsError where --kvp cannot run: INPUT without Hounsfield units, --material-out with
 *  more than one view. */
void checkPolychromaticRun(const Options& o, const core::Volume& volume, std::size_t views);

/** The sidecar's "polychromatic" settings: the spectrum, detector, materials and noise
 *  (`noise` as the first view's pixels see it). */
Json polychromaticJson(const Options& o, const core::TubeSpectrum& spectrum,
                       const core::SpectralResponse& response, const core::NoiseModel& noise);

/** One polychromatic view as the writers take it: I/I0 (or its noisy version), W x H, row 0 at
 *  the top, and the materials' mass thicknesses (g/cm^2) when asked for. */
struct PolychromaticImages {
    int width = 0, height = 0;
    std::vector<float> transmission;
    std::vector<std::vector<float>> materials;
    double spectralSumMs = 0.0;
};
/** View i with its noise seed (--seed + i); `materials`: with the mass thicknesses. */
using PolychromaticViewFn =
    std::function<PolychromaticImages(std::size_t i, std::uint64_t seed, bool materials)>;

/** What a run wrote. */
struct RenderedPolychromatic {
    std::vector<std::string> files;
    bool stacked = false;
    double msPerView = 0.0;
    double spectralSumMs = 0.0; ///< per view
};

/** Renders and writes `count` views of width x height (several .npy views: one (n, H, W) stack
 *  unless --numbered; .png: -ln(I/I0) auto-windowed, bone white), --material-out (one view),
 *  then the sidecar FILE.json `sidecar` returns: all or nothing, staged and committed together
 *  (an interrupt leaves nothing). `summary` says what was written. */
void writePolychromaticRun(const Options& o, std::size_t count, int width, int height,
                           const PolychromaticViewFn& view,
                           const std::function<Json(const RenderedPolychromatic&)>& sidecar,
                           const std::function<void(const RenderedPolychromatic&)>& summary);

} // namespace fvr::cli
