// Display mapping (fvr::core::DisplayWindow::map): line integrals, or with uMuWater > 0 the log
// exposure min(0, log10(uExposure exp(-uMuWater max(L, 0)))) of the Beer-Lambert signal (film), -> 8-bit
// gray through a window (low -> black, high -> white), optionally inverted. Used by the display
// pass (a window change) and fused into the last pass of the inverse transform (a new frame).
uniform float uLow;
uniform float uHigh;
uniform int uInvert;
uniform float uMuWater;
uniform float uExposure;
#include "common/bindings.glsl"
layout(rgba8, binding = FVR_IMAGE_DISPLAY) writeonly uniform image2D displayOut;

// Image row `row` (0 at the top) goes to texel row `row`.
void storeDisplay(int col, int row, float lineIntegral) {
    float v = lineIntegral;
    const float ln10 = 2.302585092994046;
    if (uMuWater > 0.0) v = min(0.0, (log(uExposure) - uMuWater * max(v, 0.0)) / ln10);
    float t = clamp((v - uLow) / (uHigh - uLow), 0.0, 1.0);
    if (uInvert != 0) t = 1.0 - t;
    imageStore(displayOut, ivec2(col, row), vec4(t, t, t, 1.0));
}
