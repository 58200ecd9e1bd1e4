// The central slice of the spectrum, exactly as fvr::core::CpuFourierRenderer samples it:
// k(m, n) = m A + n B in spectrum index units; the band-limited voxel model (uVoxelModel 0) is
// zero outside the band |k_a| <= P_a / 2 (uHalf); the trilinear (1) and B-spline (2) models read
// the spectrum's continuation (period signs on the antiperiodic axes uAnti) times their transfer
// function (fvr/core/render/voxel_model.h). The Nyquist row and column average their two aliases; the
// output centring (-1)^(m+n) and the physical scale are folded in. SPECTRUM_FHT selects the real Hartley spectrum (R channel, full
// kx range) instead of the complex half spectrum (RG, kx = 0..P0/2, Hermitian lookups).
// DEPTH_CUE adds the depth cueing term (fvr/core/xray/xray.h): a G(k) + i E.grad G(k) for the complex
// spectrum, a H(k) + E.grad H(-k) for Hartley, E = b/(2 pi) (D_a s_a P_a). The slice filter
// (unsharp mask, Butterworth band limit, pixel aperture) multiplies every value when uFilterOn is
// set. The host computes every uniform from fvr::core::SliceParams (slice_params.h) and
// fvr::core::SliceFilterTable (slice_filter.h).
#include "common/bindings.glsl"
#include "common/kernel.glsl"

layout(binding = FVR_TEXTURE_SPECTRUM) uniform sampler3D uSpectrum;
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
uniform float uBandInv2;       // 1 / (nu_c M d)^2; 0: no band limit
uniform int uAperture;         // 1: pixels integrate over their area (sinc(m/M) sinc(n/M))
// fvr::core::SliceFilterTable::axis, |j| = 0..M/2: (the blur's factor, the pixel aperture).
layout(std430, binding = FVR_BINDING_FILTER_AXIS) readonly buffer FilterAxisBuffer { vec2 filterAxis[]; };
uniform int uVoxelModel;       // 0 band-limited, 1 trilinear, 2 cubic B-spline
uniform ivec3 uAnti;           // 1 on axes of an even voxel count
uniform vec3 uInvP;            // 1 / P_a: spectrum index to cycles per voxel

// The model's 1D transfer function t(nu) and its derivative (fvr::core::voxelModelTransfer).
float modelT(float nu, out float dt) {
    float x = 3.14159265358979 * nu;
    float s, ds;
    if (abs(x) < 1e-3) {
        s = 1.0 - x * x / 6.0;
        ds = -3.14159265358979 * x / 3.0;
    } else {
        s = sin(x) / x;
        ds = (cos(x) - s) / nu;
    }
    if (uVoxelModel == 1) {
        dt = 2.0 * s * ds;
        return s * s;
    }
    float den = 2.0 + cos(2.0 * x);
    float g = 3.0 / den;
    float dg = 6.0 * 3.14159265358979 * sin(2.0 * x) / (den * den);
    float s3 = s * s * s;
    dt = 4.0 * s3 * ds * g + s3 * s * dg;
    return s3 * s * g;
}

float sinc(float x) { return abs(x) < 1e-4 ? 1.0 : sin(3.14159265358979 * x) / (3.14159265358979 * x); }

// t(nu) alone: one sine (for the B-spline, cos 2 pi nu = 1 - 2 sin^2 pi nu, sin pi nu = pi nu sinc).
float modelValue(float nu) {
    float s = sinc(nu);
    float s2 = s * s;
    if (uVoxelModel == 1) return s2;
    float x = 3.14159265358979 * nu;
    return s2 * s2 * 3.0 / (3.0 - 2.0 * x * x * s2);
}

// T(k) = prod_a t(k_a / P_a), and with DEPTH_CUE E.grad T.
float modelTransfer(vec3 k, out float gt) {
    vec3 nu = k * uInvP;
#ifdef DEPTH_CUE
    float dx, dy, dz;
    float tx = modelT(nu.x, dx), ty = modelT(nu.y, dy), tz = modelT(nu.z, dz);
    gt = uDepthE.x * uInvP.x * dx * ty * tz + uDepthE.y * uInvP.y * tx * dy * tz + uDepthE.z * uInvP.z * tx * ty * dz;
    return tx * ty * tz;
#else
    gt = 0.0;
    return modelValue(nu.x) * modelValue(nu.y) * modelValue(nu.z);
#endif
}

// The taps' signed indices of one axis with the period signs folded into the weights.
void wrapTaps(int base, int p, bool anti, out int idx[TAPS], inout float w[TAPS]) {
    for (int t = 0; t < TAPS; ++t) {
        float sg;
        idx[t] = wrapSigned(base + t, p, anti, sg);
        w[t] *= sg;
    }
}
#ifdef DEPTH_CUE
void wrapTapsD(int base, int p, bool anti, out int idx[TAPS], inout float w[TAPS], inout float dw[TAPS]) {
    for (int t = 0; t < TAPS; ++t) {
        float sg;
        idx[t] = wrapSigned(base + t, p, anti, sg);
        w[t] *= sg;
        dw[t] *= sg;
    }
}
#endif

#ifdef SPECTRUM_FHT
// The interpolated Hartley value at k (x), and with `derivative` also E.grad H there (y, depth
// cueing) from the same taps with the derivative weights (fvr::core's interpolateHartley).
vec2 sampleHartley(vec3 k, bool derivative) {
    int bx, by, bz;
    float wx[TAPS], wy[TAPS], wz[TAPS], dx[TAPS], dy[TAPS], dz[TAPS];
    int ix[TAPS], iy[TAPS], iz[TAPS];
#ifdef DEPTH_CUE
    if (derivative) {
        axisWeightsD(k.x, bx, wx, dx);
        axisWeightsD(k.y, by, wy, dy);
        axisWeightsD(k.z, bz, wz, dz);
        wrapTapsD(bx, uPadded.x, uAnti.x != 0, ix, wx, dx);
        wrapTapsD(by, uPadded.y, uAnti.y != 0, iy, wy, dy);
        wrapTapsD(bz, uPadded.z, uAnti.z != 0, iz, wz, dz);
    } else
#endif
    {
        axisWeights(k.x, bx, wx);
        axisWeights(k.y, by, wy);
        axisWeights(k.z, bz, wz);
        wrapTaps(bx, uPadded.x, uAnti.x != 0, ix, wx);
        wrapTaps(by, uPadded.y, uAnti.y != 0, iy, wy);
        wrapTaps(bz, uPadded.z, uAnti.z != 0, iz, wz);
    }
    for (int t = 0; t < TAPS; ++t) {
        if (ix[t] < 0) ix[t] += uPadded.x;
        if (iy[t] < 0) iy[t] += uPadded.y;
        if (iz[t] < 0) iz[t] += uPadded.z;
    }
    float acc = 0.0, dacc = 0.0;
    for (int zc = 0; zc < TAPS; ++zc)
        for (int yc = 0; yc < TAPS; ++yc) {
            float sx = 0.0, dsx = 0.0;
            for (int xc = 0; xc < TAPS; ++xc) {
                float v = texelFetch(uSpectrum, ivec3(ix[xc], iy[yc], iz[zc]), 0).r;
                sx += wx[xc] * v;
                if (derivative) dsx += dx[xc] * v;
            }
            acc += (wz[zc] * wy[yc]) * sx;
            if (derivative)
                dacc += (wz[zc] * wy[yc] * uDepthE.x) * dsx + (uDepthE.y * dy[yc] * wz[zc] + uDepthE.z * wy[yc] * dz[zc]) * sx;
        }
    return vec2(acc, dacc);
}
// The model's Hartley value H_m at k, with DEPTH_CUE a H_m(k) + E.grad H_m(-k).
vec2 sampleSpectrum(vec3 k) {
    if (any(greaterThan(abs(k), uHalf))) return vec2(0.0);
    float h = sampleHartley(k, false).x;
    float t = 1.0, gt = 0.0;
    if (uVoxelModel != 0) t = modelTransfer(k, gt);
#ifdef DEPTH_CUE
    vec2 m = sampleHartley(-k, true);
    // T even, grad T odd: E.grad (T H)(-k) = T(k) E.grad H(-k) - H(-k) E.grad T(k).
    return vec2(uDepthA * t * h + t * m.y - gt * m.x, 0.0);
#else
    return vec2(t * h, 0.0);
#endif
}
#else
vec2 sampleSpectrum(vec3 k) {
    if (any(greaterThan(abs(k), uHalf))) return vec2(0.0);
    vec3 k0 = k;
    bool conjugate = false;
    if (k.x < 0.0) {
        k = -k;
        conjugate = true;
    }
    int bx, by, bz;
    float wx[TAPS], wy[TAPS], wz[TAPS];
    int ix[TAPS], iy[TAPS], iz[TAPS], my[TAPS], mz[TAPS];
#ifdef DEPTH_CUE
    float dx[TAPS], dy[TAPS], dz[TAPS];
    axisWeightsD(k.x, bx, wx, dx);
    axisWeightsD(k.y, by, wy, dy);
    axisWeightsD(k.z, bz, wz, dz);
    wrapTapsD(bx, uPadded.x, uAnti.x != 0, ix, wx, dx);
    wrapTapsD(by, uPadded.y, uAnti.y != 0, iy, wy, dy);
    wrapTapsD(bz, uPadded.z, uAnti.z != 0, iz, wz, dz);
    vec2 dacc = vec2(0.0);
#else
    axisWeights(k.x, bx, wx);
    axisWeights(k.y, by, wy);
    axisWeights(k.z, bz, wz);
    wrapTaps(bx, uPadded.x, uAnti.x != 0, ix, wx);
    wrapTaps(by, uPadded.y, uAnti.y != 0, iy, wy);
    wrapTaps(bz, uPadded.z, uAnti.z != 0, iz, wz);
#endif
    bool flip[TAPS];
    float msy[TAPS], msz[TAPS]; // the mirror's sign: -(+P/2) is stored as +P/2, one period away
    for (int t = 0; t < TAPS; ++t) {
        flip[t] = ix[t] < 0; // beyond the stored half: its negative image
        ix[t] = abs(ix[t]);
        msy[t] = (uAnti.y != 0 && 2 * iy[t] == uPadded.y) ? -1.0 : 1.0;
        msz[t] = (uAnti.z != 0 && 2 * iz[t] == uPadded.z) ? -1.0 : 1.0;
        if (iy[t] < 0) iy[t] += uPadded.y;
        if (iz[t] < 0) iz[t] += uPadded.z;
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
                    v *= msy[yc] * msz[zc];
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
    // G(k) = conj G(-k) and grad G(k) = -conj grad G(-k).
    if (conjugate) acc.y = -acc.y;
#ifdef DEPTH_CUE
    if (conjugate) dacc.x = -dacc.x;
#endif
    if (uVoxelModel != 0) {
        float gt;
        float t = modelTransfer(k0, gt);
#ifdef DEPTH_CUE
        dacc = t * dacc + gt * acc; // E.grad (T G)
#endif
        acc *= t;
    }
#ifdef DEPTH_CUE
    acc = vec2(uDepthA * acc.x - dacc.y, uDepthA * acc.y + dacc.x); // a G + i E.grad G
#endif
    return acc;
}
#endif

vec3 sliceK(int m, int n) { return float(m) * uA + float(n) * uB; }

// The slice filter at signed image frequency (m, n) from the frame's fvr::core::SliceFilterTable:
// its per-axis table (blur, aperture) at |m| and |n|, the amount and 1 / (nu_c M d)^2 as uniforms.
// The combination repeats fvr::core::sliceFilterGain (xray.h), which cannot be called from GLSL:
// keep the two alike (the GPU tests compare filtered renders with the CPU's).
float filterResponse(int m, int n) {
    vec2 fm = filterAxis[abs(m)], fn = filterAxis[abs(n)];
    float h = 1.0;
    if (uSharpenAmount > 0.0) h *= 1.0 + uSharpenAmount * (1.0 - fm.x * fn.x);
    float q = float(m * m + n * n) * uBandInv2;
    if (q > 0.0) {
        float q2 = q * q, q4 = q2 * q2;
        h /= sqrt(1.0 + q4 * q4);
    }
    if (uAperture != 0) h *= fm.y * fn.y;
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
