// The built-in chest phantom: the painted composition against hand-computed integrals, the
// renderer on its voxels against its exact line integrals, and its anatomy where a radiograph
// shows it (lungs dark, heart on the patient's left, HU of the tissues).
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include <fvr/core/io/open_study.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/xray/patient_views.h>
#include <fvr/core/xray/phantom.h>

#include "image_metrics.h"

using namespace fvr::core;

namespace {

/** A sphere of radius r at c. */
Ellipsoid sphere(const Vec3& c, double r, double density) {
    Ellipsoid e;
    e.centre = c;
    e.semiAxes = {r, r, r};
    e.density = density;
    return e;
}

/** The value at the pixel whose ray passes through the point p (mm from the volume centre). */
float pixelAt(const ProjectionImage& img, const Vec3& p) {
    const int col = img.width / 2 + int(std::lround(glm::dot(p, img.view.r) / img.pixelSize));
    const int row = img.height / 2 - int(std::lround(glm::dot(p, img.view.u) / img.pixelSize));
    return img.at(col, row);
}

/** The HU of the voxel holding the point p (mm from the volume centre). */
float huAt(const Volume& v, const Vec3& p) {
    std::int64_t i[3];
    for (int a = 0; a < 3; ++a)
        i[a] = std::llround(p[a] / v.spacing[a] + double(v.dims[a] - 1) / 2.0);
    return v.at(i[0], i[1], i[2]);
}

constexpr double kT6 = 13.0; // T1 at z = +148 mm, 27 mm apart (phantom.h)

struct Chest {
    static constexpr int kN = 96;
    static constexpr int kM = 256;
    EllipsoidPhantom phantom = EllipsoidPhantom::chest(420.0);
    Volume volume = makeChestPhantomVolume(kN);
    double d = defaultPixelSize(volume.dims, volume.spacing, kM);

    ProjectionImage exact(const ViewFrame& v, ValueMapping m = ValueMapping::Mu) const {
        return phantom.project(v, {kM, d}, m, volume.dims, volume.spacing);
    }
};

const Chest& chest() {
    static const Chest c;
    return c;
}

} // namespace

// Painting: a point has the density of the last ellipsoid holding it. A sphere of radius 20 and
// density 0.25 painted into one of radius 50 and density 1: the ray through the centre crosses
// 60 mm of 1 and 40 mm of 0.25 (70); summed, the densities would add (110).
TEST(ChestPhantom, PaintCompositionAgainstHandComputedIntegrals) {
    EllipsoidPhantom p;
    p.ellipsoids = {sphere({0, 0, 0}, 50, 1.0), sphere({0, 0, 0}, 20, 0.25)};
    const Dims3 dims{32, 32, 32};
    const Vec3 s{4, 4, 4};
    const ViewFrame v = ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1});
    auto centre = [&](const EllipsoidPhantom& ph, double x) {
        return double(pixelAt(ph.project(v, {128, 1.0}, ValueMapping::Mu, dims, s), {x, 0, 0}));
    };
    EXPECT_NEAR(centre(p, 0), 110.0, 1e-4);
    p.composition = EllipsoidPhantom::Composition::Paint;
    EXPECT_NEAR(centre(p, 0), 70.0, 1e-4);
    EXPECT_NEAR(centre(p, 30), 80.0, 1e-4); // misses the small sphere: 2 sqrt(50^2 - 30^2)
    // The order decides: the big sphere painted last hides the small one.
    std::swap(p.ellipsoids[0], p.ellipsoids[1]);
    EXPECT_NEAR(centre(p, 0), 100.0, 1e-4);
    std::swap(p.ellipsoids[0], p.ellipsoids[1]);
    // Voxels: inside the small sphere -750 HU, in the shell 0 HU, outside -1000 HU; a voxel
    // the small sphere's surface crosses lies in between.
    const Volume vol = p.voxelize(dims, s);
    EXPECT_NEAR(huAt(vol, {2, 2, 2}), -750.0, 1e-2);
    EXPECT_NEAR(huAt(vol, {34, 2, 2}), 0.0, 1e-2);
    EXPECT_NEAR(huAt(vol, {2, 2, 58}), -1000.0, 1e-2);
    const float edge = huAt(vol, {18, 2, 2}); // voxel [16, 20] x [0, 4] x [0, 4]
    EXPECT_GT(edge, -750.0f);
    EXPECT_LT(edge, 0.0f);
}

namespace {

/** The two images over the pixels whose rays stay two voxels clear of the volume's top and
 *  bottom faces, where the box cuts the torso (a 20 cm step the voxels cannot hold sharper
 *  than a voxel); all pixels when the view is not horizontal. */
fvr::test::Comparison compareInside(const ProjectionImage& a, const ProjectionImage& b,
                                    const Volume& v) {
    const double limit = v.extent()[2] / 2 - 2 * v.spacing[2];
    std::vector<float> pa, pb;
    for (int row = 0; row < a.height; ++row)
        for (int col = 0; col < a.width; ++col) {
            const double z = (col - a.width / 2) * a.pixelSize * a.view.r[2] -
                             (row - a.height / 2) * a.pixelSize * a.view.u[2];
            if (std::abs(a.view.d[2]) < 1e-12 && std::abs(z) > limit) continue;
            const std::size_t i = std::size_t(row) * std::size_t(a.width) + std::size_t(col);
            pa.push_back(a.pixels[i]);
            pb.push_back(b.pixels[i]);
        }
    return fvr::test::compare(pa, pb);
}

} // namespace

// The renderer on the voxelised chest against the chest's exact line integrals. The voxels
// average the phantom over 4.4 mm cubes and the renderer interpolates between them, so the
// image differs from the exact one by about a voxel's blur. Where a large interface lies along
// the rays (the diaphragm's dome in AP: lung above, 20 cm of liver below) that blur is a step of
// 15-25 mm of water (the same voxelisation of one sphere, summed or painted, gives 46 dB: the
// two compositions voxelise alike). Measured (CPU, FFT, Catmull-Rom, oversampling 2, M 256):
// AP 37.0 dB / 3.6 %, LEFT 38.6 dB / 3.7 %, oblique 44.9 dB / 2.3 % (PSNR / relative RMS
// error); the floors sit a little under the measured values.
TEST(ChestPhantom, RendererMatchesExactLineIntegrals) {
    const Chest& c = chest();
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.mapping = ValueMapping::Mu;
    o.oversampling = 2.0;
    CpuFourierRenderer r(preprocess(c.volume, o));
    const std::vector<ViewFrame> views = {patientViewFrame(c.volume, PatientView::AP),
                                          patientViewFrame(c.volume, PatientView::Left),
                                          ViewFrame::fromDirUp({0.6, 0.45, -0.35}, {0, 0, 1})};
    for (const ViewFrame& v : views) {
        const auto cmp = compareInside(r.render({v, {Chest::kM, c.d}, Kernel::CatmullRom}),
                                       c.exact(v), c.volume);
        std::printf("[chest] view %.2f %.2f %.2f: PSNR %.2f dB, relative RMSE %.4f, max %.1f mm\n",
                    v.d[0], v.d[1], v.d[2], cmp.psnr, cmp.relRmse, cmp.maxAbsError);
        EXPECT_GT(cmp.psnr, 36.0);
        EXPECT_LT(cmp.relRmse, 0.042);
    }
}

// In the AP view (from the front, the patient's left on the image's right) the exact integrals
// show a radiograph: the lung fields transmit most, the mediastinum, the heart and the spine
// least; the heart's shadow lies on the patient's left.
TEST(ChestPhantom, ApViewShowsTheAnatomy) {
    const Chest& c = chest();
    const ViewFrame ap = patientViewFrame(c.volume, PatientView::AP);
    ASSERT_NEAR(ap.r[0], 1.0, 1e-9); // image right = patient left (+x)
    ASSERT_NEAR(ap.u[2], 1.0, 1e-9); // image up = superior (+z)
    const ProjectionImage img = c.exact(ap);
    const float rightLung = pixelAt(img, {-85, 0, 60}), leftLung = pixelAt(img, {85, 0, 60});
    const float heart = pixelAt(img, {40, 0, -40}), mediastinum = pixelAt(img, {0, 0, 60});
    const float spine = pixelAt(img, {0, 0, kT6});
    std::printf("[chest] AP: lungs %.1f %.1f, heart %.1f, mediastinum %.1f, spine %.1f mm\n",
                rightLung, leftLung, heart, mediastinum, spine);
    for (float lung : {rightLung, leftLung}) {
        EXPECT_LT(lung, 0.75f * heart);
        EXPECT_LT(lung, 0.75f * mediastinum);
        EXPECT_LT(lung, 0.75f * spine);
    }
    // The heart: at the height of its widest part the patient's left side (x > 0) holds more
    // than the mirror image on the right, everywhere from 30 to 80 mm off the midline.
    for (double x = 30; x <= 80; x += 5)
        EXPECT_GT(pixelAt(img, {x, 0, -40}), pixelAt(img, {-x, 0, -40}) + 20.0f) << x;
    // Outside the body no attenuation; the body as thick as a chest (about 20 cm of water).
    EXPECT_EQ(pixelAt(img, {200, 0, -100}), 0.0f);
    EXPECT_GT(mediastinum, 180.0f);
    EXPECT_LT(mediastinum, 280.0f);
}

TEST(ChestPhantom, TissuesHaveTheirHounsfieldUnits) {
    const Volume v = makeChestPhantomVolume(128); // 3.3 mm voxels
    EXPECT_EQ(v.units, ValueUnits::HounsfieldUnits);
    EXPECT_TRUE(v.orientationStated);
    EXPECT_NEAR(huAt(v, {-85, -30, 60}), -750.0f, 1.0f); // right lung
    EXPECT_NEAR(huAt(v, {85, -30, 60}), -750.0f, 1.0f); // left lung
    EXPECT_GT(huAt(v, {0, 46, kT6}), 150.0f); // T6 vertebral body
    EXPECT_NEAR(huAt(v, {30, 30, 200}), 40.0f, 1.0f); // neck muscle
    EXPECT_NEAR(huAt(v, {0, -1, 150}), -1000.0f, 1.0f); // trachea
    EXPECT_NEAR(huAt(v, {40, -20, -40}), 60.0f, 1.0f); // heart (blood)
    EXPECT_NEAR(huAt(v, {0, 0, -210 + 1.6}), 40.0f, 30.0f); // abdomen at the edge
    const auto [lo, hi] = v.valueRange();
    EXPECT_GE(lo, -1000.0f); // painting never leaves negative attenuation
    EXPECT_LE(hi, 850.0f); // nothing denser than cortical bone (1.85)
}

TEST(ChestPhantom, OpensAsAStudy) {
    const InputSource s = classifyInput("phantom:chest:64");
    EXPECT_EQ(s.kind, InputKind::Phantom);
    EXPECT_EQ(s.phantom, PhantomKind::Chest);
    const OpenedStudy st = openStudy(s);
    EXPECT_EQ(st.volume.dims, (Dims3{64, 64, 64}));
    EXPECT_NEAR(st.volume.spacing[0], 420.0 / 64, 1e-12);
    EXPECT_EQ(st.volume.units, ValueUnits::HounsfieldUnits);
    EXPECT_EQ(st.volume.name, "chest-phantom-64");
    EXPECT_TRUE(st.warnings.empty());
    EXPECT_EQ(classifyInput("phantom:chest").phantomSize, 160);
    EXPECT_EQ(classifyInput("phantom:shepp-logan").phantom, PhantomKind::SheppLogan);
    try {
        classifyInput("phantom:knee");
        ADD_FAILURE() << "an unknown phantom must throw";
    } catch (const SettingsError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("'knee'"), std::string::npos) << m;
        EXPECT_NE(m.find("phantom:chest[:N]"), std::string::npos) << m;
        EXPECT_NE(m.find("phantom:shepp-logan[:N]"), std::string::npos) << m;
    }
}
