#pragma once
/** What a projection view renders, as plain data: its own settings (the compare mode gives each
 *  view its own), the per-frame effects all views share, and the polychromatic output's source.
 *  Qt-free (core headers only): the panels, the settings model and the main window fill these
 *  in, ProjectionView reads them. */
#include <memory>
#include <vector>

#include <fvr/core/render/cone_projector.h>
#include <fvr/core/render/kernels.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/polychromatic.h>

namespace fvr::ui {

/** How a view projects: the Fourier renderers' parallel beam, or a C-arm's cone beam ray cast
 *  on the CPU (core::ConeProjector). */
enum class ProjectionKind { Parallel, Cone };

/** The cone beam's C-arm, less its angles: those are the view frame's (core::cArmAngles), so
 *  that dragging, the synchronised views and the compare mode share one orientation. */
struct ConeSettings {
    double sid = 1000.0; ///< source to detector, mm
    double sod = 750.0; ///< source to isocentre (the volume's centre), mm
    core::RayModel model = core::ConeProjectorOptions{}.model;
    bool operator==(const ConeSettings&) const = default;
};

/** Per-view render settings (the compare mode gives each view its own); the defaults are
 *  core::RenderSettings'. */
struct ViewSettings {
    core::Kernel kernel = core::RenderSettings{}.kernel;
    int size = core::RenderSettings{}.size;
    core::VoxelModel voxelModel = core::RenderSettings{}.voxelModel; ///< RenderParams::voxelModel
    ProjectionKind projection = ProjectionKind::Parallel;
    ConeSettings cone;
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
    core::NoiseModel noise; ///< on -ln(I/I0) only (none on a material's mass thickness)
    int show = -1; ///< -1: -ln(I/I0); m: material m's mass thickness (g/cm^2)
    // The tube the response was made for (what the overlay and the exports say).
    double kvp = 0.0;
    double filtrationAlMm = 0.0;
    double filtrationCuMm = 0.0;
};

} // namespace fvr::ui
