// Simulated X-rays for registration tests and benchmarks (registration/simulated_xray.h).
#include <fvr/core/registration/simulated_xray.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include <fvr/core/errors.h>
#include <fvr/core/registration/pose.h>
#include <fvr/core/xray/polychromatic_cone.h>
#include <fvr/core/xray/spectrum_model.h>

namespace fvr::core {

void gaussianBlur(std::vector<float>& image, int width, int height, double sigma) {
    if (sigma <= 0.0) return;
    const int r = std::max(1, int(std::ceil(3.0 * sigma)));
    std::vector<double> k(std::size_t(2 * r + 1));
    double sum = 0.0;
    for (int i = -r; i <= r; ++i)
        sum += k[std::size_t(i + r)] = std::exp(-0.5 * i * i / (sigma * sigma));
    for (double& w : k) w /= sum;
    std::vector<float> tmp(image.size());
    for (int y = 0; y < height; ++y) // rows
        for (int x = 0; x < width; ++x) {
            double acc = 0.0;
            for (int i = -r; i <= r; ++i)
                acc += k[std::size_t(i + r)] *
                       image[std::size_t(y) * width + std::clamp(x + i, 0, width - 1)];
            tmp[std::size_t(y) * width + x] = float(acc);
        }
    for (int y = 0; y < height; ++y) // columns
        for (int x = 0; x < width; ++x) {
            double acc = 0.0;
            for (int i = -r; i <= r; ++i)
                acc += k[std::size_t(i + r)] *
                       tmp[std::size_t(std::clamp(y + i, 0, height - 1)) * width + x];
            image[std::size_t(y) * width + x] = float(acc);
        }
}

std::vector<float> simulateXray(const Volume& ct, const ConeCamera& camera, const glm::dmat4& T,
                                const XraySimulation& simulation) {
    if (ct.units != ValueUnits::HounsfieldUnits)
        throw SettingsError("simulated X-ray: the CT must hold Hounsfield units");
    Volume shifted = ct;
    for (float& v : shifted.voxels) v += float(simulation.huOffset);
    const MaterialMapping mapping;
    auto response = std::make_shared<SpectralResponse>(tubeSpectrum(simulation.kvp, 2.5),
                                                       DetectorModel{}, mapping.materials);
    ConeProjectorOptions options;
    options.model = RayModel::Box;
    options.threads = simulation.threads;
    PolychromaticConeProjector poly(shifted, mapping, response, options);
    const ConeCamera posed = posedCamera(camera, T);
    NoiseModel noise;
    noise.mAs = simulation.mAs;
    noise.seed = simulation.seed;
    PolychromaticConeFrame frame = poly.project(posed, noise);
    std::vector<float> image = std::move(frame.transmission.pixels);
    // Blur the intensities (the detector spreads light, not line integrals), then -ln.
    gaussianBlur(image, camera.width, camera.height, simulation.blurPixels);
    for (float& v : image) v = -std::log(std::max(v, 1e-6f));
    return image;
}

} // namespace fvr::core
