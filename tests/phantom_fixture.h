#pragma once
// The accuracy tests' common ground: the 3D Shepp-Logan phantom voxelised at 64^3 over 256 mm
// (boundary voxels 4x supersampled), imaged at M = 128 with the default pixel size, so that
// results of different test files compare (and docs/dev/accuracy.md's numbers stay one setting).
#include <fvr/core/render/view.h>
#include <fvr/core/xray/phantom.h>

namespace fvr::test {

struct PhantomFixture {
    static constexpr int kN = 64;
    static constexpr int kM = 128;
    core::EllipsoidPhantom phantom = core::EllipsoidPhantom::sheppLogan3D(256.0);
    core::Volume volume = phantom.voxelize({kN, kN, kN}, {256.0 / kN, 256.0 / kN, 256.0 / kN}, 4);
    double d = core::defaultPixelSize(volume.dims, volume.spacing, kM);
};

} // namespace fvr::test
