// Register to X-ray…: a simulated X-ray (a DRR of the chest phantom at a known pose, written as a
// DICOM XA with the C-arm of the identity camera) is opened; the manual controls move the pose as
// their help line says (checked against the camera's projection of the CT's centre), the DRR
// follows the pose, Register finds the true pose (mTRE against the truth), Cancel stops a run
// with the best pose so far, Revert and Accept do what they say, and Save pose writes a file
// that readPoseJson reads back.
#include <QAction>
#include <QCheckBox>
#include <QDoubleSpinBox>
#include <QElapsedTimer>
#include <QLabel>
#include <QMouseEvent>
#include <QPushButton>

#include <cmath>
#include <cstdio>
#include <fstream>

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/registration/pose.h>
#include <fvr/core/registration/registration_io.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/ui/xray_match.h>
#include <fvr/ui/xray_register.h>

#include "image_metrics.h"
#include "ui_support.h"

namespace {

using namespace fvr;
using fvr::test::openAndWait;
using fvr::test::Workstation;
using ui::StudySource;

/** The identity C-arm (AP, about the study's centre) and its camera. */
struct Scene {
    core::CArm arm;
    core::ConeCamera camera;
    glm::dvec3 centre;
    core::ValueMapping mapping;
};

Scene sceneFor(const core::Volume& vol, core::ValueMapping mapping) {
    Scene s;
    s.centre = core::volumeCentre(vol);
    s.arm = core::CArm{0.0, 0.0, 1000.0, 750.0, s.centre};
    const double pitch = core::framingPitch(vol, 1000.0, 750.0, 128, 128);
    s.camera = core::cArmCamera(s.arm, 128, 128, pitch, pitch);
    s.mapping = mapping;
    return s;
}

/** The DRR of the CT at pose T written as an XA whose geometry is the identity camera. */
std::filesystem::path writeXrayAtPose(const core::Volume& vol, const Scene& s, const glm::dmat4& T,
                                      const std::string& name) {
    core::ConeProjectorOptions o;
    o.mapping = s.mapping;
    core::DetectorImage image = core::ConeProjector(vol, o).project(core::posedCamera(s.camera, T));
    image.camera = s.camera;
    const auto path = test::tmpDir() / name;
    core::writeXrayDicom(path, image, s.arm);
    return path;
}

/** The truth: within the range (rotations +-10 deg, translations +-20 mm). */
core::Pose truthPose() {
    core::Pose p;
    p.rotationDeg = {3.0, -2.0, 4.0};
    p.translationMm = {4.0, -3.0, 5.0};
    return p;
}

/** Where the camera shows a point (columns, rows). */
glm::dvec2 pixelOf(const core::ConeCamera& cam, const glm::dvec3& x) {
    const glm::dvec3 p = cam.matrix().apply(x);
    return {p.x, p.y};
}

bool waitForEnd(ui::XrayRegisterDialog& d, int timeoutMs = 300000) {
    return QTest::qWaitFor([&] { return !d.registering(); }, timeoutMs);
}

TEST_F(Workstation, RegisterToXrayMovesThePoseByHandAndFindsTheTruth) {
    ASSERT_TRUE(openAndWait(*window, StudySource::chest(64)));
    const core::Volume& vol = *window->views()[0]->volume();
    const Scene s = sceneFor(vol, window->study().spectrum()->mapping);
    const glm::dmat4 truth = core::poseMatrix(truthPose(), s.centre);
    const auto path = writeXrayAtPose(vol, s, truth, "register_xa.dcm");

    // From the match dialog's button, as a user goes.
    ui::XrayMatchDialog* m = window->matchXray(QString::fromStdString(path.string()));
    ASSERT_TRUE(m->drr()) << m->errorText().toStdString();
    m->registerButton()->click();
    ui::XrayRegisterDialog* d = window->findChild<ui::XrayRegisterDialog*>();
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->drr()) << d->errorText().toStdString();
    EXPECT_NEAR(glm::length(d->centre() - s.centre), 0.0, 1e-6);
    EXPECT_EQ(d->pose().translationMm, glm::dvec3(0.0));

    // A manual offset through the spin boxes: the DRR is the caster's at that pose.
    const std::vector<float> atIdentity = d->drr()->pixels;
    d->poseSpin(3)->setValue(6.0); // tx
    d->poseSpin(2)->setValue(1.0); // rz
    EXPECT_EQ(d->pose().translationMm.x, 6.0);
    EXPECT_EQ(d->pose().rotationDeg.z, 1.0);
    ASSERT_TRUE(d->drr());
    EXPECT_LT(test::compare(d->drr()->pixels, atIdentity).psnr, 60.0);
    {
        core::ConeProjectorOptions o;
        o.mapping = s.mapping;
        const auto expected = core::ConeProjector(vol, o).project(
            core::posedCamera(s.camera, core::poseMatrix(d->pose(), s.centre)));
        EXPECT_GT(test::compare(d->drr()->pixels, expected.pixels).psnr, 100.0);
    }
    const double mtreStart =
        core::meanTargetError(truth, d->poseMatrix(), core::cubeCorners(s.centre));

    // Register with a small budget: two levels.
    d->registrationOptions().levels = {{32, 4.0, 120, 3.0, 6.0}, {64, 2.0, 80, 1.0, 2.0}};
    d->grab().save(QString::fromStdString((test::tmpDir() / "register_before.png").string()));
    const core::Pose before = d->pose();
    QElapsedTimer clock;
    clock.start();
    d->registerButton()->click();
    EXPECT_TRUE(d->registering());
    EXPECT_TRUE(d->cancelButton()->isEnabled());
    EXPECT_FALSE(d->registerButton()->isEnabled());
    ASSERT_TRUE(waitForEnd(*d));
    const double wall = clock.elapsed() / 1000.0;
    ASSERT_TRUE(d->result());
    EXPECT_FALSE(d->result()->cancelled);
    const double mtre = core::meanTargetError(truth, d->poseMatrix(), core::cubeCorners(s.centre));
    std::printf("[ register ] mTRE %.3f mm -> %.3f mm, similarity %.4f -> %.4f, %.2f s "
                "(%.2f s wall), %d evaluations\n",
                mtreStart, mtre, d->result()->similarityBefore, d->result()->similarityAfter,
                d->result()->seconds, wall, d->result()->evaluations);
    EXPECT_LT(mtre, 2.0);
    EXPECT_GT(d->result()->similarityAfter, d->result()->similarityBefore);
    // The spin boxes show the registered pose; the before overlay is the pose Register started
    // from.
    EXPECT_NEAR(d->poseSpin(3)->value(), d->pose().translationMm.x, 0.05);
    EXPECT_FALSE(d->beforeCanvas()->composed().isNull());
    EXPECT_NE(d->beforeCanvas()->composed(), d->canvas()->composed());
    EXPECT_TRUE(d->resultLabel()->text().contains("→")) << d->resultLabel()->text().toStdString();
    d->checkerboardCheck()->setChecked(true);
    d->grab().save(
        QString::fromStdString((test::tmpDir() / "register_after_checker.png").string()));
    d->checkerboardCheck()->setChecked(false);
    d->grab().save(QString::fromStdString((test::tmpDir() / "register_after.png").string()));
    const QString log = window->messages()->toPlainText();
    EXPECT_TRUE(log.contains("Registration to register_xa.dcm started")) << log.toStdString();
    EXPECT_TRUE(log.contains("Registration to register_xa.dcm finished")) << log.toStdString();

    // Save pose: readPoseJson reads the same matrix back.
    const auto posePath = test::tmpDir() / "register_pose.json";
    ASSERT_TRUE(d->savePose(QString::fromStdString(posePath.string())));
    const glm::dmat4 back = core::readPoseJson(posePath, s.centre);
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) EXPECT_NEAR(back[c][r], d->poseMatrix()[c][r], 1e-9);

    // Revert: the pose before Register, its DRR again.
    ASSERT_TRUE(d->revertButton()->isEnabled());
    d->revertButton()->click();
    EXPECT_EQ(d->pose().translationMm, before.translationMm);
    EXPECT_EQ(d->pose().rotationDeg, before.rotationDeg);
    EXPECT_EQ(d->poseSpin(3)->value(), 6.0);
    EXPECT_FALSE(d->acceptButton()->isEnabled());
    EXPECT_TRUE(window->messages()->toPlainText().contains("reverted"));
}

TEST_F(Workstation, RegisterToXrayManualControlsMoveThePoseAsTheirHelpSays) {
    ASSERT_TRUE(openAndWait(*window, StudySource::chest(64)));
    const core::Volume& vol = *window->views()[0]->volume();
    const Scene s = sceneFor(vol, window->study().spectrum()->mapping);
    const auto path = writeXrayAtPose(vol, s, glm::dmat4(1.0), "register_identity.dcm");
    // File ▸ Register to X-ray… registers to the X-ray the match dialog shows.
    ui::XrayMatchDialog* m = window->matchXray(QString::fromStdString(path.string()));
    ASSERT_TRUE(m->drr()) << m->errorText().toStdString();
    QAction* action = nullptr;
    for (QAction* a : window->findChildren<QAction*>())
        if (a->text() == QString::fromUtf8("Re&gister to X-ray…")) action = a;
    ASSERT_TRUE(action);
    action->trigger();
    ui::XrayRegisterDialog* d = window->findChild<ui::XrayRegisterDialog*>();
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->drr()) << d->errorText().toStdString();
    EXPECT_EQ(d->xray()->file, path);

    // A drag of 10 detector pixels right: the CT's centre is shown 10 columns further right.
    const glm::dvec2 c0 = pixelOf(s.camera, s.centre);
    d->dragPose(QPointF(10.0, 0.0), Qt::NoModifier);
    glm::dvec2 c1 = pixelOf(s.camera, glm::dvec3(d->poseMatrix() * glm::dvec4(s.centre, 1.0)));
    EXPECT_NEAR(c1.x - c0.x, 10.0, 1e-6);
    EXPECT_NEAR(c1.y - c0.y, 0.0, 1e-6);
    EXPECT_NEAR(glm::length(d->pose().rotationDeg), 0.0, 1e-9);
    // ... and 4 rows down.
    d->dragPose(QPointF(0.0, 4.0), Qt::NoModifier);
    c1 = pixelOf(s.camera, glm::dvec3(d->poseMatrix() * glm::dvec4(s.centre, 1.0)));
    EXPECT_NEAR(c1.y - c0.y, 4.0, 1e-6);
    d->setPose({});

    // Shift+drag: a turn about the beam (AP: the y axis) by 0.25 degree per pixel, in place.
    d->dragPose(QPointF(8.0, 0.0), Qt::ShiftModifier);
    EXPECT_NEAR(std::abs(d->pose().rotationDeg.y), 2.0, 1e-6);
    EXPECT_NEAR(d->pose().rotationDeg.x, 0.0, 1e-6);
    EXPECT_NEAR(d->pose().rotationDeg.z, 0.0, 1e-6);
    EXPECT_NEAR(glm::length(d->pose().translationMm), 0.0, 1e-6);
    d->setPose({});
    // Ctrl+drag sideways: about the image's vertical (AP: the z axis); up and down: about its
    // horizontal (the x axis).
    d->dragPose(QPointF(8.0, 0.0), Qt::ControlModifier);
    EXPECT_NEAR(std::abs(d->pose().rotationDeg.z), 2.0, 1e-6);
    EXPECT_NEAR(d->pose().rotationDeg.x, 0.0, 1e-6);
    d->setPose({});
    d->dragPose(QPointF(0.0, 8.0), Qt::ControlModifier);
    EXPECT_NEAR(std::abs(d->pose().rotationDeg.x), 2.0, 1e-6);
    EXPECT_NEAR(d->pose().rotationDeg.z, 0.0, 1e-6);
    d->setPose({});
    // The wheel: along the beam (AP: y), 2 mm a notch.
    d->wheelPose(1.0);
    EXPECT_NEAR(std::abs(d->pose().translationMm.y), 2.0, 1e-9);
    EXPECT_NEAR(d->pose().translationMm.x, 0.0, 1e-9);
    EXPECT_NEAR(d->pose().translationMm.z, 0.0, 1e-9);
    EXPECT_NEAR(d->poseSpin(4)->value(), d->pose().translationMm.y, 1e-9);
    d->setPose({});

    // A real mouse drag on the canvas goes the same way: the pose moves in the detector plane.
    ui::PoseCanvas* canvas = d->canvas();
    const QPointF a(canvas->width() / 2.0, canvas->height() / 2.0), b = a + QPointF(30.0, 0.0);
    QMouseEvent press(QEvent::MouseButtonPress, a, canvas->mapToGlobal(a), Qt::LeftButton,
                      Qt::LeftButton, Qt::NoModifier);
    QMouseEvent move(QEvent::MouseMove, b, canvas->mapToGlobal(b), Qt::NoButton, Qt::LeftButton,
                     Qt::NoModifier);
    QMouseEvent release(QEvent::MouseButtonRelease, b, canvas->mapToGlobal(b), Qt::LeftButton,
                        Qt::NoButton, Qt::NoModifier);
    QApplication::sendEvent(canvas, &press);
    QApplication::sendEvent(canvas, &move);
    QApplication::sendEvent(canvas, &release);
    c1 = pixelOf(s.camera, glm::dvec3(d->poseMatrix() * glm::dvec4(s.centre, 1.0)));
    EXPECT_GT(c1.x - c0.x, 1.0);
    EXPECT_NEAR(c1.y - c0.y, 0.0, 1e-6);
}

TEST_F(Workstation, RegisterToXrayCancelGivesTheBestPoseSoFarAndAcceptKeepsIt) {
    ASSERT_TRUE(openAndWait(*window, StudySource::chest(64)));
    const core::Volume& vol = *window->views()[0]->volume();
    const Scene s = sceneFor(vol, window->study().spectrum()->mapping);
    const auto path =
        writeXrayAtPose(vol, s, core::poseMatrix(truthPose(), s.centre), "register_cancel.dcm");
    ui::XrayRegisterDialog* d = window->registerXray(QString::fromStdString(path.string()));
    ASSERT_TRUE(d->drr()) << d->errorText().toStdString();
    // A large budget: the run would take long; it is cancelled once it has reported progress.
    // A global stage of a million poses: the run cannot end on its own before the cancel.
    d->registrationOptions().levels = {{64, 2.0, 5000, 3.0, 6.0}, {0, 0.0, 5000, 1.0, 2.0}};
    d->registrationOptions().globalSamples = 1000000;
    d->registerButton()->click();
    ASSERT_TRUE(d->registering());
    ASSERT_TRUE(
        QTest::qWaitFor([&] { return d->progressLabel()->text().startsWith("Stage"); }, 120000));
    ASSERT_TRUE(d->registering());
    EXPECT_FALSE(d->poseSpin(0)->isEnabled()); // no manual steps meanwhile
    QElapsedTimer clock;
    clock.start();
    d->cancelButton()->click();
    ASSERT_TRUE(waitForEnd(*d));
    std::printf("[ register ] cancel answered in %lld ms\n", (long long)clock.elapsed());
    ASSERT_TRUE(d->result());
    EXPECT_TRUE(d->result()->cancelled);
    EXPECT_TRUE(d->resultLabel()->text().startsWith("Cancelled"));
    EXPECT_TRUE(window->messages()->toPlainText().contains("register_cancel.dcm cancelled"));
    // Accept keeps the best pose so far; Revert has nothing to go back to any more.
    const core::Pose found = d->pose();
    ASSERT_TRUE(d->acceptButton()->isEnabled());
    d->acceptButton()->click();
    EXPECT_EQ(d->pose().rotationDeg, found.rotationDeg);
    EXPECT_EQ(d->pose().translationMm, found.translationMm);
    EXPECT_EQ(d->poseBeforeRegistration().translationMm, found.translationMm);
    EXPECT_FALSE(d->revertButton()->isEnabled());
    EXPECT_TRUE(d->registerButton()->isEnabled());
    EXPECT_TRUE(window->messages()->toPlainText().contains("accepted"));
}

TEST_F(Workstation, RegisterToXrayRefusesAFileWithoutGeometry) {
    ASSERT_TRUE(openAndWait(*window, StudySource::chest(64)));
    const auto bad = test::tmpDir() / "register_not_an_xray.dcm";
    {
        std::ofstream f(bad);
        f << "hello";
    }
    ui::XrayRegisterDialog* d = window->registerXray(QString::fromStdString(bad.string()));
    EXPECT_FALSE(d->drr());
    EXPECT_FALSE(d->errorText().isEmpty());
    EXPECT_FALSE(d->registerButton()->isEnabled());
    EXPECT_TRUE(window->messages()->toPlainText().contains("register_not_an_xray.dcm"));
}

TEST_F(Workstation, ClosingTheWindowDuringARegistrationStopsIt) {
    ASSERT_TRUE(openAndWait(*window, StudySource::chest(64)));
    const core::Volume& vol = *window->views()[0]->volume();
    const Scene s = sceneFor(vol, window->study().spectrum()->mapping);
    const auto path =
        writeXrayAtPose(vol, s, core::poseMatrix(truthPose(), s.centre), "register_close.dcm");
    ui::XrayRegisterDialog* d = window->registerXray(QString::fromStdString(path.string()));
    ASSERT_TRUE(d->drr()) << d->errorText().toStdString();
    d->registrationOptions().levels = {{0, 0.0, 100000, 3.0, 6.0}};
    d->registrationOptions().globalSamples = 1000000; // cannot end on its own
    d->registerButton()->click();
    ASSERT_TRUE(
        QTest::qWaitFor([&] { return d->progressLabel()->text().startsWith("Stage"); }, 120000));
    // The dialog goes with the window: its registration sees the cancel at its next evaluation
    // and the window's destruction waits for it (no crash, no outcome delivered to the dead).
    ASSERT_TRUE(d->registering());
    QElapsedTimer clock;
    clock.start();
    window.reset();
    std::printf("[ register ] window closed during a registration in %lld ms\n",
                (long long)clock.elapsed());
    QApplication::processEvents();
}

} // namespace
