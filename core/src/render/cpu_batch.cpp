// Many views of one spectrum on the CPU: one single-threaded renderer per thread.
#include <fvr/core/render/cpu_batch.h>

#include <cstdint>

namespace fvr::core {

/** One single-threaded renderer per thread, made on the first batch. */
struct CpuBatchRenderer::Lanes {
    Lanes(const std::shared_ptr<const Spectrum>& spectrum, int threads) : pool(threads) {
        for (int i = 0; i < threads; ++i)
            renderers.push_back(std::make_unique<CpuFourierRenderer>(spectrum, 1));
    }
    ThreadPool pool;
    std::vector<std::unique_ptr<CpuFourierRenderer>> renderers;
};

CpuBatchRenderer::CpuBatchRenderer(std::shared_ptr<const Spectrum> spectrum, int threads)
    : m_spectrum(spectrum), m_renderer(std::move(spectrum), threads),
      m_threads(threads > 0 ? threads : hardwareThreads()) {}

CpuBatchRenderer::~CpuBatchRenderer() = default;

std::vector<ProjectionImage> CpuBatchRenderer::renderBatch(
    const std::vector<RenderParams>& params) {
    // One view alone goes to the renderer with every thread; the views of a batch run, its last
    // one included, all to the single-threaded lanes (the same plans: the same bytes).
    std::vector<ProjectionImage> images(params.size());
    if (params.size() < 2 && !m_lanes) {
        for (std::size_t i = 0; i < params.size(); ++i) images[i] = m_renderer.render(params[i]);
        return images;
    }
    if (!m_lanes) m_lanes = std::make_unique<Lanes>(m_spectrum, m_threads);
    for (std::size_t first = 0; first < params.size(); first += std::size_t(m_threads)) {
        const std::size_t n = std::min(params.size() - first, std::size_t(m_threads));
        m_lanes->pool.parallelFor(std::int64_t(n), 1, [&](std::int64_t lo, std::int64_t hi) {
            for (std::int64_t i = lo; i < hi; ++i)
                images[first + std::size_t(i)] =
                    m_lanes->renderers[std::size_t(i)]->render(params[first + std::size_t(i)]);
        });
    }
    return images;
}

} // namespace fvr::core
