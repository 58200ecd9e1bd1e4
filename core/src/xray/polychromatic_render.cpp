#include <fvr/core/xray/polychromatic_render.h>

#include <chrono>
#include <string>

#include <fvr/core/errors.h>

namespace fvr::core {

std::vector<Volume> materialVolumes(const Volume& hu, const MaterialMapping& mapping,
                                    ThreadPool* pool) {
    if (hu.units != ValueUnits::HounsfieldUnits)
        throw SettingsError(
            std::string("materials: the volume must hold Hounsfield units, found ") +
            unitsName(hu.units));
    const MaterialDecomposer decomposer(mapping);
    const std::size_t k = decomposer.size();
    std::vector<Volume> out(k);
    for (Volume& v : out) {
        v.dims = hu.dims;
        v.spacing = hu.spacing;
        v.origin = hu.origin;
        v.direction = hu.direction;
        v.orientationStated = hu.orientationStated;
        v.units = ValueUnits::Unknown;
        v.voxels.assign(hu.voxels.size(), 0.0f);
    }
    for (std::size_t m = 0; m < k; ++m)
        out[m].name = hu.name + " [" + materialKey(mapping.materials[m]) + "]";
    auto run = [&](std::int64_t begin, std::int64_t end) {
        std::vector<double> rho(k);
        for (std::int64_t i = begin; i < end; ++i) {
            decomposer.densities(hu.voxels[std::size_t(i)], rho.data());
            for (std::size_t m = 0; m < k; ++m) out[m].voxels[std::size_t(i)] = float(rho[m]);
        }
    };
    const auto n = std::int64_t(hu.voxels.size());
    if (pool)
        pool->parallelFor(n, 1 << 16, run);
    else
        run(0, n);
    return out;
}

std::vector<std::shared_ptr<const Spectrum>> preprocessMaterials(const Volume& hu,
                                                                 const MaterialMapping& mapping,
                                                                 PreprocessOptions options,
                                                                 const ProgressFn& progress,
                                                                 const CancelToken* cancel) {
    options.mapping = ValueMapping::Raw;
    std::vector<std::shared_ptr<const Spectrum>> spectra;
    {
        ThreadPool pool(options.threads);
        std::vector<Volume> volumes = materialVolumes(hu, mapping, &pool);
        const double k = double(volumes.size());
        for (std::size_t m = 0; m < volumes.size(); ++m) {
            ProgressFn part;
            if (progress)
                part = [&, m](double f, std::string_view stage) {
                    progress((double(m) + f) / k, stage);
                };
            spectra.push_back(preprocess(volumes[m], options, part, cancel));
            volumes[m] = Volume{}; // free the material's voxels once transformed
        }
    }
    return spectra;
}

double spectralSumWithNoise(const SpectralResponse& response, const std::vector<const float*>& rhoL,
                            std::vector<float>& out, const NoiseModel& noise,
                            SpectralResponse::Output output, ThreadPool* pool, const float* gain) {
    using Output = SpectralResponse::Output;
    const auto t0 = std::chrono::steady_clock::now();
    // Noise and a gain act on I/I0: the table's -ln(I/I0) only where neither applies.
    const bool direct = !noise.active() && !gain;
    response.apply(rhoL, out.data(), std::int64_t(out.size()), pool,
                   direct ? output : Output::Transmission);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (direct) return ms;
    if (gain)
        for (std::size_t p = 0; p < out.size(); ++p) out[p] *= gain[p];
    if (noise.active()) applyQuantumNoise(out, unattenuatedQuanta(response, noise), noise);
    if (output == Output::NegativeLog) negativeLogInPlace(out);
    return ms;
}

PolychromaticRenderer::PolychromaticRenderer(std::vector<std::unique_ptr<Renderer>> perMaterial,
                                             std::shared_ptr<const SpectralResponse> response,
                                             int threads)
    : m_renderers(std::move(perMaterial)), m_pool(threads) {
    setResponse(std::move(response));
}

void PolychromaticRenderer::setResponse(std::shared_ptr<const SpectralResponse> response) {
    if (!response || response->materials() != m_renderers.size())
        throw SettingsError("polychromatic renderer: expected a response for " +
                            std::to_string(m_renderers.size()) + " materials");
    m_response = std::move(response);
}

PolychromaticFrame PolychromaticRenderer::render(const RenderParams& params,
                                                 const NoiseModel& noise, StageTimes* times,
                                                 SpectralResponse::Output output) {
    PolychromaticFrame frame;
    StageTimes sum;
    for (auto& r : m_renderers) {
        StageTimes t;
        ProjectionImage img = r->render(params, &t);
        for (float& v : img.pixels) v *= 0.1f; // rho x mm -> g/cm^2
        frame.massThickness.push_back(std::move(img));
        sum.sliceMs += t.sliceMs;
        sum.inverseMs += t.inverseMs;
        sum.totalMs += t.totalMs;
    }
    frame.transmission = frame.massThickness.front();
    frame.transmission.mapping = ValueMapping::Raw;
    std::vector<const float*> rhoL;
    for (const auto& img : frame.massThickness) rhoL.push_back(img.pixels.data());
    NoiseModel n = noise;
    n.pixelAreaMm2 = params.image.pixelSize * params.image.pixelSize;
    frame.spectralSumMs =
        spectralSumWithNoise(*m_response, rhoL, frame.transmission.pixels, n, output, &m_pool);
    sum.totalMs += frame.spectralSumMs;
    if (times) *times = sum;
    return frame;
}

} // namespace fvr::core
