// The checks every renderer (CPU, GPU, spatial) and fvr-render run on the render parameters
// and on the images they write; declared in renderer.h.
#include <fvr/core/render/renderer.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <fvr/core/errors.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/view.h>

namespace fvr::core {

void validateRenderParams(const RenderParams& params) {
    validateImageGeometry(params.image);
    if (!(params.depthCue >= 0.0 && params.depthCue <= 1.0))
        throw SettingsError("depth cueing: strength must be in [0, 1], found " +
                            std::to_string(params.depthCue));
    if (params.depthCue > 0.0 && params.kernel == Kernel::Nearest)
        throw SettingsError(
            "depth cueing: needs the derivative of the interpolation kernel; nearest has none "
            "(choose linear or better)");
    validateSliceFilter(params.filter);
}

void checkFiniteImage(const ProjectionImage& image) {
    std::size_t bad = 0;
    for (const float p : image.pixels) bad += std::isfinite(p) ? 0 : 1;
    if (bad == 0) return;
    throw RenderError("rendered image: " + std::to_string(bad) + " of " +
                      std::to_string(image.pixels.size()) +
                      " pixels are not finite (NaN or infinite): the projection overflowed float "
                      "(voxel values or line integrals too large); nothing is output");
}

ProjectionImage cropProjection(ProjectionImage square, int width, int height) {
    if (square.width == width && square.height == height) return square;
    const CropOffset o = centredCrop(square.width, width, height);
    ProjectionImage out = square;
    out.width = width;
    out.height = height;
    out.pixels.resize(std::size_t(width) * height);
    for (int row = 0; row < height; ++row) {
        const float* from = square.pixels.data() + std::size_t(row + o.row) * square.width + o.col;
        std::copy(from, from + width, out.pixels.data() + std::size_t(row) * width);
    }
    return out;
}

void validateRenderParams(const RenderParams& params, const Spectrum& spectrum) {
    validateImageGeometry(params.image, spectrum.volumeDims, spectrum.spacing);
    validateRenderParams(params);
}

} // namespace fvr::core
