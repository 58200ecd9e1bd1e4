// ProjectionView's polychromatic frame on the GPU (issue 19): the material frames stay on the GPU
// and one compute pass evaluates the spectral response into the frame the view shows.
#include <QOpenGLContext>

#include <fvr/gpu/gpu_renderer.h>
#include <fvr/ui/projection_view.h>

namespace fvr::ui {

bool ProjectionView::renderPolychromaticOnGpu(const core::RenderParams& params) {
    if (m_poly->noise.active() || m_poly->spectra.size() > 5) return false; // noise: on the CPU
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
        FrameStats sum;
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
                                       material ? Output::Material : Output::NegativeLog,
                                       std::max(0, m_poly->show));
        m_stats.sliceMs = sum.sliceMs;
        m_stats.inverseMs = sum.inverseMs;
        m_stats.totalMs = sum.totalMs;
        m_stats.fused = false;
        m_stats.displayFused = false;
    } catch (const std::exception& e) {
        m_polyGpu.clear();
        m_polyGpuSpectra.clear();
        m_notice = tr("Polychromatic output on the GPU failed (%1): rendering it on the CPU")
                       .arg(QString::fromUtf8(e.what()));
        return false;
    }
    m_polyOnGpu = true;
    m_gpuTimesPending = false;
    m_cpuImage.reset();
    return true;
}

} // namespace fvr::ui
