// Cine and the tag browser: playback turns the view by the step per tick about the patient's
// S-I axis and stops on pause (or after one turn); the MP4 decodes (FFmpeg) to one frame per
// step, each the rendered frame at its angle; the multi-frame DICOM reads back (DCMTK) with its
// frames and frame time and passes dciodvfy; the tag browser lists PatientName and its filter
// narrows the rows.
#include <QAction>
#include <QComboBox>
#include <QElapsedTimer>
#include <QLineEdit>
#include <QProgressDialog>
#include <QTimer>
#include <QToolBar>
#include <QToolButton>
#include <QTreeWidget>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <sstream>
#include <unistd.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <fvr/ui/cine_controller.h>
#include <fvr/ui/dicom_tags_dialog.h>

#include "dicom_tag.h"
#include "support/movie_decode.h"
#include "ui_support.h"

namespace fvr::test {
namespace {

using fvr::test::dicomTag;

namespace fs = std::filesystem;

const char* kCt = "dicom/ct_head_slicer_64x64x93";

double angleDeg(const core::Vec3& a, const core::Vec3& b) {
    const double c = glm::dot(a, b) / (glm::length(a) * glm::length(b));
    return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

/** The patient's S-I axis in the volume's index frame (an independent reading of direction). */
core::Vec3 siAxis(const core::Volume& v) {
    const glm::dmat3 toIndex = glm::transpose(v.direction); // orthonormal: inverse = transpose
    return toIndex * glm::dvec3(0, 0, 1);
}

std::string tmp(const std::string& name) {
    return (tmpDir() / ("cine_" + std::to_string(getpid()) + "_" + name)).string();
}

QAction* playAction(MainWindow& w) { return w.findChild<QAction*>("cine.play"); }

TEST_F(Workstation, CineTurnsByTheStepPerTickAndStopsOnPause) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ui::CineController& cine = window->cine();
    ui::CineSettings s;
    s.stepDegrees = 7.0;
    s.fps = 40.0;
    cine.setSettings(s);
    const core::ViewFrame start = window->views()[0]->viewFrame();
    const core::Vec3 axis = siAxis(*window->study().volume());
    std::vector<core::ViewFrame> seen{start};
    QObject::connect(&cine, &ui::CineController::stepped,
                     [&](const core::ViewFrame& f) { seen.push_back(f); });
    QAction* play = playAction(*window);
    ASSERT_TRUE(play);
    EXPECT_EQ(play->shortcut(), QKeySequence(Qt::Key_Space));
    play->trigger();
    EXPECT_TRUE(cine.playing());
    ASSERT_TRUE(QTest::qWaitFor([&] { return cine.ticks() >= 4; }, 20000));
    play->trigger();
    EXPECT_FALSE(cine.playing());
    const int ticks = cine.ticks();
    ASSERT_EQ(int(seen.size()), ticks + 1);
    for (int k = 1; k <= ticks; ++k) {
        // Each tick: 7° about S-I (the direction turns in the plane normal to the axis, which is
        // in that plane for the AP start), and every view shows the frame.
        EXPECT_NEAR(angleDeg(seen[k - 1].d, seen[k].d), 7.0, 1e-6) << "tick " << k;
        EXPECT_NEAR(glm::dot(seen[k].d, axis), glm::dot(start.d, axis), 1e-9) << "tick " << k;
    }
    EXPECT_NEAR(angleDeg(start.d, window->views()[0]->viewFrame().d), 7.0 * ticks, 1e-6);
    // Paused: nothing moves any more.
    const core::ViewFrame paused = window->views()[0]->viewFrame();
    QTest::qWait(300);
    EXPECT_EQ(cine.ticks(), ticks);
    EXPECT_LT(glm::length(window->views()[0]->viewFrame().d - paused.d), 1e-12);
}

TEST_F(Workstation, MainAndCineToolbarsShowEveryControlSideBySideAt1200Pixels) {
    // The toolbar buttons short ("Open folder", "2 views", "Play"), the menus whole: at 1200
    // pixels (the tests' window, a laptop's) none of the Cine toolbar's controls hides behind »,
    // on the main toolbar's row.
    window->resize(1200, 800);
    QTest::qWait(100);
    auto* cine = window->findChild<QToolBar*>("toolbar.cine");
    auto* main = window->findChild<QToolBar*>("toolbar.main");
    ASSERT_TRUE(cine && main);
    for (QToolBar* tb : {main, cine})
        for (QAction* a : tb->actions())
            if (QWidget* w = tb->widgetForAction(a); w && !a->isSeparator())
                EXPECT_TRUE(w->isVisible()) << a->text().toStdString();
    EXPECT_EQ(cine->y(), main->y());
    // The menus keep the whole words, the buttons say them in their tooltips.
    auto* folder = qobject_cast<QToolButton*>(main->widgetForAction(main->actions().at(0)));
    ASSERT_NE(folder, nullptr);
    EXPECT_EQ(folder->text(), "Open folder");
    EXPECT_EQ(main->actions().at(0)->text(), "Open DICOM &folder…");
    EXPECT_TRUE(folder->toolTip().startsWith("Open DICOM folder"))
        << folder->toolTip().toStdString();
}

TEST_F(Workstation, CineOfOneTurnStopsWhereItStarted) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ui::CineController& cine = window->cine();
    ui::CineSettings s;
    s.stepDegrees = 90.0;
    s.fps = 50.0;
    s.loop = false;
    cine.setSettings(s);
    const core::ViewFrame start = window->views()[0]->viewFrame();
    cine.play();
    ASSERT_TRUE(QTest::qWaitFor([&] { return !cine.playing(); }, 20000));
    EXPECT_EQ(cine.ticks(), 4);
    EXPECT_LT(glm::length(window->views()[0]->viewFrame().d - start.d), 1e-9);
}

TEST_F(Workstation, MovieDecodesToTheRenderedFrameAtEachAngle) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ui::CineSettings s;
    s.stepDegrees = 45.0; // 8 frames
    s.fps = 12.0;
    window->cine().setSettings(s);
    ui::ProjectionView* v = window->views()[0];
    const core::ViewFrame start = v->viewFrame();
    const std::string path = tmp("movie.mp4");
    QElapsedTimer clock;
    clock.start();
    ASSERT_TRUE(window->exportMovie(QString::fromStdString(path)))
        << window->messages()->toPlainText().toStdString();
    std::printf("[cine] 8-frame movie of %d x %d: %lld ms (%s)\n", v->settings().size,
                v->settings().size, static_cast<long long>(clock.elapsed()),
                v->usingGpu() ? "GPU" : "CPU");
    EXPECT_LT(glm::length(v->viewFrame().d - start.d), 1e-12); // back where it was
    const DecodedMovie d = decodeMovie(path);
    ASSERT_EQ(d.error, "");
    ASSERT_EQ(d.frames.size(), 8u);
    EXPECT_NEAR(d.fps, 12.0, 1e-6);
    const core::Vec3 axis = siAxis(*window->study().volume());
    for (int k : {0, 3}) {
        // The oracle: the view rendered at k x 45° about S-I, through its window.
        v->setViewFrame(start.rotated(axis, k * std::numbers::pi / 4));
        const auto p = v->projection();
        ASSERT_TRUE(p);
        EXPECT_EQ(d.width, p->width);
        EXPECT_EQ(d.height, p->height);
        std::vector<double> shown(p->pixels.size());
        for (std::size_t i = 0; i < shown.size(); ++i) shown[i] = v->window().map(p->pixels[i]);
        const double same = correlation(d.frames[k], shown);
        EXPECT_GT(same, 0.99) << "frame " << k;
        // and better than the frames 45° either side (the order is right; frames 360° - θ are
        // mirror images, alike for a symmetric phantom)
        EXPECT_GT(same, correlation(d.frames[(k + 1) % 8], shown)) << "frame " << k;
        EXPECT_GT(same, correlation(d.frames[(k + 7) % 8], shown)) << "frame " << k;
    }
    v->setViewFrame(start);
}

TEST_F(Workstation, MovieExportCancelledWritesNothing) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ui::CineSettings s;
    s.stepDegrees = 2.0; // 180 frames: long enough to cancel
    window->cine().setSettings(s);
    const core::ViewFrame start = window->views()[0]->viewFrame();
    const std::string path = tmp("cancelled.mp4");
    fs::remove(path);
    // The user presses Cancel in the progress dialog while the frames render.
    QTimer cancel;
    QObject::connect(&cancel, &QTimer::timeout, [&] {
        for (QProgressDialog* p : window->findChildren<QProgressDialog*>()) p->cancel();
    });
    cancel.start(50);
    EXPECT_FALSE(window->exportMovie(QString::fromStdString(path)));
    EXPECT_FALSE(fs::exists(path));
    EXPECT_TRUE(window->messages()->toPlainText().contains("Movie export cancelled"));
    EXPECT_LT(glm::length(window->views()[0]->viewFrame().d - start.d), 1e-12);
    for (const auto& e : fs::directory_iterator(tmpDir()))
        EXPECT_EQ(e.path().filename().string().find("cancelled.mp4"), std::string::npos)
            << "left: " << e.path();
}

TEST_F(Workstation, CineDicomReadsBackAndPassesDciodvfy) {
    FVR_REQUIRE_DATA(kCt);
    ASSERT_TRUE(openAndWait(
        *window, StudySource::fromPath(QString::fromStdString((sharedData() / kCt).string()))));
    ui::CineSettings s;
    s.stepDegrees = 120.0; // 3 frames
    s.fps = 8.0; // 125 ms apart
    window->cine().setSettings(s);
    const std::string path = tmp("cine.dcm");
    ASSERT_TRUE(window->exportCineDicom(QString::fromStdString(path)))
        << window->messages()->toPlainText().toStdString();
    EXPECT_EQ(dicomTag(path, DCM_NumberOfFrames), "3");
    EXPECT_EQ(dicomTag(path, DCM_FrameTime), "125");
    EXPECT_EQ(dicomTag(path, DCM_FrameIncrementPointer), "(0018,1063)");
    const std::string first = window->study().series()->files.front().string();
    for (const DcmTagKey& k : {DCM_PatientName, DCM_PatientID, DCM_StudyInstanceUID, DCM_StudyDate})
        EXPECT_EQ(dicomTag(path, k), dicomTag(first, k)) << DcmTag(k).getTagName();
    EXPECT_NE(dicomTag(path, DCM_SeriesInstanceUID), dicomTag(first, DCM_SeriesInstanceUID));
    if (runCommand("command -v dciodvfy").status != 0)
        GTEST_SKIP() << "dciodvfy (Debian package dicom3tools) is not installed";
    const auto r = runCommand("dciodvfy -new '" + path + "' 2>&1");
    std::istringstream in(r.out);
    for (std::string line; std::getline(in, line);) {
        EXPECT_NE(line.rfind("Error", 0), 0u) << line;
        if (line.rfind("Warning", 0) == 0) std::cout << "dciodvfy: " << line << "\n";
    }
}

TEST_F(Workstation, TagBrowserListsPatientNameAndTheFilterNarrows) {
    FVR_REQUIRE_DATA(kCt);
    ASSERT_TRUE(openAndWait(
        *window, StudySource::fromPath(QString::fromStdString((sharedData() / kCt).string()))));
    ui::DicomTagsDialog* tags = window->showDicomTags();
    ASSERT_TRUE(tags);
    const auto& files = window->study().series()->files;
    EXPECT_EQ(tags->instanceCombo()->count(), int(files.size()));
    const std::string name = dicomTag(files.front().string(), DCM_PatientName);
    const QStringList all = tags->visibleRows();
    EXPECT_TRUE(all.contains("PatientName=" + QString::fromStdString(name))) << name;
    EXPECT_GT(all.size(), 20);
    tags->filterEdit()->setText("patientname"); // as typed: case does not matter
    const QStringList narrowed = tags->visibleRows();
    EXPECT_EQ(narrowed, QStringList{"PatientName=" + QString::fromStdString(name)})
        << narrowed.join("; ").toStdString();
    tags->filterEdit()->setText("00100010"); // the tag without brackets
    EXPECT_EQ(tags->visibleRows(), narrowed);
    tags->filterEdit()->setText(QString::fromStdString(dicomTag(files.front().string(), DCM_Rows)));
    EXPECT_TRUE(tags->visibleRows().contains("Rows=64"));
    EXPECT_LT(tags->visibleRows().size(), all.size());
    // Another instance: its own SOPInstanceUID.
    tags->filterEdit()->setText("SOPInstanceUID");
    const auto uidRow = [&](int i) {
        return "SOPInstanceUID=" +
               QString::fromStdString(dicomTag(files[i].string(), DCM_SOPInstanceUID));
    };
    EXPECT_TRUE(tags->visibleRows().contains(uidRow(0)));
    tags->instanceCombo()->setCurrentIndex(5);
    const QStringList fifth = tags->visibleRows();
    EXPECT_TRUE(fifth.contains(uidRow(5))) << fifth.join("; ").toStdString();
    EXPECT_FALSE(fifth.contains(uidRow(0))) << fifth.join("; ").toStdString();
}

TEST_F(Workstation, TagBrowserSaysAPhantomHasNoTags) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(32)));
    ui::DicomTagsDialog* tags = window->showDicomTags();
    EXPECT_TRUE(tags->visibleRows().isEmpty());
    EXPECT_TRUE(tags->error().contains("not DICOM")) << tags->error().toStdString();
}

} // namespace
} // namespace fvr::test
