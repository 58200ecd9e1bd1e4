#version 430
// Display pass: maps the last projection through a new window (common/display.glsl) without
// rendering again.
// Binding points (generated from fvr/gpu/bindings.h), outside any #ifdef: a file is included
// once, so the includes below reuse these lines.
#include "common/bindings.glsl"
layout(local_size_x = 16, local_size_y = 16) in;
uniform int uM;
#include "common/display.glsl"
layout(std430, binding = FVR_BINDING_PASS_INPUT) readonly buffer ImageIn { float imageIn[]; };

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= uM || p.y >= uM) return;
    storeDisplay(p.x, p.y, imageIn[p.y * uM + p.x]);
}
