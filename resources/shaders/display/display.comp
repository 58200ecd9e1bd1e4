#version 430
// Display mapping (fvr::core::DisplayWindow::map): line integrals, or with uMuWater > 0 the log
// exposure min(0, log10(uExposure exp(-uMuWater L))) of the Beer-Lambert signal (film), -> 8-bit
// gray through a window (low -> black, high -> white), optionally inverted. Image row 0 (the top)
// goes to texel row 0.
layout(local_size_x = 16, local_size_y = 16) in;
uniform int uM;
uniform float uLow;
uniform float uHigh;
uniform int uInvert;
uniform float uMuWater;
uniform float uExposure;
layout(std430, binding = 1) readonly buffer ImageIn { float imageIn[]; };
layout(rgba8, binding = 0) writeonly uniform image2D displayOut;

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= uM || p.y >= uM) return;
    float v = imageIn[p.y * uM + p.x];
    const float ln10 = 2.302585092994046;
    if (uMuWater > 0.0) v = min(0.0, (log(uExposure) - uMuWater * v) / ln10);
    float t = clamp((v - uLow) / (uHigh - uLow), 0.0, 1.0);
    if (uInvert != 0) t = 1.0 - t;
    imageStore(displayOut, p, vec4(t, t, t, 1.0));
}
