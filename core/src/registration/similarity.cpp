// NCC, gradient NCC and the image pyramid of the registration (registration/similarity.h).
#include <fvr/core/registration/similarity.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include <fvr/core/errors.h>

namespace fvr::core {

const char* similarityName(SimilarityMeasure m) {
    return m == SimilarityMeasure::Ncc ? "ncc" : "gradient-ncc";
}

SimilarityMeasure parseSimilarity(const std::string& name) {
    if (name == "ncc") return SimilarityMeasure::Ncc;
    if (name == "gradient-ncc" || name == "gncc" || name == "gc" || name == "gradient")
        return SimilarityMeasure::GradientNcc;
    throw SettingsError("unknown similarity '" + name + "' (use ncc or gradient-ncc)");
}

double ncc(const float* a, const float* b, const std::uint8_t* mask, std::size_t n) {
    // Two passes (means, then centred sums) in double: no cancellation on large offsets.
    double sa = 0.0, sb = 0.0;
    std::size_t count = 0;
    for (std::size_t i = 0; i < n; ++i) {
        if (mask && !mask[i]) continue;
        sa += a[i];
        sb += b[i];
        ++count;
    }
    if (count < 2) return 0.0;
    const double ma = sa / double(count), mb = sb / double(count);
    double saa = 0.0, sbb = 0.0, sab = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        if (mask && !mask[i]) continue;
        const double da = a[i] - ma, db = b[i] - mb;
        saa += da * da;
        sbb += db * db;
        sab += da * db;
    }
    if (saa <= 0.0 || sbb <= 0.0) return 0.0;
    return sab / std::sqrt(saa * sbb);
}

namespace {

/** The Sobel derivatives of an image (interior pixels; the border 0) and the mask of the pixels
 *  whose 3 x 3 neighbourhood is all in `mask`. */
void sobel(const float* in, int w, int h, std::vector<float>& gx, std::vector<float>& gy) {
    gx.assign(std::size_t(w) * h, 0.0f);
    gy.assign(std::size_t(w) * h, 0.0f);
    for (int y = 1; y + 1 < h; ++y) {
        const float* up = in + std::size_t(y - 1) * w;
        const float* mid = in + std::size_t(y) * w;
        const float* dn = in + std::size_t(y + 1) * w;
        for (int x = 1; x + 1 < w; ++x) {
            const std::size_t i = std::size_t(y) * w + x;
            gx[i] = (up[x + 1] + 2.0f * mid[x + 1] + dn[x + 1]) -
                    (up[x - 1] + 2.0f * mid[x - 1] + dn[x - 1]);
            gy[i] = (dn[x - 1] + 2.0f * dn[x] + dn[x + 1]) - (up[x - 1] + 2.0f * up[x] + up[x + 1]);
        }
    }
}

std::vector<std::uint8_t> interiorMask(const std::uint8_t* mask, int w, int h) {
    std::vector<std::uint8_t> out(std::size_t(w) * h, 0);
    for (int y = 1; y + 1 < h; ++y)
        for (int x = 1; x + 1 < w; ++x) {
            bool all = true;
            for (int dy = -1; dy <= 1 && all; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    if (mask && !mask[std::size_t(y + dy) * w + x + dx]) {
                        all = false;
                        break;
                    }
            out[std::size_t(y) * w + x] = all ? 1 : 0;
        }
    return out;
}

} // namespace

namespace {

/** Gradient NCC from the derivatives: the mean of the x and y NCCs over the interior mask. */
double gradientNccOf(const std::vector<float>& ax, const std::vector<float>& ay,
                     const std::vector<float>& bx, const std::vector<float>& by,
                     const std::uint8_t* mask, int width, int height) {
    const std::vector<std::uint8_t> inner = interiorMask(mask, width, height);
    const std::size_t n = std::size_t(width) * height;
    return 0.5 * (ncc(ax.data(), bx.data(), inner.data(), n) +
                  ncc(ay.data(), by.data(), inner.data(), n));
}

} // namespace

double gradientNcc(const float* a, const float* b, const std::uint8_t* mask, int width,
                   int height) {
    if (width < 3 || height < 3) return 0.0;
    std::vector<float> ax, ay, bx, by;
    sobel(a, width, height, ax, ay);
    sobel(b, width, height, bx, by);
    return gradientNccOf(ax, ay, bx, by, mask, width, height);
}

double similarity(SimilarityMeasure measure, const float* a, const float* b,
                  const std::uint8_t* mask, int width, int height) {
    if (measure == SimilarityMeasure::Ncc)
        return ncc(a, b, mask, std::size_t(width) * std::size_t(height));
    return gradientNcc(a, b, mask, width, height);
}

SimilarityTarget::SimilarityTarget(SimilarityMeasure measure, MaskedImage image)
    : m_measure(measure), m_image(std::move(image)) {
    if (m_measure == SimilarityMeasure::GradientNcc && m_image.width >= 3 && m_image.height >= 3)
        sobel(m_image.pixels.data(), m_image.width, m_image.height, m_gx, m_gy);
}

double SimilarityTarget::score(const float* moving, const std::uint8_t* extraMask) const {
    const int w = m_image.width, h = m_image.height;
    std::vector<std::uint8_t> combined;
    const std::uint8_t* mask = m_image.mask.empty() ? extraMask : m_image.mask.data();
    if (!m_image.mask.empty() && extraMask) {
        combined = m_image.mask;
        for (std::size_t i = 0; i < combined.size(); ++i) combined[i] = combined[i] && extraMask[i];
        mask = combined.data();
    }
    if (m_measure == SimilarityMeasure::Ncc)
        return ncc(moving, m_image.pixels.data(), mask, std::size_t(w) * std::size_t(h));
    if (w < 3 || h < 3) return 0.0;
    std::vector<float> mx, my;
    sobel(moving, w, h, mx, my);
    return gradientNccOf(mx, my, m_gx, m_gy, mask, w, h);
}

MaskedImage downsampleImage(const MaskedImage& image, int factor) {
    if (factor < 1) throw SettingsError("image downsampling factor must be at least 1");
    if (factor == 1) return image;
    MaskedImage out;
    out.width = image.width / factor;
    out.height = image.height / factor;
    out.pixels.assign(std::size_t(out.width) * out.height, 0.0f);
    const bool masked = !image.mask.empty();
    if (masked) out.mask.assign(out.pixels.size(), 1);
    const double norm = 1.0 / double(factor * factor);
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x) {
            double sum = 0.0;
            bool in = true;
            for (int dy = 0; dy < factor; ++dy)
                for (int dx = 0; dx < factor; ++dx) {
                    const std::size_t i =
                        std::size_t(y * factor + dy) * image.width + std::size_t(x * factor + dx);
                    sum += image.pixels[i];
                    if (masked && !image.mask[i]) in = false;
                }
            const std::size_t o = std::size_t(y) * out.width + x;
            out.pixels[o] = float(sum * norm);
            if (masked) out.mask[o] = in ? 1 : 0;
        }
    return out;
}

ConeCamera downsampleCamera(const ConeCamera& camera, int factor) {
    if (factor < 1) throw SettingsError("camera downsampling factor must be at least 1");
    if (factor == 1) return camera;
    // Old pixel i lies at (i - (W-1)/2 + du) pu; new pixel I is the block of old pixels f I ..
    // f I + f - 1, centred on old index f I + (f-1)/2: (I - (W'-1)/2 + du') f pu.
    ConeCamera c = camera;
    const double f = factor;
    const int w = camera.width / factor, h = camera.height / factor;
    c.principalOffset.x = ((f - 1.0) / 2.0 - (camera.width - 1) / 2.0 + camera.principalOffset.x +
                           f * (w - 1) / 2.0) /
                          f;
    c.principalOffset.y = ((f - 1.0) / 2.0 - (camera.height - 1) / 2.0 + camera.principalOffset.y +
                           f * (h - 1) / 2.0) /
                          f;
    c.width = w;
    c.height = h;
    c.pitchU = camera.pitchU * f;
    c.pitchV = camera.pitchV * f;
    return c;
}

void gaussianBlur(std::vector<float>& image, int width, int height, double sigma) {
    if (sigma <= 0.0) return;
    const int r = std::max(1, int(std::ceil(3.0 * sigma)));
    std::vector<double> k(std::size_t(2 * r + 1));
    double sum = 0.0;
    for (int i = -r; i <= r; ++i)
        sum += k[std::size_t(i + r)] = std::exp(-0.5 * i * i / (sigma * sigma));
    for (double& w : k) w /= sum;
    std::vector<float> tmp(image.size());
    for (int y = 0; y < height; ++y) // rows
        for (int x = 0; x < width; ++x) {
            double acc = 0.0;
            for (int i = -r; i <= r; ++i)
                acc += k[std::size_t(i + r)] *
                       image[std::size_t(y) * width + std::clamp(x + i, 0, width - 1)];
            tmp[std::size_t(y) * width + x] = float(acc);
        }
    for (int y = 0; y < height; ++y) // columns
        for (int x = 0; x < width; ++x) {
            double acc = 0.0;
            for (int i = -r; i <= r; ++i)
                acc += k[std::size_t(i + r)] *
                       tmp[std::size_t(std::clamp(y + i, 0, height - 1)) * width + x];
            image[std::size_t(y) * width + x] = float(acc);
        }
}

} // namespace fvr::core
