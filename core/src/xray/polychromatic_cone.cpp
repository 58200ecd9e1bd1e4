#include <fvr/core/xray/polychromatic_cone.h>

#include <string>

#include <fvr/core/errors.h>
#include <fvr/core/xray/polychromatic_render.h>

namespace fvr::core {

NoiseModel coneNoiseModel(NoiseModel noise, const ConeCamera& camera) {
    noise.sidMm = camera.sourceToDetector();
    noise.pixelAreaMm2 = camera.pitchU * camera.pitchV;
    return noise;
}

PolychromaticConeProjector::PolychromaticConeProjector(
    const Volume& hu, const MaterialMapping& mapping,
    std::shared_ptr<const SpectralResponse> response, ConeProjectorOptions options,
    const CasterFactory& factory)
    : m_options(options), m_pool(options.threads) {
    m_options.mapping = ValueMapping::Raw; // the densities' line integrals, rho x mm
    m_volumes.resize(mapping.materials.size()); // setResponse checks against their count
    setResponse(std::move(response));
    m_volumes = materialVolumes(hu, mapping, &m_pool);
    for (const Volume& v : m_volumes) {
        if (factory) {
            m_casters.push_back(factory(v, m_options));
            continue;
        }
        m_cpu.push_back(std::make_unique<ConeProjector>(v, m_options));
        ConeProjector* p = m_cpu.back().get();
        m_casters.push_back([p](const ConeCamera& c) { return p->project(c); });
    }
}

PolychromaticConeProjector::~PolychromaticConeProjector() = default;

void PolychromaticConeProjector::setResponse(std::shared_ptr<const SpectralResponse> response) {
    if (!response || response->materials() != m_volumes.size())
        throw SettingsError("polychromatic cone beam: expected a response for " +
                            std::to_string(m_volumes.size()) + " materials");
    m_response = std::move(response);
}

PolychromaticConeFrame PolychromaticConeProjector::project(const ConeCamera& camera,
                                                           const NoiseModel& noise,
                                                           SpectralResponse::Output output,
                                                           const std::vector<float>* flatField) {
    PolychromaticConeFrame frame;
    for (auto& cast : m_casters) {
        DetectorImage img = cast(camera);
        for (float& v : img.pixels) v *= 0.1f; // rho x mm -> g/cm^2
        frame.massThickness.push_back(std::move(img));
    }
    frame.transmission = frame.massThickness.front();
    frame.transmission.mapping = ValueMapping::Raw;
    if (flatField && flatField->size() != frame.transmission.pixels.size())
        throw SettingsError("polychromatic cone beam: the flat field has " +
                            std::to_string(flatField->size()) + " values for " +
                            std::to_string(frame.transmission.pixels.size()) + " pixels");
    std::vector<const float*> rhoL;
    for (const auto& img : frame.massThickness) rhoL.push_back(img.pixels.data());
    frame.spectralSumMs = spectralSumWithNoise(*m_response, rhoL, frame.transmission.pixels,
                                               coneNoiseModel(noise, camera), output, &m_pool,
                                               flatField ? flatField->data() : nullptr);
    return frame;
}

} // namespace fvr::core
