#pragma once
/** A rendered projection: float line integrals on a W x H grid (row 0 at the top), the volume's
 *  centre at pixel (W/2, H/2) (view.h). */
#include <string>
#include <vector>

#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>

namespace fvr::core {

struct ProjectionImage {
    int width = 0; ///< W, columns
    int height = 0; ///< H, rows
    double pixelSize = 0.0; ///< d, mm
    ViewFrame view;
    ValueMapping mapping = ValueMapping::Raw;
    std::vector<float> pixels; ///< W*H, pixel (col, row) at row * W + col

    float at(int col, int row) const { return pixels[std::size_t(row) * width + col]; }
    ImageGeometry geometry() const { return {width, pixelSize, height}; }
};

/** The centred W x H crop (centredCrop) of a square image rendered on a larger side; the
 *  image itself when it is already W x H. */
ProjectionImage cropProjection(ProjectionImage square, int width, int height);

/** Per-frame stage timings in milliseconds. */
struct StageTimes {
    double sliceMs = 0.0;
    double inverseMs = 0.0;
    double totalMs = 0.0;
};

/** Units label of a projection's values ("HU x mm", "mm" for mu, "value x mm"). */
std::string projectionUnits(ValueMapping mapping, ValueUnits source);

} // namespace fvr::core
