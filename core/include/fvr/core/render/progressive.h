#pragma once
/** Progressive refinement (the paper has none): while the user drags, frames render at a lower
 *  slice resolution or with a cheaper kernel so that the interaction holds a target frame rate;
 *  when the drag ends, the full-quality frame follows. No Qt: the workstation's views drive it
 *  and the tests feed it simulated frame times. */
#include <string>
#include <vector>

#include <fvr/core/render/kernels.h>

namespace fvr::core {

/** What one frame renders with. */
struct QualityLevel {
    int size = 512;
    Kernel kernel = Kernel::Linear;
    bool operator==(const QualityLevel&) const = default;
};

/**
 * The levels from full quality down: (M, K) first; when the kernel may change (kernelLocked
 * false: the spectrum is not deapodized for K) and K is costlier than linear, (M, linear) next;
 * then halving the size (with linear when allowed, else K) down to minSize. A deapodized
 * spectrum renders with its kernel only, so only the size drops.
 */
std::vector<QualityLevel> progressiveLevels(int size, Kernel kernel, bool kernelLocked,
                                            int minSize = 64);

class ProgressiveController {
public:
    /** targetFps <= 0: progressive refinement off (always level 0). */
    explicit ProgressiveController(double targetFps = 30.0);

    void setTargetFps(double fps);
    double targetFps() const { return m_targetFps; }
    bool enabled() const { return m_targetFps > 0.0; }
    /** New levels (settings changed): forgets the measured times, back to level 0. */
    void setLevels(std::vector<QualityLevel> levels);
    const std::vector<QualityLevel>& levels() const { return m_levels; }

    /** A drag starts: the first frame uses the best level whose expected time fits the budget. */
    void beginInteraction();
    /** The drag ended: full quality (level 0) from the next frame. */
    void endInteraction();
    bool interacting() const { return m_interacting; }

    /** The level the next frame renders at (index into levels()). */
    int level() const { return m_level; }
    QualityLevel current() const;
    /** Reports the time (ms) of a frame rendered at level(); while interacting, a frame over the
     *  budget (1000 / target) drops a level, and a level up is taken when its expected time
     *  (measured, or this level's time scaled by the size ratio squared) is under 70 % of it.
     *  Fast frames let a remembered slow time of the level above decay towards their prediction
     *  (20 % per frame), so a single hiccup does not keep the drag at low quality. */
    void frameRendered(double ms);
    /** Expected time (ms) of a level: its measured time, else an estimate from the nearest
     *  measured level with the same kernel (scaled by the pixel count); 0 if unknown. */
    double expectedMs(int level) const;
    /** "full quality" or "interactive 2/4: 256² linear". */
    std::string describe() const;

private:
    double m_targetFps;
    std::vector<QualityLevel> m_levels;
    std::vector<double> m_measured; // ms, exponential average per level; 0 = never rendered
    int m_level = 0;
    bool m_interacting = false;
};

} // namespace fvr::core
