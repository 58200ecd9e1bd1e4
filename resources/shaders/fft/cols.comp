#version 430
// Column pass: one work group per column of the image (a row of the transposed buffer).
// OUTPUT_REAL: the projection (real part; the slice was Hermitian). OUTPUT_HARTLEY: Re + Im, the
// separable 2D Hartley product T that the eq. 4 pass corrects. OUTPUT_COMPLEX: the complex
// result (tests), row-major.
layout(local_size_x = WG_SIZE) in;
#include "common/fft.glsl"
uniform int uM;
#ifdef OUTPUT_REAL
#include "common/clip.glsl"
#endif
layout(std430, binding = 1) readonly buffer ColsIn { vec2 colsIn[]; };
#ifdef OUTPUT_COMPLEX
layout(std430, binding = 0) writeonly buffer ColsOut { vec2 colsOut[]; };
#else
layout(std430, binding = 0) writeonly buffer ColsOut { float colsOut[]; };
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
        colsOut[i * uM + c] = (uClip != 0 && rayMissesVolume(c, i, uM)) ? 0.0 : row[i].x;
#endif
    }
}
