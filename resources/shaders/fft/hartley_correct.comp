#version 430
// The paper's eq. 4: the separable product T of 1D Hartley transforms becomes the 2D Hartley
// transform, H(u,v) = 1/2 (T(u,v) + T(-u,v) + T(u,-v) - T(-u,-v)). FUSED_DISPLAY: also maps the
// result through the display window into the display texture.
// Binding points (generated from fvr/gpu/bindings.h), outside any #ifdef: a file is included
// once, so the includes below reuse these lines.
#include "common/bindings.glsl"
layout(local_size_x = 16, local_size_y = 16) in;
uniform int uM;
#include "common/clip.glsl"
#ifdef FUSED_DISPLAY
#include "common/display.glsl"
#endif
layout(std430, binding = FVR_BINDING_PASS_INPUT) readonly buffer TIn { float tIn[]; };
layout(std430, binding = FVR_BINDING_PASS_OUTPUT) writeonly buffer HOut { float hOut[]; };

void main() {
    int u = int(gl_GlobalInvocationID.x), v = int(gl_GlobalInvocationID.y);
    if (u >= uM || v >= uM) return;
    int mu = u == 0 ? 0 : uM - u;
    int mv = v == 0 ? 0 : uM - v;
    float h = 0.5 * (tIn[v * uM + u] + tIn[v * uM + mu] + tIn[mv * uM + u] - tIn[mv * uM + mu]);
    float p = finalValue(u, v, uM, h);
    hOut[v * uM + u] = p;
#ifdef FUSED_DISPLAY
    storeDisplay(u, v, p);
#endif
}
