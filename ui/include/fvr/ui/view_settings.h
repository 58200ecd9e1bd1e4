#pragma once
/** What a projection view renders, as plain data: its own settings (the compare mode gives each
 *  view its own), the per-frame effects all views share, and the polychromatic output's source.
 *  Qt-free (core headers only): the panels, the settings model and the main window fill these
 *  in, ProjectionView reads them. */
#include <memory>
#include <vector>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/polychromatic.h>

namespace fvr::ui {

/** Per-view render settings (the compare mode gives each view its own); the defaults are
 *  core::RenderSettings'. */
struct ViewSettings {
    core::Kernel kernel = core::RenderSettings{}.kernel;
    int size = core::RenderSettings{}.size;
    core::VoxelModel voxelModel = core::RenderSettings{}.voxelModel; ///< RenderParams::voxelModel
    bool operator==(const ViewSettings&) const = default;
};

/** Per-frame image effects shared by all views: the pixel aperture, depth cueing, the slice
 *  filters (xray.h) and what the last pass removes. */
struct FrameEffects {
    bool pixelAperture = core::RenderSettings{}.pixelAperture; ///< RenderParams::pixelAperture
    double depthCue = core::RenderSettings{}.depthCue;
    core::SliceFilter filter = core::RenderSettings{}.filter;
    /** Zero outside the volume's shadow (RenderParams::clipToVolume). */
    bool clip = core::RenderSettings{}.clip;
    /** Never below 0 for a non-negative volume (RenderParams::nonNegative). */
    bool nonNegative = core::RenderSettings{}.nonNegative;
    bool operator==(const FrameEffects&) const = default;
};

/** What the polychromatic output renders: the material spectra (shared by the views), the
 *  spectral response (kVp, filtration, detector), the noise and what the view shows. */
struct PolychromaticSource {
    std::vector<std::shared_ptr<const core::Spectrum>> spectra;
    std::shared_ptr<const core::SpectralResponse> response;
    core::NoiseModel noise;
    int show = -1; ///< -1: -ln(I/I0); m: material m's mass thickness (g/cm^2)
};

} // namespace fvr::ui
