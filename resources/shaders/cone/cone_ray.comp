#version 430
// Cone-beam ray casting (fvr::gpu::ConeRayCaster), one invocation per detector pixel and view
// (gl_GlobalInvocationID.z: the view, its rays from the ConeViews buffer): the line integral of the volume's voxel model from the source to the pixel's centre, as
// fvr::core::ConeProjector computes it on the CPU. Positions are continuous voxel indices (voxel
// centres at integers) relative to the grid's centre (N-1)/2; the host computes the ray vectors
// in double, relative to that centre, so float keeps its precision inside the volume.
// Variants (host defines):
//   MODEL 0  box: each voxel a constant cube, exact path lengths (Amanatides-Woo walk);
//   MODEL 1  trilinear, exact: a walk over the cells between voxel centres (support [-1, N]),
//            Simpson's rule on each cell's segment (the interpolant is a cubic along a ray
//            inside a cell, so the rule is exact);
//   MODEL 2  trilinear, midpoint samples at uStep mm over the ray's part in [-1, N]^3;
//   HW_FILTER 1  trilinear values from the texture's GL_LINEAR filter (border 0: zero outside)
//            instead of 8 texelFetches with float weights (the hardware's weights are fixed
//            point: 8 fraction bits on NVIDIA);
//   SUBSAMPLES n  n x n rays per pixel at the centres of its n x n sub-pixels, averaged;
//   SKIP_EMPTY 1  blocks of 8^3 cells whose corners are all 0 left out (exact: they add 0).
#include "common/bindings.glsl"
layout(local_size_x = 16, local_size_y = 16) in;

#ifndef MODEL
#define MODEL 1
#endif
#ifndef HW_FILTER
#define HW_FILTER 0
#endif
#ifndef SUBSAMPLES
#define SUBSAMPLES 1
#endif
#ifndef SKIP_EMPTY
#define SKIP_EMPTY 0
#endif

layout(binding = FVR_TEXTURE_VOLUME) uniform sampler3D uVolume;
#if SKIP_EMPTY
/** Per block of 8^3 cells of the walk: 1 where a cell touches a non-zero voxel. */
layout(binding = FVR_TEXTURE_OCCUPANCY) uniform usampler3D uOccupancy;
#endif
layout(std430, binding = FVR_BINDING_PASS_OUTPUT) writeonly buffer ConeOut { float outValue[]; };
/** One view's rays (xyz; w unused): the source relative to the centre, the centre of pixel
 *  (0, 0) minus the source, one column and one row along the detector, in voxel indices. */
struct ConeView {
    vec4 source;
    vec4 dir0;
    vec4 dirCol;
    vec4 dirRow;
};
layout(std430, binding = FVR_BINDING_PASS_INPUT) readonly buffer ConeViews { ConeView views[]; };

uniform ivec3 uSize; // W, H, views
uniform ivec3 uDims; // voxels per index axis
uniform vec3 uCentre; // (N - 1) / 2
uniform mat3 uIndexToMm; // index steps to LPS millimetres (direction cosines x spacing)
uniform float uStep; // MODEL 2: the sampling step, mm

const float kFar = 3.0e38;

/** A voxel's value, 0 outside the grid. */
float voxel(ivec3 i) {
    return all(greaterThanEqual(i, ivec3(0))) && all(lessThan(i, uDims))
               ? texelFetch(uVolume, i, 0).r
               : 0.0;
}

/** The trilinear interpolant at q (absolute voxel indices), zero outside the grid. */
float trilinear(vec3 q) {
#if HW_FILTER
    return texture(uVolume, (q + 0.5) / vec3(uDims)).r;
#else
    vec3 fl = floor(q);
    ivec3 i = ivec3(fl);
    vec3 f = q - fl;
    float c00 = mix(voxel(i), voxel(i + ivec3(1, 0, 0)), f.x);
    float c10 = mix(voxel(i + ivec3(0, 1, 0)), voxel(i + ivec3(1, 1, 0)), f.x);
    float c01 = mix(voxel(i + ivec3(0, 0, 1)), voxel(i + ivec3(1, 0, 1)), f.x);
    float c11 = mix(voxel(i + ivec3(0, 1, 1)), voxel(i + ivec3(1, 1, 1)), f.x);
    return mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
#endif
}

/** The part [t0, t1] of s + t d, t in [0, 1] (source to pixel), inside |x| <= h per axis. */
bool clipRay(vec3 s, vec3 d, vec3 h, out float t0, out float t1) {
    t0 = 0.0;
    t1 = 1.0;
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (abs(s[a]) >= h[a]) return false;
            continue;
        }
        float ta = (-h[a] - s[a]) / d[a], tb = (h[a] - s[a]) / d[a];
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
    return t0 < t1;
}

#if MODEL == 0 || MODEL == 1
/** The integral over one cell's segment [ta, tb] of g0 + t d (g: cell k spans [k, k+1]).
 *  fEdge: with HW_FILTER, the interpolant at ta on entry (the previous segment's end), at tb on
 *  return, so each cell costs 2 filtered fetches. */
float cellSegment(ivec3 cell, vec3 g0, vec3 d, float ta, float tb, inout float fEdge) {
#if MODEL == 0
    return (tb - ta) * voxel(cell); // g = q + 1/2: cell k is voxel k
#else
    float tm = 0.5 * (ta + tb);
#if HW_FILTER
    // g = q + 1: the texture coordinate of g is (g - 1/2) / N.
    vec3 inv = 1.0 / vec3(uDims);
    float fa = fEdge;
    float fm = texture(uVolume, (g0 + tm * d - 0.5) * inv).r;
    float fb = texture(uVolume, (g0 + tb * d - 0.5) * inv).r;
    fEdge = fb;
#else
    // g = q + 1: cell k lies between voxels k - 1 and k; fetch its 8 corners once.
    ivec3 i = cell - 1;
    float c000 = voxel(i), c100 = voxel(i + ivec3(1, 0, 0));
    float c010 = voxel(i + ivec3(0, 1, 0)), c110 = voxel(i + ivec3(1, 1, 0));
    float c001 = voxel(i + ivec3(0, 0, 1)), c101 = voxel(i + ivec3(1, 0, 1));
    float c011 = voxel(i + ivec3(0, 1, 1)), c111 = voxel(i + ivec3(1, 1, 1));
    float fv[3];
    float ts[3] = float[3](ta, tm, tb);
    for (int k = 0; k < 3; ++k) {
        vec3 f = clamp(g0 + ts[k] * d - vec3(cell), 0.0, 1.0);
        fv[k] = mix(mix(mix(c000, c100, f.x), mix(c010, c110, f.x), f.y),
                    mix(mix(c001, c101, f.x), mix(c011, c111, f.x), f.y), f.z);
    }
    float fa = fv[0], fm = fv[1], fb = fv[2];
#endif
    return (tb - ta) * (fa + 4.0 * fm + fb) / 6.0;
#endif
}

/** The integral (per unit t) along g0 + t d, t in [ta, tb], over the unit cells [lo, hi) per
 *  axis (cell k spans [k, k+1]): Amanatides and Woo's walk, each boundary computed from g0 (no
 *  running sums), so that walks restarted at block boundaries meet the same boundaries. */
float walkCells(vec3 g0, vec3 d, float ta, float tb, ivec3 lo, ivec3 hi, inout float fEdge) {
    ivec3 cell, stepDir;
    vec3 tMax, invD;
    for (int a = 0; a < 3; ++a) {
        float p = g0[a] + ta * d[a];
        float c = floor(p);
        if (d[a] < 0.0 && c == p) c -= 1.0; // on a boundary going down: the cell below
        cell[a] = clamp(int(c), lo[a], hi[a] - 1);
        stepDir[a] = d[a] > 0.0 ? 1 : (d[a] < 0.0 ? -1 : 0);
        invD[a] = d[a] != 0.0 ? 1.0 / d[a] : 0.0;
        tMax[a] = d[a] != 0.0 ? (float(cell[a] + max(stepDir[a], 0)) - g0[a]) * invD[a] : kFar;
    }
    float t = ta, sum = 0.0;
    int guard = (hi.x - lo.x) + (hi.y - lo.y) + (hi.z - lo.z) + 3;
    for (int it = 0; it < guard && t < tb; ++it) {
        int m = tMax.x < tMax.y ? (tMax.x < tMax.z ? 0 : 2) : (tMax.y < tMax.z ? 1 : 2);
        float tn = min(tMax[m], tb);
        if (tn > t) {
            sum += cellSegment(cell, g0, d, t, tn, fEdge);
            t = tn;
        }
        cell[m] += stepDir[m];
        if (cell[m] < lo[m] || cell[m] >= hi[m]) break;
        tMax[m] = (float(cell[m] + max(stepDir[m], 0)) - g0[m]) * invD[m];
    }
    return sum;
}
#endif

/** The interpolant at g0 + t d (g = q + 1), where the hardware-filtered exact walk starts. */
float edgeValue(vec3 g0, vec3 d, float t) {
#if MODEL == 1 && HW_FILTER
    return texture(uVolume, (g0 + t * d - 0.5) / vec3(uDims)).r;
#else
    return 0.0;
#endif
}

#if SKIP_EMPTY
/** The ray's part in one block of cells [lo, hi), t in [ta, tb]: the cell walk (MODEL 0, 1), or
 *  the midpoint samples k in [k0, k1) at (k + 1/2) dt (MODEL 2). */
float blockPart(vec3 g0, vec3 d, float ta, float tb, ivec3 lo, ivec3 hi, int k0, int k1,
                float dt) {
#if MODEL == 2
    vec3 first = g0 + 0.5 * dt * d - 1.0, delta = dt * d; // q = g - 1
    float sum = 0.0;
    for (int k = k0; k < k1; ++k) sum += trilinear(first + float(k) * delta);
    return sum;
#else
    float fEdge = edgeValue(g0, d, ta);
    return walkCells(g0, d, ta, tb, lo, hi, fEdge);
#endif
}

/** The walk over blocks of 8^3 cells (n cells per axis), t in [0, T], leaving out the blocks
 *  uOccupancy marks empty (all their cells' corners 0: they add nothing). MODEL 2: nSamples
 *  samples dt apart; each block takes those whose t it holds, the same rule at every boundary
 *  (k from ceil(t / dt - 1/2)), so each sample is taken once. */
float walkBlocks(vec3 g0, vec3 d, float T, ivec3 n, int nSamples, float dt) {
    ivec3 nb = (n + 7) / 8, blk, stepDir;
    vec3 tMax, invD;
    for (int a = 0; a < 3; ++a) {
        float c = floor(g0[a] / 8.0);
        if (d[a] < 0.0 && c * 8.0 == g0[a]) c -= 1.0;
        blk[a] = clamp(int(c), 0, nb[a] - 1);
        stepDir[a] = d[a] > 0.0 ? 1 : (d[a] < 0.0 ? -1 : 0);
        invD[a] = d[a] != 0.0 ? 1.0 / d[a] : 0.0;
        tMax[a] = d[a] != 0.0 ? (float((blk[a] + max(stepDir[a], 0)) * 8) - g0[a]) * invD[a] : kFar;
    }
    float t = 0.0, sum = 0.0;
    int k0 = 0;
    int guard = nb.x + nb.y + nb.z + 3;
    for (int it = 0; it < guard && t < T; ++it) {
        int m = tMax.x < tMax.y ? (tMax.x < tMax.z ? 0 : 2) : (tMax.y < tMax.z ? 1 : 2);
        float tn = min(tMax[m], T);
        if (tn > t) {
            int k1 = tn >= T ? nSamples : clamp(int(ceil(tn / dt - 0.5)), k0, nSamples);
            if (texelFetch(uOccupancy, blk, 0).r != 0u)
                sum += blockPart(g0, d, t, tn, blk * 8, min(blk * 8 + 8, n), k0, k1, dt);
            k0 = k1;
            t = tn;
        }
        blk[m] += stepDir[m];
        if (blk[m] < 0 || blk[m] >= nb[m]) break;
        tMax[m] = (float((blk[m] + max(stepDir[m], 0)) * 8) - g0[m]) * invD[m];
    }
    return sum;
}
#endif

/** The line integral (value x mm) from the source s along d to s + d (both relative to the
 *  centre, voxel indices). */
float integrate(vec3 s, vec3 d) {
    float mmPerT = length(uIndexToMm * d);
#if MODEL == 0
    vec3 h = 0.5 * vec3(uDims); // voxels' cubes: [-1/2, N - 1/2]
#else
    vec3 h = 0.5 * vec3(uDims) + 0.5; // the trilinear support: [-1, N]
#endif
    float t0, t1;
    if (!clipRay(s, d, h, t0, t1)) return 0.0;
    vec3 g0 = s + t0 * d + h; // the walk's coordinates: the box's lower corner at 0
    ivec3 n = ivec3(2.0 * h + 0.5); // its cells: N (box), N + 1 (trilinear)
    float T = t1 - t0;
#if MODEL == 2
    float len = T * mmPerT;
    int nSamples = max(1, int(ceil(len / uStep)));
    float dt = T / float(nSamples);
#else
    int nSamples = 0;
    float dt = 1.0;
#endif
#if SKIP_EMPTY
    float part = walkBlocks(g0, d, T, n, nSamples, dt);
#if MODEL == 2
    return part * dt * mmPerT; // dt mmPerT = len / nSamples
#else
    return part * mmPerT;
#endif
#elif MODEL == 2
    vec3 first = g0 + 0.5 * dt * d - 1.0, delta = dt * d; // q = g - 1
    float sum = 0.0;
    for (int k = 0; k < nSamples; ++k) sum += trilinear(first + float(k) * delta);
    return sum * (len / float(nSamples));
#else
    float fEdge = edgeValue(g0, d, 0.0);
    return mmPerT * walkCells(g0, d, 0.0, T, ivec3(0), n, fEdge);
#endif
}

void main() {
    ivec3 px = ivec3(gl_GlobalInvocationID);
    if (px.x >= uSize.x || px.y >= uSize.y || px.z >= uSize.z) return;
    ConeView view = views[px.z];
    float value = 0.0;
    for (int sy = 0; sy < SUBSAMPLES; ++sy) {
        for (int sx = 0; sx < SUBSAMPLES; ++sx) {
            vec2 off = (vec2(sx, sy) + 0.5) / float(SUBSAMPLES) - 0.5;
            vec2 at = vec2(px.xy) + off;
            value += integrate(view.source.xyz,
                               view.dir0.xyz + at.x * view.dirCol.xyz + at.y * view.dirRow.xyz);
        }
    }
    outValue[(px.z * uSize.y + px.y) * uSize.x + px.x] = value / float(SUBSAMPLES * SUBSAMPLES);
}
