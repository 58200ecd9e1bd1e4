#pragma once
/** Polychromatic rendering: one spectrum per material (the same preprocessing, kernel and voxel
 *  model as a monochromatic study), per frame one slice and inverse transform per material, then
 *  the spectral sum (polychromatic.h). Fourier rendering is linear, so each material's image is
 *  its exact line integral up to the renderer's own interpolation error. */
#include <memory>
#include <vector>

#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/renderer.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/volume.h>
#include <fvr/core/xray/polychromatic.h>

namespace fvr::core {

/** One volume per material of the mapping, each voxel the material's density rho_m (g/cm^3)
 *  from the CT number (MaterialDecomposer); `hu` must hold Hounsfield units (SettingsError
 *  otherwise). Memory: materials x the volume. */
std::vector<Volume> materialVolumes(const Volume& hu, const MaterialMapping& mapping,
                                    ThreadPool* pool = nullptr);

/** Preprocesses each material volume with the same options (Raw mapping: the line integrals
 *  are rho x mm; the polychromatic renderer turns them into g/cm^2). Progress spans all of them.
 *  Memory: one spectrum per material (spectrumBytes(padded) each). */
std::vector<std::shared_ptr<const Spectrum>> preprocessMaterials(
    const Volume& hu, const MaterialMapping& mapping, PreprocessOptions options,
    const ProgressFn& progress = {}, const CancelToken* cancel = nullptr);

/** The step every polychromatic image shares (the parallel renderer's and the cone beam's):
 *  `out` (sized by the caller: the pixels of rhoL) gets I/I0 of the materials' mass thicknesses
 * rhoL (g/cm^2) through the response, multiplied by `gain` where given (a detector's flat field:
 * the open beam's relative intensity per pixel), then quantum noise where `noise` is active (its
 * pixel area and SID as the caller states them), or -ln of that when `output` is NegativeLog (from
 * the table without noise). Runs on `pool` (null: this thread). Returns the spectral sum's time in
 * ms (noise excluded). */
double spectralSumWithNoise(const SpectralResponse& response, const std::vector<const float*>& rhoL,
                            std::vector<float>& out, const NoiseModel& noise,
                            SpectralResponse::Output output, ThreadPool* pool = nullptr,
                            const float* gain = nullptr);

/** What the polychromatic frame returns besides I/I0. */
struct PolychromaticFrame {
    /** I/I0 (noisy when noise is on), or -ln of it when render() was asked for NegativeLog. */
    ProjectionImage transmission;
    std::vector<ProjectionImage> massThickness; ///< rhoL_m in g/cm^2, per material
    double spectralSumMs = 0.0;
};

/** Renders with one renderer per material, then applies the response (and noise). */
class PolychromaticRenderer {
public:
    PolychromaticRenderer(std::vector<std::unique_ptr<Renderer>> perMaterial,
                          std::shared_ptr<const SpectralResponse> response, int threads = 0);
    /** Swaps the response (kVp, filtration, detector): no preprocessing again. */
    void setResponse(std::shared_ptr<const SpectralResponse> response);
    const SpectralResponse& response() const { return *m_response; }
    std::size_t materials() const { return m_renderers.size(); }

    /** The frame; times (if given) sum the materials' stages, and totalMs includes the sum.
     *  `output` NegativeLog: the display's -ln(I/I0), read from the table without noise (no
     *  exp and log per pixel), or taken of the noisy I/I0. */
    PolychromaticFrame render(
        const RenderParams& params, const NoiseModel& noise = {}, StageTimes* times = nullptr,
        SpectralResponse::Output output = SpectralResponse::Output::Transmission);

private:
    std::vector<std::unique_ptr<Renderer>> m_renderers;
    std::shared_ptr<const SpectralResponse> m_response;
    ThreadPool m_pool;
};

} // namespace fvr::core
