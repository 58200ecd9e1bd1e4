#pragma once
/** The display window of a projection, the one rule for fvr-render's PNGs and the workstation's
 *  views: with Beer-Lambert transmission the window applies to the film's log exposure
 *  (Transmission::logExposure), otherwise to the line integrals themselves. */
#include <vector>

#include <fvr/core/io/image_io.h>
#include <fvr/core/xray/xray.h>

namespace fvr::core {

/** What a DisplayWindow with this transmission windows: the log exposure of each line integral
 *  when the transmission is active (the film), the line integrals unchanged otherwise. */
std::vector<float> windowedValues(std::vector<float> lineIntegrals, const Transmission& transmission);

/**
 * The automatic window of a projection of line integrals: autoWindow (0.5 and 99.5 percentiles)
 * of windowedValues(), carrying `transmission` (DisplayWindow::map then maps line integrals
 * through it) and `invert`. For a Beer-Lambert image invert = true gives the film look (bone
 * white, air black); false the fluoroscopy look.
 */
DisplayWindow filmWindow(const std::vector<float>& lineIntegrals, const Transmission& transmission,
                         bool invert);

} // namespace fvr::core
