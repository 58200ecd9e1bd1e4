#pragma once
/** A rendered projection: float line integrals on an M x M grid (row 0 at the top). */
#include <string>
#include <vector>

#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>

namespace fvr::core {

struct ProjectionImage {
    int size = 0; ///< M
    double pixelSize = 0.0; ///< d, mm
    ViewFrame view;
    ValueMapping mapping = ValueMapping::Raw;
    std::vector<float> pixels; ///< M*M, pixel (col, row) at row * M + col

    float at(int col, int row) const { return pixels[std::size_t(row) * size + col]; }
};

/** Per-frame stage timings in milliseconds. */
struct StageTimes {
    double sliceMs = 0.0;
    double inverseMs = 0.0;
    double totalMs = 0.0;
};

/** Units label of a projection's values ("HU x mm", "mm" for mu, "value x mm"). */
std::string projectionUnits(ValueMapping mapping, ValueUnits source);

} // namespace fvr::core
