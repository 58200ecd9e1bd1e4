#pragma once
/** Display windows: how a projection's values become brightness, the one rule for fvr-render's
 *  PNGs and the workstation's views: with Beer-Lambert transmission the window applies to the
 *  film's log exposure (Transmission::logExposure), otherwise to the line integrals themselves. */
#include <vector>

#include <fvr/core/xray/xray.h>

namespace fvr::core {

/** Window for display mapping: value `low` maps to black, `high` to white (inverted swaps).
 *  With an active transmission, the window applies to the log exposure of the Beer-Lambert
 *  signal (Transmission::logExposure) instead of the line integral: not inverted, bone is dark
 *  (fluoroscopy); inverted, the film look: bone white, air black. */
struct DisplayWindow {
    double low = 0.0;
    double high = 1.0;
    bool invert = false;
    Transmission transmission;

    /** The displayed brightness in [0, 1] of a projection value. */
    double map(double value) const;
};

/** Window from the 0.5 and 99.5 percentiles of the image (robust auto window). */
DisplayWindow autoWindow(const std::vector<float>& pixels);

/** What a DisplayWindow with this transmission windows: the log exposure of each line integral
 *  when the transmission is active (the film), the line integrals unchanged otherwise. */
std::vector<float> windowedValues(std::vector<float> lineIntegrals,
                                  const Transmission& transmission);

/**
 * The automatic window of a projection of line integrals: autoWindow (0.5 and 99.5 percentiles)
 * of windowedValues(), carrying `transmission` (DisplayWindow::map then maps line integrals
 * through it) and `invert`. For a Beer-Lambert image invert = true gives the film look (bone
 * white, air black); false the fluoroscopy look.
 */
DisplayWindow filmWindow(const std::vector<float>& lineIntegrals, const Transmission& transmission,
                         bool invert);

} // namespace fvr::core
