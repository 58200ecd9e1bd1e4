#include <fvr/core/render/progressive.h>

#include <algorithm>
#include <cmath>

namespace fvr::core {

std::vector<QualityLevel> progressiveLevels(int size, Kernel kernel, bool kernelLocked,
                                            int minSize) {
    std::vector<QualityLevel> levels{{size, kernel}};
    const bool cheaper = !kernelLocked && kernelTaps(kernel) > kernelTaps(Kernel::Linear);
    const Kernel fast = cheaper ? Kernel::Linear : kernel;
    if (cheaper) levels.push_back({size, fast});
    for (int m = size / 2; m >= minSize; m /= 2) levels.push_back({m, fast});
    return levels;
}

ProgressiveController::ProgressiveController(double targetFps) : m_targetFps(targetFps) {
    setLevels({QualityLevel{}});
}

void ProgressiveController::setTargetFps(double fps) {
    m_targetFps = fps;
    if (!enabled()) m_level = 0;
}

void ProgressiveController::setLevels(std::vector<QualityLevel> levels) {
    if (levels.empty()) levels.push_back(QualityLevel{});
    if (levels == m_levels) return;
    m_levels = std::move(levels);
    m_measured.assign(m_levels.size(), 0.0);
    m_level = 0;
}

QualityLevel ProgressiveController::current() const { return m_levels[std::size_t(m_level)]; }

double ProgressiveController::expectedMs(int level) const {
    if (level < 0 || level >= int(m_levels.size())) return 0.0;
    if (m_measured[std::size_t(level)] > 0.0) return m_measured[std::size_t(level)];
    // Scale the nearest measured level with the same kernel by the pixel count (the slice and the
    // 2D FFT are ~M^2); across kernels the cost ratio is unknown (unmeasured: worth a try).
    const Kernel k = m_levels[std::size_t(level)].kernel;
    for (int dist = 1; dist < int(m_levels.size()); ++dist)
        for (int other : {level - dist, level + dist}) {
            if (other < 0 || other >= int(m_levels.size()) ||
                m_measured[std::size_t(other)] <= 0.0 || m_levels[std::size_t(other)].kernel != k)
                continue;
            const double r =
                double(m_levels[std::size_t(level)].size) / m_levels[std::size_t(other)].size;
            return m_measured[std::size_t(other)] * r * r;
        }
    return 0.0;
}

void ProgressiveController::beginInteraction() {
    m_interacting = true;
    if (!enabled()) {
        m_level = 0;
        return;
    }
    const double budget = 1000.0 / m_targetFps;
    m_level = 0;
    while (m_level + 1 < int(m_levels.size()) && expectedMs(m_level) > budget) ++m_level;
}

void ProgressiveController::endInteraction() {
    m_interacting = false;
    m_level = 0;
}

void ProgressiveController::frameRendered(double ms) {
    auto& m = m_measured[std::size_t(m_level)];
    m = m > 0.0 ? 0.5 * m + 0.5 * ms : ms;
    if (!m_interacting || !enabled()) return;
    const double budget = 1000.0 / m_targetFps;
    if (ms > budget) {
        if (m_level + 1 < int(m_levels.size())) ++m_level;
    } else if (m_level > 0) {
        // A fast frame lets the remembered time of the level above decay towards what this frame
        // predicts for it, so that one slow frame (a hiccup) does not lock the drag at low quality.
        auto& above = m_measured[std::size_t(m_level - 1)];
        const double r =
            double(m_levels[std::size_t(m_level - 1)].size) / m_levels[std::size_t(m_level)].size;
        const bool sameKernel =
            m_levels[std::size_t(m_level - 1)].kernel == m_levels[std::size_t(m_level)].kernel;
        if (above > 0.0 && sameKernel) above = 0.8 * above + 0.2 * ms * r * r;
        const double up = expectedMs(m_level - 1);
        if (up > 0.0 && up < 0.7 * budget) --m_level;
    }
}

std::string ProgressiveController::describe() const {
    const QualityLevel q = current();
    if (m_level == 0) return "full quality";
    return "interactive " + std::to_string(m_level) + "/" + std::to_string(m_levels.size() - 1) +
           ": " + std::to_string(q.size) + "\u00b2 " + kernelName(q.kernel);
}

} // namespace fvr::core
