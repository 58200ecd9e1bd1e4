// The volume loaders on the shared data sets, against values computed independently from the
// files (Python, standard library only).
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "volume_io_test_support.h"

using namespace fvr::test::volume_io;

// ================================================================================================
// Shared data sets. Expected values were computed independently from the files with a Python
// script (standard library: struct, gzip): dims and spacing from the headers, min/max/sum over
// all voxels and a few voxels at given (x, y, z) with x fastest.

namespace {

struct Probe {
    int x, y, z;
    float value;
};

struct SharedCase {
    const char* path;
    Dims3 dims;
    Vec3 spacing;
    float min, max;
    double sum;
    std::vector<Probe> probes;
};

void checkShared(const SharedCase& c) {
    SCOPED_TRACE(c.path);
    const Volume v = fvr::core::loadVolume(fvr::test::sharedData() / c.path);
    ASSERT_EQ(v.dims, c.dims);
    expectVec(v.spacing, c.spacing, 1e-6, "spacing");
    ASSERT_EQ(v.voxels.size(), std::size_t(c.dims[0] * c.dims[1] * c.dims[2]));
    const auto [lo, hi] = v.valueRange();
    EXPECT_FLOAT_EQ(lo, c.min);
    EXPECT_FLOAT_EQ(hi, c.max);
    EXPECT_NEAR(voxelSum(v), c.sum, std::abs(c.sum) * 1e-9 + 1e-3);
    for (const Probe& p : c.probes)
        EXPECT_FLOAT_EQ(v.at(p.x, p.y, p.z), p.value)
            << "(" << p.x << ", " << p.y << ", " << p.z << ")";
    EXPECT_EQ(v.units, fvr::core::ValueUnits::Unknown);
    EXPECT_FALSE(v.name.empty());
}

} // namespace

TEST(VolumeIo, SharedMetaImageVolumes) {
    FVR_REQUIRE_DATA("volumes/headsq/headsq.mhd");
    const std::vector<SharedCase> cases = {
        {"volumes/headsq/headsq.mhd",
         {64, 64, 93},
         {3.2, 3.2, 1.5},
         0,
         3926,
         193392317.0,
         {{0, 0, 0, 0}, {32, 32, 46, 669}, {21, 16, 18, 1092}, {32, 21, 46, 1070}}},
        {"volumes/lidc2_lung_ct/LIDC2.mhd",
         {256, 256, 133},
         {1.40625, 1.40625, 2.5},
         0,
         255,
         61489178.0,
         {{128, 128, 66, 128}, {85, 64, 26, 16}, {128, 85, 66, 92}}},
        {"volumes/mr_head_mhd/HeadMRVolume.mhd",
         {48, 62, 42},
         {4, 4, 4},
         0,
         255,
         3058332.0,
         {{0, 0, 0, 1}, {24, 31, 21, 79}, {16, 15, 8, 45}, {24, 20, 21, 89}}},
        {"volumes/brain_pd_3slices_mha/BrainProtonDensity3Slices.mha",
         {181, 217, 3},
         {1, 1, 1},
         0,
         250,
         14725708.0,
         {{0, 0, 0, 7}, {90, 108, 1, 228}, {180, 216, 2, 1}, {60, 54, 0, 159}}},
    };
    for (const SharedCase& c : cases) checkShared(c);
}

TEST(VolumeIo, SharedStanfordCtHeadFromPatternOf113BigEndianFiles) {
    FVR_REQUIRE_DATA("volumes/stanford_cthead_256x256x113/CThead.mhd");
    checkShared({"volumes/stanford_cthead_256x256x113/CThead.mhd",
                 {256, 256, 113},
                 {1, 1, 2},
                 0,
                 3272,
                 2810724494.0,
                 {{0, 0, 0, 25},
                  {128, 128, 56, 2322},
                  {255, 255, 112, 25},
                  {85, 64, 22, 1043},
                  {128, 85, 56, 81}}});
}

TEST(VolumeIo, SharedNiftiVolumes) {
    FVR_REQUIRE_DATA("volumes/bonsai_256/bonsai.nii.gz");
    const float avmSlope = 2.208627462387085f; // scl_slope of AVM.nii.gz (uint8 data)
    const std::vector<SharedCase> cases = {
        {"volumes/bonsai_256/bonsai.nii.gz",
         {256, 256, 256},
         {1, 1, 1},
         0,
         255,
         225901147.0,
         {{0, 0, 0, 40}, {128, 128, 128, 69}, {85, 64, 51, 49}, {128, 85, 128, 5}}},
        {"volumes/engine_256x256x128/engine.nii.gz",
         {256, 256, 128},
         {1, 1, 1},
         0,
         255,
         173590544.0,
         {{128, 128, 64, 136}, {85, 64, 25, 145}}},
        {"volumes/avm_cta/AVM.nii.gz",
         {337, 319, 154},
         {0.5469, 0.5469, 1.0},
         0,
         255 * avmSlope,
         83847168.89089203,
         {{1, 160, 77, 49 * avmSlope}, {92, 149, 7, 255 * avmSlope}, {0, 0, 0, 0}}},
        {"volumes/ct_pitch_nifti/CT_pitch.nii.gz",
         {175, 248, 58},
         {0.8125, 0.8125, 2.3970494270324707},
         0,
         255,
         95678796.0,
         {{87, 124, 29, 156}, {0, 0, 0, 0}}},
        {"volumes/fuel_nifti/fuel.nii.gz",
         {64, 33, 32},
         {1, 1, 1},
         0,
         255,
         509815.0,
         {{32, 16, 16, 189}, {32, 11, 16, 10}}},
    };
    for (const SharedCase& c : cases) checkShared(c);

    // AVM: the scale factor is applied (uint8 0..255 -> 0..563.2); sform identity RAS -> LPS.
    const Volume avm =
        fvr::core::loadVolume(fvr::test::sharedData() / "volumes/avm_cta/AVM.nii.gz");
    EXPECT_NEAR(avm.valueRange().second, 563.2, 1e-3);
    expectVec(avm.direction[0], {-1, 0, 0}, 1e-12, "AVM dir0");
    expectVec(avm.direction[1], {0, -1, 0}, 1e-12, "AVM dir1");
    expectVec(avm.direction[2], {0, 0, 1}, 1e-12, "AVM dir2");
    expectVec(avm.origin, {73.39768981933594, 69.69419860839844, -64.11000061035156}, 1e-9,
              "AVM origin");

    // CT_pitch: a gantry-tilted CT whose sform (and qform, a rotation of -16.5 degrees about x)
    // tilts the slice axis; the in-plane row axis leans accordingly. sform in RAS: column 1 =
    // (0, 0.779041, -0.230762), column 2 = (0, 0.680799, 2.298338).
    const Volume pitch =
        fvr::core::loadVolume(fvr::test::sharedData() / "volumes/ct_pitch_nifti/CT_pitch.nii.gz");
    expectVec(pitch.direction[0], {-1, 0, 0}, 1e-6, "pitch dir0");
    expectVec(pitch.direction[1], {0, -0.779041051864624 / 0.8125, -0.23076248168945312 / 0.8125},
              1e-5, "pitch dir1");
    expectVec(
        pitch.direction[2],
        {0, -0.6807987689971924 / 2.3970494270324707, 2.2983384132385254 / 2.3970494270324707},
        1e-5, "pitch dir2");
    expectVec(pitch.origin, {69.02075958251953, 134.38560485839844, -13.56882095336914}, 1e-9,
              "pitch origin");
}

TEST(VolumeIo, SharedBodyCtMetaImageAndNiftiAgree) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.nii.gz");
    const fs::path base = fvr::test::sharedData() / "volumes/body_ct_hu_3mm";
    const std::vector<Probe> probes = {{0, 0, 0, -1023},
                                       {61, 50, 56, 164},
                                       {121, 100, 111, -997},
                                       {40, 25, 22, 34},
                                       {61, 33, 56, 7}};
    // The .mhd/.raw (int16) and the .nii.gz (int32, sform_code 2) hold the same HU values.
    checkShared({"volumes/body_ct_hu_3mm/example_ct.mhd",
                 {122, 101, 112},
                 {3, 3, 3},
                 -1207,
                 3382,
                 -496851173.0,
                 probes});
    checkShared({"volumes/body_ct_hu_3mm/example_ct.nii.gz",
                 {122, 101, 112},
                 {3, 3, 3},
                 -1207,
                 3382,
                 -496851173.0,
                 probes});
    const Volume mhd = fvr::core::loadVolume(base / "example_ct.mhd");
    const Volume nii = fvr::core::loadVolume(base / "example_ct.nii.gz");
    // Voxel for voxel in the same index order: no axis flip between the two files. The derived
    // .mhd carries no Offset/TransformMatrix (identity, origin 0) while the NIfTI sform is
    // diag(3, 3, 3) in RAS, i.e. LPS axes (-x, -y, +z): same voxels, different stated orientation.
    ASSERT_EQ(mhd.voxels.size(), nii.voxels.size());
    std::size_t mismatches = 0;
    for (std::size_t i = 0; i < mhd.voxels.size(); ++i)
        mismatches += mhd.voxels[i] != nii.voxels[i];
    EXPECT_EQ(mismatches, 0u);
    expectVec(mhd.direction[0], {1, 0, 0}, 0, "mhd dir0");
    expectVec(mhd.origin, {0, 0, 0}, 0, "mhd origin");
    expectVec(nii.direction[0], {-1, 0, 0}, 1e-12, "nii dir0");
    expectVec(nii.direction[1], {0, -1, 0}, 1e-12, "nii dir1");
    expectVec(nii.direction[2], {0, 0, 1}, 1e-12, "nii dir2");
    expectVec(nii.origin, {177.95632934570312, -11.319000244140625, 94.3017578125}, 1e-9,
              "nii origin");
    // Plausible body CT in HU: air near -1024, bone above 1000.
    EXPECT_LT(nii.valueRange().first, -1000.0f);
    EXPECT_GT(nii.valueRange().second, 1000.0f);
}
