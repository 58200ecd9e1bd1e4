#version 430
// Slice pass (unfused): the full M x M complex slice, row-major, rows and columns wrapped.
// Binding points (generated from fvr/gpu/bindings.h), outside any #ifdef: a file is included
// once, so the includes below reuse these lines.
#include "common/bindings.glsl"
layout(local_size_x = 16, local_size_y = 16) in;
#include "common/slice.glsl"
layout(std430, binding = FVR_BINDING_PASS_OUTPUT) writeonly buffer SliceOut { vec2 sliceOut[]; };

void main() {
    int col = int(gl_GlobalInvocationID.x), r = int(gl_GlobalInvocationID.y);
    if (col >= uM || r >= uM) return;
    int m = col < uM / 2 ? col : col - uM;
    int n = r < uM / 2 ? r : r - uM;
    sliceOut[r * uM + col] = sliceValue(m, n);
}
