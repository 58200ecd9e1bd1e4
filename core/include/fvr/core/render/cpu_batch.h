#pragma once
/** Many views of one spectrum on the CPU: the batch rule that fvr-render's --sweep and --views
 *  and the Python module's render_many share. */
#include <memory>
#include <vector>

#include <fvr/core/render/cpu_renderer.h>

namespace fvr::core {

/**
 * One view alone goes to a renderer with every thread; the views of a batch go one per thread,
 * each to a single-threaded renderer over the shared spectrum (no synchronisation inside a frame:
 * more views per second than all threads on one frame). Both use the same plans, so a view's
 * bytes do not depend on the path it took. Not thread-safe: one batch renderer per caller.
 */
class CpuBatchRenderer {
public:
    /** threads <= 0: all hardware threads. */
    CpuBatchRenderer(std::shared_ptr<const Spectrum> spectrum, int threads);
    ~CpuBatchRenderer();

    /** The renderer with every thread (one view at a time). */
    CpuFourierRenderer& renderer() { return m_renderer; }
    /** How many views renderBatch() renders at once: the thread count. */
    int width() const { return m_threads; }
    /** The views of `params` (any number), in order. Throws what CpuFourierRenderer::render
     *  throws. */
    std::vector<ProjectionImage> renderBatch(const std::vector<RenderParams>& params);

private:
    struct Lanes;
    std::shared_ptr<const Spectrum> m_spectrum;
    CpuFourierRenderer m_renderer;
    int m_threads;
    std::unique_ptr<Lanes> m_lanes; ///< made on the first batch of two views or more
};

} // namespace fvr::core
