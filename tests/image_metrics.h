#pragma once
// Image comparison metrics used by the accuracy tests and benchmarks: the library's own
// definition (fvr/core/render/image_metrics.h), which the accuracy readout and fvr-render --bench
// use too.
#include <vector>

#include <fvr/core/render/image_metrics.h>

namespace fvr::test {

using Comparison = core::ImageComparison;

inline Comparison compare(const std::vector<float>& image, const std::vector<float>& reference) {
    return core::compareImages(image, reference);
}

} // namespace fvr::test
