#pragma once
/** Image similarity for 2D/3D registration: normalised cross-correlation (NCC), gradient NCC
 *  (the mean of the NCCs of the horizontal and vertical Sobel derivatives, Penney et al.'s
 *  gradient correlation), their multi-scale forms, over a mask; and the image pyramid whose
 *  levels the registration works on. Larger is more similar; 1 is a perfect affine match. */
#include <cstdint>
#include <string>
#include <vector>

#include <fvr/core/geometry/camera.h>

namespace fvr::core {

enum class SimilarityMeasure {
    Ncc, ///< NCC of the values
    GradientNcc, ///< mean NCC of the Sobel x and y derivatives (insensitive to smooth offsets)
};

/** "ncc", "gradient-ncc". */
const char* similarityName(SimilarityMeasure m);
/** Inverse of similarityName (also "gncc", "gc", "gradient"); SettingsError listing the names. */
SimilarityMeasure parseSimilarity(const std::string& name);

/** A W x H float image (row 0 at the top) with an optional mask (empty: every pixel; else
 *  W x H, non-zero = counted). */
struct MaskedImage {
    int width = 0;
    int height = 0;
    std::vector<float> pixels;
    std::vector<std::uint8_t> mask;
};

/** Pearson's correlation of a and b over the pixels where `mask` (may be null) is non-zero:
 *  in [-1, 1]; 0 when either is constant there or fewer than 2 pixels count. */
double ncc(const float* a, const float* b, const std::uint8_t* mask, std::size_t n);
/** The Sobel x and y derivatives' NCCs, averaged, over interior pixels whose 3 x 3 neighbourhood
 *  lies in the mask (may be null). */
double gradientNcc(const float* a, const float* b, const std::uint8_t* mask, int width, int height);
/** The measure of a against b (same size; `mask` may be null). */
double similarity(SimilarityMeasure measure, const float* a, const float* b,
                  const std::uint8_t* mask, int width, int height);

/** A fixed image (an X-ray at one level) prepared once for many comparisons: its Sobel
 *  derivatives are taken here, not at every evaluation. score() equals similarity() of the moving
 *  image against it, over its own mask and `extraMask` (may be null) together. */
class SimilarityTarget {
public:
    SimilarityTarget(SimilarityMeasure measure, MaskedImage image);
    double score(const float* moving, const std::uint8_t* extraMask = nullptr) const;
    const MaskedImage& image() const { return m_image; }

private:
    SimilarityMeasure m_measure;
    MaskedImage m_image;
    std::vector<float> m_gx, m_gy; ///< GradientNcc: the image's Sobel derivatives
};

/** Block means over factor x factor pixels (the last partial row and column dropped): W/f x H/f.
 *  A block is in the mask only when all its pixels are. factor 1 returns a copy. */
MaskedImage downsampleImage(const MaskedImage& image, int factor);
/** The camera of downsampleImage's pixels: W/f x H/f, pitch x f, the principal offset moved so
 *  that each new pixel's centre is its block's centre. */
ConeCamera downsampleCamera(const ConeCamera& camera, int factor);

/** A Gaussian blur of standard deviation `sigma` pixels (separable, the edges clamped), in
 *  place; sigma <= 0 leaves the image as it is. */
void gaussianBlur(std::vector<float>& image, int width, int height, double sigma);

} // namespace fvr::core
