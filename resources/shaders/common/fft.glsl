// Stockham autosort FFT of one row held in shared memory, as fvr::gpu::FftPlan plans it: natural
// order in and out; radix-4 stages while they divide M, then one radix-2 stage for odd log2 M.
// Stage (span Ns, radix R): butterfly j reads x[j + r M/R] times twiddles[(j mod Ns) r M/(Ns R)],
// does the R-point DFT in registers and writes output r to (j - j mod Ns) R + j mod Ns + r Ns.
// Every thread reads all its inputs before a barrier and writes after it, so the stages run in
// place in one shared array. twiddles[k] = exp(s 2 pi i k / M), k < M (s = +1 for the inverse).
#include "common/bindings.glsl"
layout(std430, binding = FVR_BINDING_TWIDDLES) readonly buffer TwiddleBuffer { vec2 twiddles[]; };

shared vec2 row[MAX_M];

const int R4_PER_THREAD = MAX_M >= 4 ? (MAX_M / 4 + WG_SIZE - 1) / WG_SIZE : 1;
const int R2_PER_THREAD = (MAX_M / 2 + WG_SIZE - 1) / WG_SIZE;

vec2 cmul(vec2 a, vec2 b) { return vec2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x); }

void fftInShared(int M) {
    int lid = int(gl_LocalInvocationID.x);
    float s = M >= 4 ? twiddles[M / 4].y : 1.0; // sin(s pi / 2) = s exactly
    int Ns = 1;
    for (; Ns * 4 <= M; Ns *= 4) {
        int q = M / 4;
        int stride = M / (Ns * 4);
        vec2 v[R4_PER_THREAD][4];
        for (int b = 0; b < R4_PER_THREAD; ++b) {
            int j = lid + b * WG_SIZE;
            if (j < q) {
                int k = j & (Ns - 1);
                v[b][0] = row[j];
                v[b][1] = cmul(row[j + q], twiddles[k * stride]);
                v[b][2] = cmul(row[j + 2 * q], twiddles[2 * k * stride]);
                v[b][3] = cmul(row[j + 3 * q], twiddles[3 * k * stride]);
            }
        }
        memoryBarrierShared();
        barrier();
        for (int b = 0; b < R4_PER_THREAD; ++b) {
            int j = lid + b * WG_SIZE;
            if (j < q) {
                int k = j & (Ns - 1);
                vec2 t0 = v[b][0] + v[b][2], t1 = v[b][0] - v[b][2], t2 = v[b][1] + v[b][3];
                vec2 u = v[b][1] - v[b][3];
                vec2 t3 = vec2(-s * u.y, s * u.x); // (s i) u
                int d = (j - k) * 4 + k;
                row[d] = t0 + t2;
                row[d + Ns] = t1 + t3;
                row[d + 2 * Ns] = t0 - t2;
                row[d + 3 * Ns] = t1 - t3;
            }
        }
        memoryBarrierShared();
        barrier();
    }
    if (Ns < M) { // the radix-2 stage
        int q = M / 2;
        int stride = M / (Ns * 2);
        vec2 v[R2_PER_THREAD][2];
        for (int b = 0; b < R2_PER_THREAD; ++b) {
            int j = lid + b * WG_SIZE;
            if (j < q) {
                int k = j & (Ns - 1);
                v[b][0] = row[j];
                v[b][1] = cmul(row[j + q], twiddles[k * stride]);
            }
        }
        memoryBarrierShared();
        barrier();
        for (int b = 0; b < R2_PER_THREAD; ++b) {
            int j = lid + b * WG_SIZE;
            if (j < q) {
                int k = j & (Ns - 1);
                int d = (j - k) * 2 + k;
                row[d] = v[b][0] + v[b][1];
                row[d + Ns] = v[b][0] - v[b][1];
            }
        }
        memoryBarrierShared();
        barrier();
    }
}
