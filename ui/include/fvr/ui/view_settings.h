#pragma once
/** What a projection view renders, as plain data: its own settings (the compare mode gives each
 *  view its own), the per-frame effects all views share, and the polychromatic output's source.
 *  Qt-free (core headers only): the panels, the settings model and the main window fill these
 *  in, ProjectionView reads them. */
#include <memory>
#include <vector>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/polychromatic.h>

namespace fvr::ui {

/** Per-view render settings (the compare mode gives each view its own). */
struct ViewSettings {
    core::Kernel kernel = core::Kernel::CatmullRom;
    int size = 512;
    core::VoxelModel voxelModel = core::VoxelModel::Trilinear; ///< RenderParams::voxelModel
    bool operator==(const ViewSettings&) const = default;
};

/** Per-frame image effects shared by all views: the pixel aperture, depth cueing, the slice
 *  filters (xray.h) and what the last pass removes. */
struct FrameEffects {
    bool pixelAperture = false; ///< RenderParams::pixelAperture
    double depthCue = 0.0;
    core::SliceFilter filter;
    bool clip = true; ///< zero outside the volume's shadow (RenderParams::clipToVolume)
    bool nonNegative =
        true; ///< never below 0 for a non-negative volume (RenderParams::nonNegative)
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
