#include <fvr/gpu/choose_renderer.h>

#include <exception>

namespace fvr::gpu {

std::string fallbackReason(std::string_view what) {
    return "GPU backend unavailable (" + std::string(what) + "): rendering on the CPU";
}

std::string softwareGlReason(const GlInfo& gl) {
    // Software OpenGL renders the same images, several times slower than the CPU renderer.
    return "the GPU is a software renderer (" + gl.renderer +
           "): rendering on the CPU, which is faster here";
}

RendererChoice chooseRenderer(const RendererRequest& request) {
    RendererChoice c;
    if (request.use == GpuUse::Never) {
        c.why = CpuReason::Asked;
        return c;
    }
    try {
        if (request.makeContext) request.makeContext();
        c.gl = currentGlInfo();
        if (request.use == GpuUse::Hardware && c.gl.software()) {
            c.why = CpuReason::SoftwareGl;
            c.reason = softwareGlReason(c.gl);
            return c;
        }
        if (request.spectra.empty())
            c.gpu.push_back(std::make_unique<GpuFourierRenderer>(request.shareGroup));
        for (const auto& spectrum : request.spectra) {
            c.gpu.push_back(std::make_unique<GpuFourierRenderer>(request.shareGroup));
            c.gpu.back()->setSpectrum(spectrum, request.precision);
        }
    } catch (const std::exception& e) {
        c.gpu.clear(); // the context is still current: the GL objects are released in it
        c.why = CpuReason::GpuFailed;
        c.reason = fallbackReason(e.what());
    }
    return c;
}

std::string uploadSpectrum(std::unique_ptr<GpuFourierRenderer>& gpu,
                           std::shared_ptr<const core::Spectrum> spectrum,
                           SpectrumPrecision precision) {
    try {
        gpu->setSpectrum(std::move(spectrum), precision);
        return {};
    } catch (const std::exception& e) {
        gpu.reset();
        return fallbackReason(e.what());
    }
}

} // namespace fvr::gpu
