#version 430
// Column pass: one work group per column of the image (a row of the transposed buffer).
// OUTPUT_REAL: the projection (real part; the slice was Hermitian). OUTPUT_HARTLEY: Re + Im, the
// separable 2D Hartley product T that the eq. 4 pass corrects. OUTPUT_COMPLEX: the complex
// result (tests), row-major. FUSED_DISPLAY (with OUTPUT_REAL): also maps the projection through
// the display window into the display texture, saving the display pass a read of the image.
// Binding points (generated from fvr/gpu/bindings.h), outside any #ifdef: a file is included
// once, so the includes below reuse these lines.
#include "common/bindings.glsl"
layout(local_size_x = WG_SIZE) in;
#include "common/fft.glsl"
uniform int uM;
#ifdef OUTPUT_REAL
#include "common/clip.glsl"
#ifdef FUSED_DISPLAY
#include "common/display.glsl"
#endif
#endif
layout(std430, binding = FVR_BINDING_PASS_INPUT) readonly buffer ColsIn { vec2 colsIn[]; };
#ifdef OUTPUT_COMPLEX
layout(std430, binding = FVR_BINDING_PASS_OUTPUT) writeonly buffer ColsOut { vec2 colsOut[]; };
#else
layout(std430, binding = FVR_BINDING_PASS_OUTPUT) writeonly buffer ColsOut { float colsOut[]; };
#endif

void main() {
    int c = int(gl_WorkGroupID.x);
    int lid = int(gl_LocalInvocationID.x);
    for (int i = lid; i < uM; i += WG_SIZE) row[i] = colsIn[c * uM + i];
    memoryBarrierShared();
    barrier();
    fftInShared(uM);
    for (int i = lid; i < uM; i += WG_SIZE) {
#if defined(OUTPUT_COMPLEX)
        colsOut[i * uM + c] = row[i];
#elif defined(OUTPUT_HARTLEY)
        colsOut[i * uM + c] = row[i].x + row[i].y;
#else
        float p = finalValue(c, i, uM, row[i].x);
        colsOut[i * uM + c] = p;
#ifdef FUSED_DISPLAY
        storeDisplay(c, i, p);
#endif
#endif
    }
}
