#include <fvr/core/render/slice_params.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include <fvr/core/errors.h>

namespace fvr::core {

int sliceTaps(Kernel kernel, bool depthCue) {
    return depthCue && kernel == Kernel::Linear ? 3 : kernelTaps(kernel);
}

void checkKernelMatchesSpectrum(const Spectrum& s, Kernel kernel) {
    if (s.deapodizedFor && *s.deapodizedFor != kernel)
        throw SettingsError(std::string("kernel: the spectrum was deapodized for ") +
                            kernelName(*s.deapodizedFor) + ", it cannot be rendered with " +
                            kernelName(kernel) + " (preprocess again for that kernel)");
}

SliceParams sliceParams(const Spectrum& s, const RenderParams& params) {
    SliceParams p;
    const int M = params.image.size;
    const double d = params.image.pixelSize;
    const Vec3& R = params.view.r;
    const Vec3 V = -params.view.u;
    p.banded = params.voxelModel == VoxelModel::BandLimited;
    for (int a = 0; a < 3; ++a) {
        p.padded[a] = s.padded[a];
        p.invP[a] = 1.0 / double(s.padded[a]);
        const double perIndex = s.spacing[a] * double(s.padded[a]) / (M * d);
        p.A[a] = R[a] * perIndex;
        p.B[a] = V[a] * perIndex;
        p.half[a] = p.banded ? s.padded[a] / 2.0 : std::numeric_limits<double>::infinity();
        p.anti[a] = s.volumeDims[a] % 2 == 0;
        p.maxCyclesPerVoxel =
            std::max(p.maxCyclesPerVoxel,
                     (M / 2.0 + 1.0) * (std::abs(p.A[a]) + std::abs(p.B[a])) * p.invP[a]);
    }
    p.scale = s.spacing[0] * s.spacing[1] * s.spacing[2] / ((M * d) * (M * d));
    p.depth = params.depthCue > 0.0;
    p.taps = sliceTaps(params.kernel, p.depth);
    if (p.depth) {
        const DepthCueWeights w = depthCueWeights(params.depthCue, s.volumeDims, s.spacing);
        p.depthA = w.a;
        for (int a = 0; a < 3; ++a)
            p.E[a] = w.b / (2.0 * std::numbers::pi) * params.view.d[a] * s.spacing[a] *
                     double(s.padded[a]);
    }
    return p;
}

} // namespace fvr::core
