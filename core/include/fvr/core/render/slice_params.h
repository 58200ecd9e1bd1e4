#pragma once
/** What both Fourier renderers (CpuFourierRenderer, gpu::GpuFourierRenderer) derive from the
 *  spectrum and the frame's RenderParams before they sample the central slice: the one place
 *  for the slice's geometry, band, period signs, depth cueing weights and scale. */
#include <fvr/core/render/renderer.h>

namespace fvr::core {

/** The slice of one frame in spectrum index units. The image frequency (m, n) (signed, in
 *  cycles per image, -M/2 <= m, n < M/2) samples the spectrum at k(m, n) = m A + n B. */
struct SliceParams {
    /** The padded grid P_a and 1 / P_a (spectrum index to cycles per voxel). */
    std::int64_t padded[3] = {0, 0, 0};
    double invP[3] = {1, 1, 1};
    /** Frequency steps along the image's right (r) and down (-u) directions:
     *  A_a = r_a s_a P_a / (M d), B_a = -u_a s_a P_a / (M d). */
    double A[3] = {0, 0, 0};
    double B[3] = {0, 0, 0};
    /** Physical scale of the inverse transform: s_0 s_1 s_2 / (M d)^2. */
    double scale = 1.0;
    /** The band-limited voxel model samples only |k_a| <= half_a = P_a / 2 (the backends add
     *  their precision's tolerance); infinite for the other models (they read every frequency). */
    bool banded = true;
    double half[3] = {0, 0, 0};
    /** Axes of an even voxel count: the spectrum changes sign from one period to the next. */
    bool anti[3] = {false, false, false};
    /** The interpolation's taps per axis: the kernel's, except linear with depth cueing
     *  (3 taps, so that the derivative on integer frequencies is the central difference). */
    int taps = 0;
    /** Depth cueing (xray.h): the slice is a G(k) + i E.grad G(k) (FFT) or
     *  a H(k) + E.grad H(-k) (FHT), E_a = b / (2 pi) D_a s_a P_a. Off: a = 1, E = 0. */
    bool depth = false;
    double depthA = 1.0;
    double E[3] = {0, 0, 0};
    /** The slice's highest frequency per axis in cycles per voxel, max over a of
     *  (M/2 + 1)(|A_a| + |B_a|) / P_a: how far the voxel model's transfer table must reach. */
    double maxCyclesPerVoxel = 0.0;
};

/** The slice parameters of one frame (the parameters are not validated here:
 *  validateRenderParams). */
SliceParams sliceParams(const Spectrum& spectrum, const RenderParams& params);

/** Taps per axis of the slice's interpolation (SliceParams::taps). */
int sliceTaps(Kernel kernel, bool depthCue);

/** Throws SettingsError when the spectrum was deapodized for another kernel than `kernel`. */
void checkKernelMatchesSpectrum(const Spectrum& spectrum, Kernel kernel);

} // namespace fvr::core
