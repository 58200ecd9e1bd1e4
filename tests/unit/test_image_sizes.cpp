// Images of any W x H (16..4096 each): the Fourier renderers transform a square of FFTW's fast
// side (or the GPU's power of two) and crop it about the centre pixel (W/2, H/2). The oracle is
// the analytic projection of the Shepp-Logan phantom, computed directly at W x H with its own
// pixel centres: a crop off by one pixel, or a size the transform mishandles, fails here.
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/cpu_batch.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/render/spatial_projector.h>

#include "image_metrics.h"
#include "phantom_fixture.h"

using namespace fvr::core;

namespace {

const fvr::test::PhantomFixture& phantom() {
    static const fvr::test::PhantomFixture f;
    return f;
}

std::shared_ptr<const Spectrum> spectrumOf(TransformKind t) {
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = ValueMapping::Mu;
    o.transform = t;
    o.oversampling = 2.0;
    o.deapodizeFor = Kernel::CatmullRom;
    return preprocess(phantom().volume, o);
}

const ViewFrame kOblique = ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0});

} // namespace

TEST(ImageSizes, TheTransformSideIsFastForFftwOrAPowerOfTwoForTheGpu) {
    EXPECT_EQ(fourierSide(256, 256, false), 256); // the old sizes are unchanged
    EXPECT_EQ(fourierSide(512, 512, true), 512);
    EXPECT_EQ(fourierSide(200, 200, false), 200); // 2^3 5^2
    EXPECT_EQ(fourierSide(224, 200, false), 224); // 2^5 7
    EXPECT_EQ(fourierSide(1240, 960, false), 1250); // 1242..1248 have a factor above 7
    EXPECT_EQ(fourierSide(75, 51, false), 80);
    EXPECT_EQ(fourierSide(17, 17, false), 18);
    EXPECT_EQ(fourierSide(10, 12, false), 16); // at least 16
    EXPECT_EQ(fourierSide(1240, 960, true), 2048);
    EXPECT_EQ(fourierSide(200, 64, true), 256);
    EXPECT_EQ(fourierSide(4096, 4095, false), 4096);
    EXPECT_EQ(fourierSide(4095, 17, false), 4096);
    // With the volume: a square of an allowed side as ever; any other image also has the period
    // of the default pixel size at least. The 64^3 phantom over 256 mm: diagonal 443.4 mm.
    const auto& f = phantom();
    const auto side = [&](int W, int H, double d, bool pow2) {
        return fourierSide(ImageGeometry{W, d, H}, f.volume.dims, f.volume.spacing, pow2);
    };
    EXPECT_EQ(side(128, 128, 2.0, false), 128); // zoomed squares: the user's period
    EXPECT_EQ(side(100, 100, 2.0, false), 100);
    EXPECT_EQ(side(100, 100, 2.0, true), 256); // not the GPU's: >= 443.4 / 2
    EXPECT_EQ(side(17, 33, 2.0, false), 224); // >= 222, 2^5 7
    EXPECT_EQ(side(17, 33, 2.0, true), 256);
    EXPECT_EQ(side(300, 200, 2.0, false), 300); // the long side holds the diagonal already
    EXPECT_EQ(side(4000, 16, 0.01, false), 4096); // at most 4096
    // The default pixel size (the diagonal over min(W, H)) never needs more than the sides.
    for (auto [W, H] : {std::pair{128, 128}, {200, 120}, {17, 33}, {1240, 960}}) {
        const double d = defaultPixelSize(f.volume.dims, f.volume.spacing, std::min(W, H));
        EXPECT_EQ(side(W, H, d, false), fourierSide(W, H, false)) << W << "x" << H;
        EXPECT_EQ(side(W, H, d, true), fourierSide(W, H, true)) << W << "x" << H;
    }
}

TEST(ImageSizes, TheCropKeepsTheCentrePixel) {
    // An M x M image whose pixel (col, row) holds col + 1000 row: the crop's pixel (W/2, H/2)
    // must be the square's (M/2, M/2).
    for (auto [M, W, H] : {std::tuple{16, 16, 16}, {16, 15, 9}, {18, 17, 16}, {80, 75, 51}}) {
        ProjectionImage sq;
        sq.width = sq.height = M;
        for (int row = 0; row < M; ++row)
            for (int col = 0; col < M; ++col) sq.pixels.push_back(float(col + 1000 * row));
        const ProjectionImage c = cropProjection(sq, W, H);
        ASSERT_EQ(c.width, W);
        ASSERT_EQ(c.height, H);
        ASSERT_EQ(c.pixels.size(), std::size_t(W) * H);
        EXPECT_EQ(c.at(W / 2, H / 2), float(M / 2 + 1000 * (M / 2))) << M << " " << W << "x" << H;
        EXPECT_EQ(c.at(0, 0) + float(W - 1 + 1000 * (H - 1)), c.at(W - 1, H - 1));
    }
}

TEST(ImageSizes, AnyWidthAndHeightMatchTheAnalyticProjection) {
    // Each W x H image against the analytic projection computed at W x H (the truth's own pixel
    // centres). Floors: measured (docs/dev/accuracy.md), a little below. The crops inherit the
    // accuracy of the square they are cut from (128^2 for 75 x 51 and 17 x 33: the period of
    // the default pixel size); a 256^2 render's crop is printed beside for comparison.
    const auto& f = phantom();
    struct Case {
        int W, H;
        double floor;
    };
    for (TransformKind t : {TransformKind::Fft, TransformKind::Fht}) {
        CpuFourierRenderer r(spectrumOf(t));
        const ProjectionImage big = r.render({kOblique, {256, f.d}, Kernel::CatmullRom});
        for (const Case& c : {Case{128, 128, 39.8},
                              {100, 100, 38.0},
                              {200, 200, 44.0},
                              {96, 160, 39.7},
                              {160, 96, 39.7},
                              {75, 51, 35.2},
                              {17, 33, 34.8},
                              {127, 129, 40.1}}) {
            const ImageGeometry g{c.W, f.d, c.H};
            const ProjectionImage img = r.render({kOblique, g, Kernel::CatmullRom});
            ASSERT_EQ(img.width, c.W);
            ASSERT_EQ(img.height, c.H);
            const ProjectionImage truth =
                f.phantom.project(kOblique, g, ValueMapping::Mu, f.volume.dims, f.volume.spacing);
            ASSERT_EQ(truth.width, c.W);
            const double psnr = fvr::test::compare(img.pixels, truth.pixels).psnr;
            const double ref =
                fvr::test::compare(cropProjection(big, c.W, c.H).pixels, truth.pixels).psnr;
            std::printf("[sizes] %s %dx%d (transform %d^2): %.2f dB, the 256^2 render's crop "
                        "%.2f dB\n",
                        transformName(t), c.W, c.H,
                        fourierSide(g, f.volume.dims, f.volume.spacing, false), psnr, ref);
            EXPECT_GT(psnr, c.floor) << c.W << "x" << c.H;
        }
    }
}

TEST(ImageSizes, ACropOnePixelOffWouldFail) {
    // The oracle's power: the same render compared with the truth shifted by one pixel.
    const auto& f = phantom();
    CpuFourierRenderer r(spectrumOf(TransformKind::Fft));
    const ImageGeometry g{75, f.d, 51}, wider{76, f.d, 51};
    const ProjectionImage img = r.render({kOblique, g, Kernel::CatmullRom});
    const ProjectionImage truth =
        f.phantom.project(kOblique, wider, ValueMapping::Mu, f.volume.dims, f.volume.spacing);
    // The 76-wide truth has its centre at column 38, the image at 37: the truth's column c
    // lies one pixel to the left of the image's column c.
    std::vector<float> shifted;
    for (int row = 0; row < 51; ++row)
        for (int col = 0; col < 75; ++col) shifted.push_back(truth.at(col, row));
    const ProjectionImage right =
        f.phantom.project(kOblique, g, ValueMapping::Mu, f.volume.dims, f.volume.spacing);
    const double good = fvr::test::compare(img.pixels, right.pixels).psnr;
    const double off = fvr::test::compare(img.pixels, shifted).psnr;
    std::printf("[sizes] 75x51: %.2f dB aligned, %.2f dB one column off\n", good, off);
    EXPECT_GT(good, off + 10.0);
}

TEST(ImageSizes, TheSpatialProjectorAndTheBatchRendererTakeWByH) {
    // The reference projector integrates W x H rays itself (no crop): FVR at 1.25x with
    // Kaiser-Bessel agrees with it as it does on squares.
    const auto& f = phantom();
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = ValueMapping::Mu;
    o.oversampling = 1.25;
    o.deapodizeFor = Kernel::KaiserBessel4;
    CpuBatchRenderer batch(preprocess(f.volume, o), 2);
    SpatialProjector sp(f.volume, {0.25, ValueMapping::Mu, 0});
    const ImageGeometry g{90, f.d, 140};
    RenderParams p{kOblique, g, Kernel::KaiserBessel4};
    p.voxelModel = VoxelModel::Trilinear;
    const auto images = batch.renderBatch({p, p});
    const ProjectionImage ref = sp.project(kOblique, g);
    ASSERT_EQ(ref.width, 90);
    ASSERT_EQ(ref.height, 140);
    for (const auto& img : images) {
        ASSERT_EQ(img.width, 90);
        ASSERT_EQ(img.height, 140);
        const double psnr = fvr::test::compare(img.pixels, ref.pixels).psnr;
        std::printf("[sizes] 90x140 Kaiser-Bessel 4, trilinear model, vs spatial: %.2f dB\n", psnr);
        EXPECT_GT(psnr, 45.0);
    }
}

TEST(ImageSizes, SizesOutside16To4096AreRefusedNamingTheSide) {
    auto message = [](const ImageGeometry& g) {
        try {
            validateImageGeometry(g);
        } catch (const SettingsError& e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    EXPECT_EQ(message({15, 1.0}), "image width: expected 16..4096 pixels, found 15");
    EXPECT_EQ(message({64, 1.0, 4097}), "image height: expected 16..4096 pixels, found 4097");
    EXPECT_EQ(message({16, 1.0, 4096}), "accepted");
    EXPECT_EQ(message({4096, 1.0, 17}), "accepted");
    EXPECT_EQ(parseImageSize("1240x960"), (std::pair{1240, 960}));
    EXPECT_EQ(parseImageSize("224"), (std::pair{224, 224}));
    EXPECT_THROW(parseImageSize("224x"), SettingsError);
    EXPECT_THROW(parseImageSize("15x200"), SettingsError);
    // The default pixel size fits the diagonal on the shorter side.
    RenderSettings s;
    s.size = 300;
    s.height = 150;
    const ImageGeometry g = s.imageGeometry(phantom().volume);
    EXPECT_EQ(g.cols(), 300);
    EXPECT_EQ(g.rows(), 150);
    EXPECT_DOUBLE_EQ(g.pixelSize,
                     defaultPixelSize(phantom().volume.dims, phantom().volume.spacing, 150));
}
