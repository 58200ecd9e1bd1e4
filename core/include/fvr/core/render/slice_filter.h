#pragma once
/** The slice filter (xray.h SliceFilter) and the pixel aperture (RenderParams::pixelAperture) of
 *  one frame at the image's integer frequencies, built once per frame for both renderers: the CPU
 *  evaluates operator(), the GPU uploads axis() as a buffer and combines it in slice.glsl. */
#include <vector>

#include <fvr/core/xray/xray.h>

namespace fvr::core {

struct SliceFilterTable {
    /** False when neither the filter nor the aperture is on (the slice is left as it is). */
    bool on = false;
    /** The unsharp mask's amount a (0: none). */
    float amount = 0.0f;
    /** 1 / (nu_c M d)^2: q = (m^2 + n^2) invCut2 = (nu / nu_c)^2; 0: no band limit. */
    float invCut2 = 0.0f;
    bool aperture = false;
    /** Per |j| = 0..M/2, interleaved: the blur's factor SliceFilter::blur(j / (M d)) (1 without
     *  sharpening) and the pixel aperture pixelApertureResponse(j / M) (1 for point pixels). The
     *  blur is separable: blur(m, n) = blur(|m|) blur(|n|). */
    std::vector<float> axis;

    SliceFilterTable(const SliceFilter& filter, bool pixelAperture, int M, double pixelSize);

    float blur(int j) const { return axis[2 * std::size_t(j < 0 ? -j : j)]; }
    float apertureAt(int j) const { return axis[2 * std::size_t(j < 0 ? -j : j) + 1]; }
    /** H(m, n) at signed image frequencies: sliceFilterGain of the table's parts, times the
     *  aperture's sinc(m / M) sinc(n / M) when it is on. */
    float operator()(int m, int n) const {
        float h = sliceFilterGain(amount, amount > 0.0f ? blur(m) * blur(n) : 1.0f,
                                  float(m * m + n * n) * invCut2);
        if (aperture) h *= apertureAt(m) * apertureAt(n);
        return h;
    }
};

} // namespace fvr::core
