#pragma once
/** Comparing a projection with a reference (the accuracy readout, fvr-render --bench, the tests),
 *  one definition everywhere. */
#include <vector>

namespace fvr::core {

struct ImageComparison {
    double peak = 0; ///< max |reference|
    double maxAbsError = 0;
    double rmse = 0;
    double relRmse = 0; ///< rmse / rms(reference)
    double psnr = 0; ///< 20 log10(peak / rmse), dB (300 for identical images)
};

/** Pixel by pixel; the images must have the same size. */
ImageComparison compareImages(const std::vector<float>& image, const std::vector<float>& reference);

/** The most negative pixel as a fraction of the largest (0 when none is negative). */
double mostNegativeFraction(const std::vector<float>& pixels);

} // namespace fvr::core
