#version 430
// Row pass of the inverse 2D transform: one work group per row. Input is either the slice,
// sampled right here (FUSED_SLICE: the slice never goes through global memory), or a complex
// buffer. Output is written transposed so the column pass reads contiguous memory.
// HARTLEY_ROWS: the input is real; the row's 1D Hartley transform Re + Im of its inverse FFT is
// written as (t, 0).
// Binding points (generated from fvr/gpu/bindings.h), outside any #ifdef: a file is included
// once, so the includes below reuse these lines.
#include "common/bindings.glsl"
layout(local_size_x = WG_SIZE) in;
#include "common/fft.glsl"
#ifdef FUSED_SLICE
#include "common/slice.glsl"
#else
uniform int uM;
layout(std430, binding = FVR_BINDING_PASS_INPUT) readonly buffer RowsIn { vec2 rowsIn[]; };
#endif
layout(std430, binding = FVR_BINDING_PASS_OUTPUT) writeonly buffer RowsOut { vec2 rowsOut[]; };

void main() {
    int r = int(gl_WorkGroupID.x);
    int lid = int(gl_LocalInvocationID.x);
    for (int i = lid; i < uM; i += WG_SIZE) {
#ifdef FUSED_SLICE
        int m = i < uM / 2 ? i : i - uM;
        int n = r < uM / 2 ? r : r - uM;
        row[i] = sliceValue(m, n);
#else
        row[i] = rowsIn[r * uM + i];
#endif
    }
    memoryBarrierShared();
    barrier();
    fftInShared(uM);
    for (int i = lid; i < uM; i += WG_SIZE) {
#ifdef HARTLEY_ROWS
        rowsOut[i * uM + r] = vec2(row[i].x + row[i].y, 0.0);
#else
        rowsOut[i * uM + r] = row[i];
#endif
    }
}
