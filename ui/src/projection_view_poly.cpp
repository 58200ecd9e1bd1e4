// ProjectionView's polychromatic frame: on the CPU, one renderer per material and the spectral
// response evaluated per pixel; on the GPU, the material frames stay on the GPU and one compute
// pass evaluates the spectral response into the frame the view shows.
#include <QOpenGLContext>

#include <cmath>

#include <fvr/gpu/gpu_renderer.h>
#include <fvr/ui/projection_view.h>

namespace fvr::ui {

core::ProjectionImage ProjectionView::renderPolychromatic(const core::RenderParams& params,
                                                          core::StageTimes* times) {
    if (!m_polyRenderer) {
        std::vector<std::unique_ptr<core::Renderer>> renderers;
        for (const auto& s : m_poly->spectra)
            renderers.push_back(std::make_unique<core::CpuFourierRenderer>(s));
        m_polyRenderer =
            std::make_unique<core::PolychromaticRenderer>(std::move(renderers), m_poly->response);
    } else {
        m_polyRenderer->setResponse(m_poly->response);
    }
    core::PolychromaticFrame f = m_polyRenderer->render(
        params, m_poly->noise, times, core::SpectralResponse::Output::NegativeLog);
    if (m_poly->show >= 0 && std::size_t(m_poly->show) < f.massThickness.size())
        return std::move(f.massThickness[std::size_t(m_poly->show)]);
    return std::move(f.transmission); // -ln(I/I0), the quantity shown
}

bool ProjectionView::renderPolychromaticOnGpu(const core::RenderParams& params) {
    if (m_poly->spectra.size() > 5) return false;
    // Noise (on -ln(I/I0) only) is drawn on the CPU: then I/I0 is read back once.
    const bool noisy = m_poly->noise.active() && m_poly->show < 0;
    try {
        if (m_polyGpuSpectra != m_poly->spectra) {
            m_polyGpu.resize(m_poly->spectra.size());
            for (std::size_t m = 0; m < m_polyGpu.size(); ++m) {
                if (!m_polyGpu[m])
                    m_polyGpu[m] =
                        std::make_unique<gpu::GpuFourierRenderer>(context()->shareGroup());
                m_polyGpu[m]->setSpectrum(m_poly->spectra[m]);
            }
            m_polyGpuSpectra = m_poly->spectra;
        }
        std::vector<const gpu::GpuFourierRenderer*> frames;
        gpu::GpuStageTimes sum; // the materials' stages, one after the other
        for (auto& r : m_polyGpu) {
            r->renderToGpu(params);
            frames.push_back(r.get());
        }
        for (auto& r : m_polyGpu) { // waits for the GPU: the frame's cost, as on the CPU
            const gpu::GpuStageTimes t = r->lastTimes();
            sum.sliceMs += t.sliceMs;
            sum.inverseMs += t.inverseMs;
            sum.totalMs += t.totalMs;
        }
        using Output = gpu::GpuFourierRenderer::SpectralOutput;
        const bool material = m_poly->show >= 0;
        m_polyGpu.front()->spectralSum(frames, m_poly->response,
                                       noisy ? Output::Transmission
                                             : (material ? Output::Material : Output::NegativeLog),
                                       std::max(0, m_poly->show));
        m_cpuImage.reset();
        if (noisy) {
            core::ProjectionImage img = m_polyGpu.front()->readback();
            core::NoiseModel n = m_poly->noise;
            n.pixelAreaMm2 = params.image.pixelSize * params.image.pixelSize;
            core::applyQuantumNoise(img.pixels, core::unattenuatedQuanta(*m_poly->response, n), n);
            core::negativeLogInPlace(img.pixels);
            m_cpuImage = std::move(img); // shown through the CPU image's texture
        }
        recordStageTimes(sum, false);
    } catch (const std::exception& e) {
        m_polyGpu.clear();
        m_polyGpuSpectra.clear();
        m_notice = tr("Polychromatic output on the GPU failed (%1): rendering it on the CPU")
                       .arg(QString::fromUtf8(e.what()));
        return false;
    }
    m_polyOnGpu = !noisy; // the shown frame is the GPU's (else the noisy read-back)
    m_polySumOnGpu = true;
    m_gpuTimesPending = false;
    return true;
}

} // namespace fvr::ui
