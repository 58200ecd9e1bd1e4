#pragma once
/** Polychromatic cone beam: one ray caster per material's density volume (materialVolumes), the
 *  Raw line integrals rho x mm turned into mass thicknesses g/cm^2 (x 0.1, as the parallel
 *  polychromatic renderer does), then the same spectral sum and quantum noise as the parallel
 *  frames (spectralSumWithNoise). Ray casting is linear in the voxel values, so each material's
 *  image is its exact line integral under the caster's voxel model. */
#include <functional>
#include <memory>
#include <vector>

#include <fvr/core/geometry/camera.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/volume.h>
#include <fvr/core/xray/polychromatic.h>

namespace fvr::core {

/** One polychromatic cone-beam view. */
struct PolychromaticConeFrame {
    /** I/I0 (noisy when noise is on), or -ln of it when asked for NegativeLog. */
    DetectorImage transmission;
    std::vector<DetectorImage> massThickness; ///< rhoL_m in g/cm^2, per material
    double spectralSumMs = 0.0;
};

/** The noise model of a cone-beam view: the detector's pixels (pitchU x pitchV mm^2) at the
 *  source-to-detector distance of the principal ray (the fluence there: TASMIP's at 1 m times
 *  (1000 / SID)^2); the exposure, electronic noise and seed as given. */
NoiseModel coneNoiseModel(NoiseModel noise, const ConeCamera& camera);

class PolychromaticConeProjector {
public:
    /** One material's ray caster: the line integrals of its density volume (Raw mapping). */
    using MaterialCaster = std::function<DetectorImage(const ConeCamera&)>;
    /** Makes a material's caster from its density volume (which outlives the caster) and the
     *  options (mapping Raw); empty: core::ConeProjector on the CPU. */
    using CasterFactory = std::function<MaterialCaster(const Volume&, const ConeProjectorOptions&)>;

    /** Decomposes the CT numbers of `hu` (Hounsfield units, else SettingsError) by `mapping`
     *  into one density volume per material, and makes a caster for each (options.mapping is
     *  set to Raw). SettingsError when the response's materials are not the mapping's. Memory:
     *  materials x the volume, kept (the CPU casters read them). */
    PolychromaticConeProjector(const Volume& hu, const MaterialMapping& mapping,
                               std::shared_ptr<const SpectralResponse> response,
                               ConeProjectorOptions options = {},
                               const CasterFactory& factory = {});
    ~PolychromaticConeProjector();
    PolychromaticConeProjector(const PolychromaticConeProjector&) = delete;
    PolychromaticConeProjector& operator=(const PolychromaticConeProjector&) = delete;

    /** Swaps the response (kVp, filtration, detector): no decomposition again. SettingsError
     *  for a response of other materials. */
    void setResponse(std::shared_ptr<const SpectralResponse> response);
    std::size_t materials() const { return m_volumes.size(); }
    const ConeProjectorOptions& options() const { return m_options; }
    const SpectralResponse& response() const { return *m_response; }
    /** The density volume (g/cm^3) of material m. */
    const Volume& materialVolume(std::size_t m) const { return m_volumes.at(m); }

    /** One view (validateConeView first): the materials' mass thicknesses, I/I0 with noise
     *  (coneNoiseModel of the camera) where `noise` is active, times `flatField` (one value per
     *  pixel: detectorFlatField) where given, or -ln(I/I0) for NegativeLog. */
    PolychromaticConeFrame project(
        const ConeCamera& camera, const NoiseModel& noise = {},
        SpectralResponse::Output output = SpectralResponse::Output::Transmission,
        const std::vector<float>* flatField = nullptr);

private:
    std::vector<Volume> m_volumes;
    ConeProjectorOptions m_options;
    std::shared_ptr<const SpectralResponse> m_response;
    std::vector<std::unique_ptr<ConeProjector>> m_cpu; ///< the default casters
    std::vector<MaterialCaster> m_casters;
    ThreadPool m_pool;
};

} // namespace fvr::core
