/**
 * fvr_compare_npy A.npy B.npy: compares two float32 images written by fvr-render (--out X.npy)
 * pixel by pixel, B being the reference, with the library's one definition of the metrics
 * (fvr/core/render/image_metrics.h: PSNR = 20 log10(max |B| / rmse), 300 dB when identical).
 * Prints one line of JSON: {"a", "b", "shape", "psnr", "rmse", "max_abs_error", "peak",
 * "rel_rmse"}. Part of the hardware bench kit (make gpu-kit), where numpy may be missing.
 * Exit status 0 when compared, 2 on bad input (a message naming the file and the problem).
 */
#include <cstdint>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <fvr/core/io/image_io.h>
#include <fvr/core/render/image_metrics.h>

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: fvr_compare_npy IMAGE.npy REFERENCE.npy\n");
        return 2;
    }
    try {
        std::vector<std::int64_t> shapeA, shapeB;
        const std::vector<float> a = fvr::core::readNpy(argv[1], shapeA);
        const std::vector<float> b = fvr::core::readNpy(argv[2], shapeB);
        if (shapeA != shapeB || a.size() != b.size() || a.empty()) {
            std::fprintf(stderr, "fvr_compare_npy: %s and %s differ in shape (or are empty)\n",
                         argv[1], argv[2]);
            return 2;
        }
        const fvr::core::ImageComparison c = fvr::core::compareImages(a, b);
        const nlohmann::json out = {{"a", argv[1]},    {"b", argv[2]},
                                    {"shape", shapeA}, {"psnr", c.psnr},
                                    {"rmse", c.rmse},  {"max_abs_error", c.maxAbsError},
                                    {"peak", c.peak},  {"rel_rmse", c.relRmse}};
        std::printf("%s\n", out.dump().c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fvr_compare_npy: %s\n", e.what());
        return 2;
    }
}
