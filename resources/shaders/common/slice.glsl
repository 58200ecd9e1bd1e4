// The central slice of the spectrum, exactly as fvr::core::CpuFourierRenderer samples it:
// k(m, n) = m A + n B in spectrum index units; zero outside the band |k_a| <= P_a / 2; the
// Nyquist row and column average their two aliases; the output centring (-1)^(m+n) and the
// physical scale are folded in. SPECTRUM_FHT selects the real Hartley spectrum (R channel, full
// kx range) instead of the complex half spectrum (RG, kx = 0..P0/2, Hermitian lookups).
#include "common/kernel.glsl"

uniform sampler3D uSpectrum;
uniform ivec3 uPadded;
uniform vec3 uHalf;
uniform vec3 uA;
uniform vec3 uB;
uniform float uScale;
uniform int uM;

#ifdef SPECTRUM_FHT
vec2 sampleSpectrum(vec3 k) {
    if (any(greaterThan(abs(k), uHalf))) return vec2(0.0);
    int bx, by, bz;
    float wx[TAPS], wy[TAPS], wz[TAPS];
    axisWeights(k.x, bx, wx);
    axisWeights(k.y, by, wy);
    axisWeights(k.z, bz, wz);
    int ix[TAPS], iy[TAPS], iz[TAPS];
    for (int t = 0; t < TAPS; ++t) {
        ix[t] = wrapIndex(bx + t, uPadded.x);
        iy[t] = wrapIndex(by + t, uPadded.y);
        iz[t] = wrapIndex(bz + t, uPadded.z);
    }
    float acc = 0.0;
    for (int zc = 0; zc < TAPS; ++zc)
        for (int yc = 0; yc < TAPS; ++yc) {
            float sx = 0.0;
            for (int xc = 0; xc < TAPS; ++xc)
                sx += wx[xc] * texelFetch(uSpectrum, ivec3(ix[xc], iy[yc], iz[zc]), 0).r;
            acc += (wz[zc] * wy[yc]) * sx;
        }
    return vec2(acc, 0.0);
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
    axisWeights(k.x, bx, wx);
    axisWeights(k.y, by, wy);
    axisWeights(k.z, bz, wz);
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
            for (int xc = 0; xc < TAPS; ++xc) {
                vec2 v;
                if (flip[xc]) {
                    v = texelFetch(uSpectrum, ivec3(ix[xc], my[yc], mz[zc]), 0).rg;
                    v.y = -v.y;
                } else {
                    v = texelFetch(uSpectrum, ivec3(ix[xc], iy[yc], iz[zc]), 0).rg;
                }
                sx += wx[xc] * v;
            }
            acc += (wz[zc] * wy[yc]) * sx;
        }
    return conjugate ? vec2(acc.x, -acc.y) : acc;
}
#endif

vec3 sliceK(int m, int n) { return float(m) * uA + float(n) * uB; }

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
    return (((m + n) & 1) != 0 ? -uScale : uScale) * v;
}
