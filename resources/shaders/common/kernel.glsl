// Separable interpolation weights, from the same 1D table as the CPU renderer
// (fvr::core::KernelTable: kResolution intervals, taps per row, linear interpolation between
// rows). TAPS (1, 2, 3 = linear with depth cueing, 4 or 6) is defined by the host when it compiles a kernel variant; the
// general branch serves any even TAPS >= 4 (first tap at floor(k) + uKernelFirst, uKernelFirst =
// -(TAPS/2 - 1)).
#include "common/bindings.glsl"
layout(std430, binding = FVR_BINDING_KERNEL_TABLE) readonly buffer KernelTableBuffer { float kernelTable[]; };
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
#elif TAPS == 3
    // The linear kernel over three taps (depth cueing, see axisWeightsD).
    float f = floor(k);
    base = int(f) - 1;
    w[0] = 0.0;
    w[2] = k - f;
    w[1] = 1.0 - w[2];
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

// Signed index in (-p/2, p/2] of index i, and the sign of its period where the axis is
// antiperiodic (an even voxel count: the spectrum changes sign from one period to the next;
// fvr::core's wrapAxis). q = ceil((i - p/2) / p) periods are taken off.
int wrapSigned(int i, int p, bool anti, out float sgn) {
    int hi = p / 2;
    int q = i > hi ? (i - hi + p - 1) / p : -((hi - i) / p);
    sgn = (anti && (q & 1) != 0) ? -1.0 : 1.0;
    return i - q * p;
}

#ifdef DEPTH_CUE
// Derivative weights d w_j / d frac (fvr::core::KernelTable::derivativeTable, same layout) for
// depth cueing: the derivative of the interpolated spectrum along each axis.
layout(std430, binding = FVR_BINDING_KERNEL_DERIVATIVE) readonly buffer KernelDerivativeBuffer { float kernelDerivative[]; };

void axisWeightsD(float k, out int base, out float w[TAPS], out float dw[TAPS]) {
#if TAPS == 3
    // The linear kernel (TAPS 3 is linear with depth cueing): derivative -1, +1 between integers,
    // the central difference on them (mean of both sides; fvr::core's axisDerivWeights<3>).
    float r = floor(k + 0.5);
    if (abs(k - r) < 1e-5) {
        base = int(r) - 1;
        w[0] = 0.0; w[1] = 1.0; w[2] = 0.0;
        dw[0] = -0.5; dw[1] = 0.0; dw[2] = 0.5;
        return;
    }
#endif
    axisWeights(k, base, w);
#if TAPS == 1
    dw[0] = 0.0;
#elif TAPS == 2
    dw[0] = -1.0;
    dw[1] = 1.0;
#elif TAPS == 3
    dw[0] = 0.0; dw[1] = -1.0; dw[2] = 1.0;
#else
    // The derivative table at the same fractional position as the weights.
    float pos = (k - floor(k)) * float(uKernelRes);
    int i = min(int(pos), uKernelRes - 1);
    float t = pos - float(i);
    for (int j = 0; j < TAPS; ++j) {
        float da = kernelDerivative[i * TAPS + j];
        float db = kernelDerivative[(i + 1) * TAPS + j];
        dw[j] = da + t * (db - da);
    }
#endif
}
#endif
