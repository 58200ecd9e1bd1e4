// Separable interpolation weights, from the same 1D table as the CPU renderer
// (fvr::core::KernelTable: kResolution intervals, taps per row, linear interpolation between
// rows). TAPS (1, 2, 4 or 6) is defined by the host when it compiles a kernel variant; the
// general branch serves any even TAPS >= 4 (first tap at floor(k) + uKernelFirst, uKernelFirst =
// -(TAPS/2 - 1)).
layout(std430, binding = 2) readonly buffer KernelTableBuffer { float kernelTable[]; };
uniform int uKernelRes;
uniform int uKernelFirst;

void axisWeights(float k, out int base, out float w[TAPS]) {
#if TAPS == 1
    base = int(floor(k + 0.5));
    w[0] = 1.0;
#elif TAPS == 2
    float f = floor(k);
    base = int(f);
    w[1] = k - f;
    w[0] = 1.0 - w[1];
#else
    float f = floor(k);
    base = int(f) + uKernelFirst;
    float pos = (k - f) * float(uKernelRes);
    int i = min(int(pos), uKernelRes - 1);
    float t = pos - float(i);
    for (int j = 0; j < TAPS; ++j) {
        float a = kernelTable[i * TAPS + j];
        float b = kernelTable[(i + 1) * TAPS + j];
        w[j] = a + t * (b - a);
    }
#endif
}

// i lies within two periods of [0, p): GLSL's % is undefined for negative operands.
int wrapIndex(int i, int p) {
    if (i < 0) i += p;
    if (i < 0) i += p;
    if (i >= p) i -= p;
    if (i >= p) i -= p;
    return i;
}
