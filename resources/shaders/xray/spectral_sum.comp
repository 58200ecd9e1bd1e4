#version 430
// The polychromatic spectral sum, fvr::core::SpectralResponse::lookup on the GPU: per
// pixel the material mass thicknesses rhoL_m (the material frames' line integrals in rho x mm,
// times uUnit = 0.1 -> g/cm^2, clamped at >= 0) index the response's table (same layout and
// bilinear interpolation, linear beyond its end): g = -ln(I/I0). Writes I/I0 (uOutput 0),
// -ln(I/I0) (1) or material uShow's rhoL in g/cm^2 (2, not clamped). MATERIALS (1..5) frames at
// FVR_BINDING_MATERIAL_0.. (common/bindings.glsl).
// Binding points (generated from fvr/gpu/bindings.h), outside any #ifdef: a file is included
// once, so the includes below reuse these lines.
#include "common/bindings.glsl"
layout(local_size_x = 256) in;
uniform int uCount;
uniform int uN;
uniform int uStride;
uniform int uHasY;
uniform float uSx;
uniform float uSy;
uniform float uUnit;
uniform int uAxisX;
uniform int uAxisY;
uniform int uOthers;
uniform int uOther[4];
uniform float uScale[4];
uniform int uOutput;
uniform int uShow;
layout(std430, binding = FVR_BINDING_PASS_OUTPUT) writeonly buffer Out { float outValue[]; };
layout(std430, binding = FVR_BINDING_SPECTRAL_TABLE) readonly buffer Table { float nodes[]; };
layout(std430, binding = FVR_BINDING_MATERIAL_0) readonly buffer M0 { float m0[]; };
#if MATERIALS > 1
layout(std430, binding = FVR_BINDING_MATERIAL_1) readonly buffer M1 { float m1[]; };
#endif
#if MATERIALS > 2
layout(std430, binding = FVR_BINDING_MATERIAL_2) readonly buffer M2 { float m2[]; };
#endif
#if MATERIALS > 3
layout(std430, binding = FVR_BINDING_MATERIAL_3) readonly buffer M3 { float m3[]; };
#endif
#if MATERIALS > 4
layout(std430, binding = FVR_BINDING_MATERIAL_4) readonly buffer M4 { float m4[]; };
#endif

float raw(int m, int p) {
    float v = m0[p];
#if MATERIALS > 1
    if (m == 1) v = m1[p];
#endif
#if MATERIALS > 2
    if (m == 2) v = m2[p];
#endif
#if MATERIALS > 3
    if (m == 3) v = m3[p];
#endif
#if MATERIALS > 4
    if (m == 4) v = m4[p];
#endif
    return v * uUnit;
}

float rhoL(int m, int p) { return max(0.0, raw(m, p)); }

void main() {
    int p = int(gl_GlobalInvocationID.x);
    if (p >= uCount) return;
    if (uOutput == 2) {
        outValue[p] = raw(uShow, p); // as the CPU shows it: not clamped
        return;
    }
    float x = rhoL(uAxisX, p);
    float z[4];
    for (int o = 0; o < uOthers; ++o) {
        z[o] = rhoL(uOther[o], p);
        x += uScale[o] * z[o];
    }
    float u = x * uSx;
    int i = min(int(u), uN - 2);
    float tx = u - float(i);
    int a = i * uStride;
    float ty = 0.0;
    int rowStep = uN * uStride;
    if (uHasY != 0) {
        float w = rhoL(uAxisY, p) * uSy;
        int j = min(int(w), uN - 2);
        ty = w - float(j);
        a += j * rowStep;
    }
    float g = 0.0;
    for (int s = 0; s < uStride; ++s) {
        float v = nodes[a + s] + tx * (nodes[a + s + uStride] - nodes[a + s]);
        if (uHasY != 0) {
            int c = a + rowStep;
            float r1 = nodes[c + s] + tx * (nodes[c + s + uStride] - nodes[c + s]);
            v += ty * (r1 - v);
        }
        g += s == 0 ? v : v * z[s - 1];
    }
    outValue[p] = uOutput == 1 ? g : exp(-g);
}
