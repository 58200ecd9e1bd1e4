// In-place radix-2 FFT of one row held in shared memory, as fvr::gpu::FftPlan plans it: the
// caller stores input i at bitReverse(i); log2(M) butterfly stages with twiddles from the plan.
layout(std430, binding = 3) readonly buffer TwiddleBuffer { vec2 twiddles[]; };
uniform int uLog2M;

shared vec2 row[MAX_M];

int bitReverse(int i) { return int(bitfieldReverse(uint(i)) >> uint(32 - uLog2M)); }

void fftInShared(int M) {
    int lid = int(gl_LocalInvocationID.x);
    for (int h = 1; h < M; h <<= 1) {
        int stride = M / (2 * h);
        for (int j = lid; j < M / 2; j += WG_SIZE) {
            int pos = j & (h - 1);
            int i0 = (j - pos) * 2 + pos;
            int i1 = i0 + h;
            vec2 w = twiddles[pos * stride];
            vec2 b = row[i1];
            b = vec2(b.x * w.x - b.y * w.y, b.x * w.y + b.y * w.x);
            vec2 a = row[i0];
            row[i0] = a + b;
            row[i1] = a - b;
        }
        memoryBarrierShared();
        barrier();
    }
}
