// Clip to the volume's support (fvr::core::rayMissesVolume): pixels whose ray misses the voxel
// model's support box (fvr::core::voxelModelReach) hold 0 in the true projection; FVR puts the
// kernel's ghost copies and ringing there, so the last pass writes 0 for them when uClip is set.
uniform int uClip;
uniform int uNonNegative; // fvr::core::RenderParams::nonNegative for a non-negative spectrum
uniform vec3 uBoxHalf; // fvr::core::supportHalfExtents, mm
uniform vec3 uViewD;
uniform vec3 uViewR;
uniform vec3 uViewU;
uniform float uPixel;

bool rayMissesVolume(int col, int row, int M) {
    vec3 o = float(col - M / 2) * uPixel * uViewR - float(row - M / 2) * uPixel * uViewU;
    float t0 = -1e30, t1 = 1e30;
    for (int a = 0; a < 3; ++a) {
        if (abs(uViewD[a]) < 1e-9) {
            if (abs(o[a]) >= uBoxHalf[a]) return true;
            continue;
        }
        float ta = (-uBoxHalf[a] - o[a]) / uViewD[a], tb = (uBoxHalf[a] - o[a]) / uViewD[a];
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
    return !(t1 > t0);
}

// The value the last pass stores for pixel (col, row): 0 outside the support when clipping, never
// below 0 for a non-negative volume.
float finalValue(int col, int row, int M, float p) {
    if (uClip != 0 && rayMissesVolume(col, row, M)) return 0.0;
    return uNonNegative != 0 ? max(p, 0.0) : p;
}
