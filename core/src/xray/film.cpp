#include <fvr/core/xray/film.h>

namespace fvr::core {

std::vector<float> windowedValues(std::vector<float> lineIntegrals, const Transmission& transmission) {
    if (transmission.active()) applyLogExposure(lineIntegrals, transmission);
    return lineIntegrals;
}

DisplayWindow filmWindow(const std::vector<float>& lineIntegrals, const Transmission& transmission,
                         bool invert) {
    DisplayWindow w = autoWindow(windowedValues(lineIntegrals, transmission));
    w.invert = invert;
    w.transmission = transmission;
    return w;
}

} // namespace fvr::core
