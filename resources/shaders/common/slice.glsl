// The central slice of the spectrum, exactly as fvr::core::CpuFourierRenderer samples it:
// k(m, n) = m A + n B in spectrum index units; zero outside the band |k_a| <= P_a / 2; the
// Nyquist row and column average their two aliases; the output centring (-1)^(m+n) and the
// physical scale are folded in. SPECTRUM_FHT selects the real Hartley spectrum (R channel, full
// kx range) instead of the complex half spectrum (RG, kx = 0..P0/2, Hermitian lookups).
// DEPTH_CUE adds the depth cueing term (fvr/core/xray.h): a G(k) + i E.grad G(k) for the complex
// spectrum, a H(k) + E.grad H(-k) for Hartley, E = b/(2 pi) (D_a s_a P_a). The slice filter
// (unsharp mask, Butterworth band limit) multiplies every value when uFilterOn is set.
#include "common/kernel.glsl"

uniform sampler3D uSpectrum;
uniform ivec3 uPadded;
uniform vec3 uHalf;
uniform vec3 uA;
uniform vec3 uB;
uniform float uScale;
uniform int uM;
uniform float uDepthA;
uniform vec3 uDepthE;
uniform int uFilterOn;
uniform float uSharpenAmount;  // 0: no unsharp mask
uniform float uSharpenC;       // 2 pi^2 sigma^2 / (M d)^2 (per squared image frequency index)
uniform float uBandInv2;       // 1 / (nu_c M d)^2; 0: no band limit

#ifdef SPECTRUM_FHT
// The interpolated Hartley value at k, or with `derivative` E.grad H there (depth cueing) from
// the same taps with the derivative weights (fvr::core's sampleHartley<T, Derivative>).
float sampleHartley(vec3 k, bool derivative) {
    if (any(greaterThan(abs(k), uHalf))) return 0.0;
    int bx, by, bz;
    float wx[TAPS], wy[TAPS], wz[TAPS], dx[TAPS], dy[TAPS], dz[TAPS];
#ifdef DEPTH_CUE
    if (derivative) {
        axisWeightsD(k.x, bx, wx, dx);
        axisWeightsD(k.y, by, wy, dy);
        axisWeightsD(k.z, bz, wz, dz);
    } else
#endif
    {
        axisWeights(k.x, bx, wx);
        axisWeights(k.y, by, wy);
        axisWeights(k.z, bz, wz);
    }
    int ix[TAPS], iy[TAPS], iz[TAPS];
    for (int t = 0; t < TAPS; ++t) {
        ix[t] = wrapIndex(bx + t, uPadded.x);
        iy[t] = wrapIndex(by + t, uPadded.y);
        iz[t] = wrapIndex(bz + t, uPadded.z);
    }
    float acc = 0.0;
    for (int zc = 0; zc < TAPS; ++zc)
        for (int yc = 0; yc < TAPS; ++yc) {
            float sx = 0.0, dsx = 0.0;
            for (int xc = 0; xc < TAPS; ++xc) {
                float v = texelFetch(uSpectrum, ivec3(ix[xc], iy[yc], iz[zc]), 0).r;
                sx += wx[xc] * v;
                if (derivative) dsx += dx[xc] * v;
            }
            acc += derivative ? (wz[zc] * wy[yc] * uDepthE.x) * dsx + (uDepthE.y * dy[yc] * wz[zc] + uDepthE.z * wy[yc] * dz[zc]) * sx
                              : (wz[zc] * wy[yc]) * sx;
        }
    return acc;
}
vec2 sampleSpectrum(vec3 k) {
#ifdef DEPTH_CUE
    return vec2(uDepthA * sampleHartley(k, false) + sampleHartley(-k, true), 0.0);
#else
    return vec2(sampleHartley(k, false), 0.0);
#endif
}
#else
vec2 sampleSpectrum(vec3 k) {
    if (any(greaterThan(abs(k), uHalf))) return vec2(0.0);
    bool conjugate = false;
    if (k.x < 0.0) {
        k = -k;
        conjugate = true;
    }
    int bx, by, bz;
    float wx[TAPS], wy[TAPS], wz[TAPS];
#ifdef DEPTH_CUE
    float dx[TAPS], dy[TAPS], dz[TAPS];
    axisWeightsD(k.x, bx, wx, dx);
    axisWeightsD(k.y, by, wy, dy);
    axisWeightsD(k.z, bz, wz, dz);
    vec2 dacc = vec2(0.0);
#else
    axisWeights(k.x, bx, wx);
    axisWeights(k.y, by, wy);
    axisWeights(k.z, bz, wz);
#endif
    int ix[TAPS], iy[TAPS], iz[TAPS], my[TAPS], mz[TAPS];
    bool flip[TAPS];
    int hx = uPadded.x / 2;
    for (int t = 0; t < TAPS; ++t) {
        int jx = bx + t;
        if (jx > hx) jx -= uPadded.x; // beyond the stored half: its negative image
        flip[t] = jx < 0;
        ix[t] = abs(jx);
        iy[t] = wrapIndex(by + t, uPadded.y);
        iz[t] = wrapIndex(bz + t, uPadded.z);
        my[t] = iy[t] == 0 ? 0 : uPadded.y - iy[t];
        mz[t] = iz[t] == 0 ? 0 : uPadded.z - iz[t];
    }
    vec2 acc = vec2(0.0);
    for (int zc = 0; zc < TAPS; ++zc)
        for (int yc = 0; yc < TAPS; ++yc) {
            vec2 sx = vec2(0.0);
#ifdef DEPTH_CUE
            vec2 dsx = vec2(0.0);
#endif
            for (int xc = 0; xc < TAPS; ++xc) {
                vec2 v;
                if (flip[xc]) {
                    v = texelFetch(uSpectrum, ivec3(ix[xc], my[yc], mz[zc]), 0).rg;
                    v.y = -v.y;
                } else {
                    v = texelFetch(uSpectrum, ivec3(ix[xc], iy[yc], iz[zc]), 0).rg;
                }
                sx += wx[xc] * v;
#ifdef DEPTH_CUE
                dsx += dx[xc] * v;
#endif
            }
            acc += (wz[zc] * wy[yc]) * sx;
#ifdef DEPTH_CUE
            dacc += (wz[zc] * wy[yc] * uDepthE.x) * dsx + (uDepthE.y * dy[yc] * wz[zc] + uDepthE.z * wy[yc] * dz[zc]) * sx;
#endif
        }
#ifdef DEPTH_CUE
    acc = vec2(uDepthA * acc.x - dacc.y, uDepthA * acc.y + dacc.x); // a G + i E.grad G
#endif
    // G(k) = conj G(-k) and grad G(k) = -conj grad G(-k): the whole value conjugates.
    return conjugate ? vec2(acc.x, -acc.y) : acc;
}
#endif

vec3 sliceK(int m, int n) { return float(m) * uA + float(n) * uB; }

// The slice filter of fvr::core::SliceFilter at signed image frequency (m, n).
float filterResponse(int m, int n) {
    float r2 = float(m * m + n * n);
    float h = 1.0;
    if (uSharpenAmount > 0.0) h *= 1.0 + uSharpenAmount * (1.0 - exp(-uSharpenC * r2));
    if (uBandInv2 > 0.0) {
        float q = r2 * uBandInv2;
        q *= q;
        q *= q;
        h /= sqrt(1.0 + q * q);
    }
    return h;
}

// Slice value at signed image frequency (m, n), centring sign and scale included.
vec2 sliceValue(int m, int n) {
    int halfM = uM / 2;
    bool nyqM = (m == -halfM);
    bool nyqN = (n == -halfM);
    vec2 v;
    if (nyqM || nyqN) {
        vec2 sum = sampleSpectrum(sliceK(m, n));
        float count = 1.0;
        if (nyqM) { sum += sampleSpectrum(sliceK(-m, n)); count += 1.0; }
        if (nyqN) { sum += sampleSpectrum(sliceK(m, -n)); count += 1.0; }
        if (nyqM && nyqN) { sum += sampleSpectrum(sliceK(-m, -n)); count += 1.0; }
        v = sum / count;
    } else {
        v = sampleSpectrum(sliceK(m, n));
    }
    float scale = ((m + n) & 1) != 0 ? -uScale : uScale;
    if (uFilterOn != 0) scale *= filterResponse(m, n);
    return scale * v;
}
