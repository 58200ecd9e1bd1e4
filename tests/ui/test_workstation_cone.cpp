// The workstation's cone beam: the Geometry panel puts a view on a C-arm whose image is the ray
// caster's for the same camera, its angles turn every view (a parallel view beside it shows the
// same orientation), a drag moves the C-arm, the overlay reads as a cath lab, and the choices
// survive a restart.
#include <QAction>
#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QLabel>
#include <QSlider>

#include <fstream>

#include <fvr/core/dicom/rt_image.h>
#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/xray/polychromatic_render.h>
#include <fvr/ui/panels/geometry_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/xray_match.h>

#include "image_metrics.h"
#include "ui_support.h"

namespace {

using namespace fvr;
using fvr::test::openAndWait;
using fvr::test::Workstation;
using ui::StudySource;

void choose(QComboBox* c, int data) { c->setCurrentIndex(c->findData(data)); }

/** The ray caster's image of the C-arm at these angles, as the view's camera (cArmCamera about
 *  the volume's centre, the framing pitch), computed here from the contract's parts. */
std::vector<float> expectedCone(const ui::ProjectionView& v, double a, double b, double sid,
                                double sod) {
    const core::Volume& vol = *v.volume();
    const int M = v.settings().size;
    const double pitch = core::framingPitch(vol, sid, sod, M, M);
    const core::ConeCamera cam =
        core::cArmCamera({a, b, sid, sod, core::volumeCentre(vol)}, M, M, pitch, pitch);
    core::ConeProjectorOptions o;
    o.mapping = v.spectrum()->mapping;
    return core::ConeProjector(vol, o).project(cam).pixels;
}

TEST_F(Workstation, ConeBeamViewShowsTheCArmsImageAndReadsAsACathLab) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    auto* v = window->views()[0];
    choose(window->renderingPanel()->sizeCombo(), 128);
    ui::GeometryPanel& g = *window->geometryPanel();
    choose(g.projectionCombo(), int(ui::ProjectionKind::Cone));
    g.primarySpin()->setValue(30.0);
    g.secondarySpin()->setValue(15.0);
    EXPECT_EQ(g.angleLabel()->text(), QString::fromUtf8("LAO 30° CRAN 15°"));
    ASSERT_EQ(v->settings().projection, ui::ProjectionKind::Cone);
    const auto img = v->projection();
    ASSERT_TRUE(img);
    EXPECT_GT(test::compare(img->pixels, expectedCone(*v, 30.0, 15.0, 1000.0, 750.0)).psnr, 120.0);
    QApplication::processEvents();
    EXPECT_TRUE(v->overlayText().contains(QString::fromUtf8("LAO 30° CRAN 15°  SID 1000  SOD 750")))
        << v->overlayText().toStdString();
    EXPECT_TRUE(v->overlayText().contains("cone beam"));

    // A machine preset sets both distances; the image follows.
    auto* preset = g.presetCombo();
    preset->setCurrentIndex(2); // the chest radiograph
    emit preset->activated(2);
    EXPECT_EQ(v->settings().cone.sid, 1800.0);
    EXPECT_EQ(v->settings().cone.sod, 1650.0);
    EXPECT_GT(
        test::compare(v->projection()->pixels, expectedCone(*v, 30.0, 15.0, 1800.0, 1650.0)).psnr,
        120.0);

    // Where the view renders on the GPU the GPU casts (the fixture allows llvmpipe); without it
    // the CPU does: the same image either way.
    EXPECT_TRUE(v->overlayText().contains("cone beam  128×128  GPU"))
        << v->overlayText().toStdString();
    window->softwareGpuAction()->trigger();
    ASSERT_FALSE(v->usingGpu());
    EXPECT_GT(
        test::compare(v->projection()->pixels, expectedCone(*v, 30.0, 15.0, 1800.0, 1650.0)).psnr,
        120.0);
    QApplication::processEvents();
    EXPECT_TRUE(v->overlayText().contains("cone beam  128×128  CPU"))
        << v->overlayText().toStdString();

    // A drag to the right moves toward LAO, upward toward cranial; the panel follows.
    const QPoint c = v->rect().center();
    QTest::mousePress(v, Qt::LeftButton, Qt::NoModifier, c);
    QTest::mouseMove(v, c + QPoint(20, -10));
    QTest::mouseRelease(v, Qt::LeftButton, Qt::NoModifier, c + QPoint(20, -10));
    EXPECT_GT(g.primaryAngle(), 30.5);
    EXPECT_GT(g.secondaryAngle(), 15.2);
    const core::CArmAngles now = core::cArmAngles(*v->volume(), v->viewFrame());
    EXPECT_NEAR(now.primaryDeg, g.primaryAngle(), 0.051); // the spin box rounds to 0.1
    EXPECT_NEAR(now.secondaryDeg, g.secondaryAngle(), 0.051);

    // Another study: the cone beam of the new volume, not of the old one's GPU texture.
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(32)));
    ASSERT_EQ(v->volume()->dims[0], 32);
    const core::CArmAngles a = core::cArmAngles(*v->volume(), v->viewFrame());
    EXPECT_GT(test::compare(v->projection()->pixels,
                            expectedCone(*v, a.primaryDeg, a.secondaryDeg, 1800.0, 1650.0))
                  .psnr,
              120.0);

    // Saved: a new window starts in cone mode with the chest radiograph's distances.
    window.reset();
    window = std::make_unique<ui::MainWindow>();
    EXPECT_EQ(window->views()[0]->settings().projection, ui::ProjectionKind::Cone);
    EXPECT_EQ(window->geometryPanel()->values().cone.sid, 1800.0);
}

/** The view's camera at these angles (cArmCamera about the volume's centre, framing pitch). */
core::ConeCamera viewCamera(const ui::ProjectionView& v, double a, double b) {
    const core::Volume& vol = *v.volume();
    const int M = v.settings().size;
    const double pitch = core::framingPitch(vol, 1000.0, 750.0, M, M);
    return core::cArmCamera({a, b, 1000.0, 750.0, core::volumeCentre(vol)}, M, M, pitch, pitch);
}

// Output = Polychromatic on a cone-beam view: -ln(I/I0) of the materials' cone-beam mass
// thicknesses (ray cast here from the decomposed volumes) through the response's exact sum;
// a material's g/cm^2; the pixel aperture's 4 x 4 rays per pixel.
TEST_F(Workstation, ConeBeamViewRendersThePolychromaticOutputAndThePixelAperture) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    auto* v = window->views()[0];
    choose(window->renderingPanel()->sizeCombo(), 128);
    ui::GeometryPanel& g = *window->geometryPanel();
    choose(g.projectionCombo(), int(ui::ProjectionKind::Cone));
    g.primarySpin()->setValue(20.0);
    g.secondarySpin()->setValue(10.0);
    const core::ConeCamera cam = viewCamera(*v, 20.0, 10.0);
    // The materials' mass thicknesses (g/cm^2) of this camera, cast here.
    std::vector<std::vector<float>> rhoL;
    for (const core::Volume& m :
         core::materialVolumes(*v->volume(), {core::defaultMaterials(), 70.0})) {
        auto img = core::ConeProjector(m, {}).project(cam).pixels;
        for (float& x : img) x *= 0.1f;
        rhoL.push_back(std::move(img));
    }
    auto* x = window->xrayPanel();
    x->kvpSpin()->setValue(70.0);
    choose(x->outputCombo(), int(ui::XrayOutput::Polychromatic));
    auto polyReady = [&] {
        return v->polychromatic() && v->polychromatic()->response && v->showsCurrentFrame();
    };
    ASSERT_TRUE(QTest::qWaitFor(polyReady, 60000))
        << window->messages()->toPlainText().toStdString();
    const auto shown = *v->projection();
    ASSERT_EQ(shown.pixels.size(), rhoL[0].size());
    double worst = 0.0, peak = 0.0;
    for (std::size_t p = 0; p < shown.pixels.size(); ++p) {
        const double d[3] = {rhoL[0][p], rhoL[1][p], rhoL[2][p]};
        const double ref = -std::log(v->polychromatic()->response->exact(d));
        worst = std::max(worst, std::abs(shown.pixels[p] - ref));
        peak = std::max(peak, ref);
    }
    std::printf("[ui-cone-poly] -ln(I/I0) on the %s: worst %.2e of peak %.2f\n",
                v->usingGpu() ? "GPU" : "CPU", worst, peak);
    EXPECT_GT(peak, 1.0);
    EXPECT_LT(worst, 1e-3);
    // Where the view renders on the GPU (the fixture allows llvmpipe) the materials are cast
    // there; without it on the CPU: the same image either way.
    QApplication::processEvents();
    EXPECT_TRUE(v->overlayText().contains(v->usingGpu() ? "cone beam  128×128  GPU"
                                                        : "cone beam  128×128  CPU"))
        << v->overlayText().toStdString();
    if (v->usingGpu()) {
        window->softwareGpuAction()->trigger();
        ASSERT_FALSE(v->usingGpu());
        const auto cpu = *v->projection();
        double gap = 0.0;
        for (std::size_t p = 0; p < cpu.pixels.size(); ++p)
            gap = std::max(gap, double(std::abs(cpu.pixels[p] - shown.pixels[p])));
        std::printf("[ui-cone-poly] GPU vs CPU: worst %.2e in -ln(I/I0)\n", gap);
        EXPECT_LT(gap, 1e-4);
        QApplication::processEvents();
        EXPECT_TRUE(v->overlayText().contains("cone beam  128×128  CPU"))
            << v->overlayText().toStdString();
    }
    // The soft tissue's mass thickness.
    x->showCombo()->setCurrentIndex(x->showCombo()->findData(1));
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->polychromatic()->show == 1 && polyReady(); }));
    EXPECT_GT(test::compare(v->projection()->pixels, rhoL[1]).psnr, 120.0);
    // Back to line integrals: the view's own cone beam again.
    choose(x->outputCombo(), int(ui::XrayOutput::LineIntegrals));
    EXPECT_FALSE(v->polychromatic());
    EXPECT_GT(
        test::compare(v->projection()->pixels, expectedCone(*v, 20.0, 10.0, 1000.0, 750.0)).psnr,
        120.0);
    // The pixel aperture: 4 x 4 rays per pixel, averaged.
    window->renderingPanel()->pixelApertureCheck()->setChecked(true);
    ASSERT_TRUE(v->effects().pixelAperture);
    core::ConeProjectorOptions o;
    o.mapping = v->spectrum()->mapping;
    o.pixelSubsamples = 4;
    const auto area = core::ConeProjector(*v->volume(), o).project(cam).pixels;
    EXPECT_GT(test::compare(v->projection()->pixels, area).psnr, 120.0);
    EXPECT_LT(
        test::compare(v->projection()->pixels, expectedCone(*v, 20.0, 10.0, 1000.0, 750.0)).psnr,
        90.0);
}

TEST_F(Workstation, CompareModePutsParallelBesideConeAtTheSameAngles) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    window->setCompareCount(2);
    ASSERT_EQ(window->views().size(), 2u);
    auto* rendering = window->renderingPanel();
    rendering->appliesToCombo()->setCurrentIndex(2); // view 2
    choose(window->geometryPanel()->projectionCombo(), int(ui::ProjectionKind::Cone));
    rendering->appliesToCombo()->setCurrentIndex(0);
    auto* parallel = window->views()[0];
    auto* cone = window->views()[1];
    EXPECT_EQ(parallel->settings().projection, ui::ProjectionKind::Parallel);
    EXPECT_EQ(cone->settings().projection, ui::ProjectionKind::Cone);
    window->geometryPanel()->primarySpin()->setValue(-40.0);
    window->geometryPanel()->secondarySpin()->setValue(-20.0);
    for (auto* v : {parallel, cone}) {
        const core::CArmAngles a = core::cArmAngles(*v->volume(), v->viewFrame());
        EXPECT_NEAR(a.primaryDeg, -40.0, 1e-9);
        EXPECT_NEAR(a.secondaryDeg, -20.0, 1e-9);
    }
    // The cone-beam view needs no spectrum of its kernel's; the parallel one has view 1's.
    EXPECT_TRUE(cone->spectrum());
    const auto p = parallel->projection(), c = cone->projection();
    ASSERT_TRUE(p && c);
    EXPECT_GT(test::compare(c->pixels, expectedCone(*cone, -40.0, -20.0, 1000.0, 750.0)).psnr,
              120.0);
    // Same orientation, different beams: alike but not equal (the cone magnifies the near side).
    const auto cmp = test::compare(c->pixels, p->pixels);
    EXPECT_GT(cmp.psnr, 12.0);
    EXPECT_LT(cmp.psnr, 60.0);
    EXPECT_TRUE(cone->overlayText().contains(QString::fromUtf8("RAO 40° CAUD 20°")));
}

TEST_F(Workstation, AnXrayIsShownBesideTheDrrOfItsOwnGeometry) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    const core::Volume& vol = *window->views()[0]->volume();
    // The "X-ray": a cone beam of the study from an oblique C-arm with an off-centre
    // detector, written as an XA carrying its geometry.
    const core::CArm arm{-25.0, 12.0, 1100.0, 800.0, core::volumeCentre(vol)};
    const core::ConeCamera cam = core::cArmCamera(arm, 96, 80, 0.9, 0.9, {3.0, -2.0});
    core::ConeProjectorOptions o;
    o.mapping = window->study().spectrum()->mapping;
    const core::DetectorImage xray = core::ConeProjector(vol, o).project(cam);
    const auto path = test::tmpDir() / "match_xa.dcm";
    core::writeXrayDicom(path, xray, arm);

    ui::XrayMatchDialog* d = window->matchXray(QString::fromStdString(path.string()));
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->drr()) << d->errorText().toStdString();
    EXPECT_EQ(d->drr()->width, 96);
    EXPECT_EQ(d->drr()->height, 80);
    // The DRR of the file's geometry is the image the file was made from.
    EXPECT_GT(test::compare(d->drr()->pixels, xray.pixels).psnr, 80.0);
    EXPECT_EQ(d->invertCheck()->isChecked(), true); // an XA: fluoroscopy's dense = dark
    const QImage side = d->canvas()->composed();
    EXPECT_EQ(side.size(), QSize(192, 80));
    d->modeCombo()->setCurrentIndex(
        d->modeCombo()->findData(int(ui::XrayMatchCanvas::Mode::Checkerboard)));
    EXPECT_EQ(d->canvas()->composed().size(), QSize(96, 80));
    // The opacity's ends show one image alone.
    d->modeCombo()->setCurrentIndex(
        d->modeCombo()->findData(int(ui::XrayMatchCanvas::Mode::Overlay)));
    d->opacitySlider()->setValue(0);
    const QImage xrayOnly = d->canvas()->composed();
    d->opacitySlider()->setValue(100);
    EXPECT_NE(d->canvas()->composed(), xrayOnly);

    // Not an X-ray: said, nothing shown, the window still usable.
    const auto bad = test::tmpDir() / "not_an_xray.dcm";
    {
        std::ofstream f(bad);
        f << "hello";
    }
    d = window->matchXray(QString::fromStdString(bad.string()));
    EXPECT_FALSE(d->drr());
    EXPECT_FALSE(d->errorText().isEmpty());
    EXPECT_TRUE(window->messages()->toPlainText().contains("not_an_xray.dcm"));
}

TEST_F(Workstation, AnRtImageIsShownBesideTheDrrOfItsTreatmentBeam) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    const core::Volume& vol = *window->views()[0]->volume();
    // A treatment beam's DRR with couch and collimator turned, written as an RT Image.
    core::TreatmentBeam beam;
    beam.gantryDeg = 30.0;
    beam.couchDeg = 10.0;
    beam.collimatorDeg = 20.0;
    beam.isocentre = core::volumeCentre(vol);
    const core::ConeCamera cam = core::treatmentBeamCamera(beam, 96, 80, 1.2, 1.2);
    core::ConeProjectorOptions o;
    o.mapping = window->study().spectrum()->mapping;
    const core::DetectorImage image = core::ConeProjector(vol, o).project(cam);
    const auto path = test::tmpDir() / "match_rtimage.dcm";
    core::writeRtImageDicom(path, image, beam);

    ui::XrayMatchDialog* d = window->matchXray(QString::fromStdString(path.string()));
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->drr()) << d->errorText().toStdString();
    EXPECT_EQ(d->frameSpin()->maximum(), 1);
    EXPECT_GT(test::compare(d->drr()->pixels, image.pixels).psnr, 80.0);
    EXPECT_TRUE(d->warningsText().isEmpty()) << d->warningsText().toStdString();
}

} // namespace
