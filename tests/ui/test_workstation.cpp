// The workstation driven like a user (QTest, real widgets and GL under Xvfb): opening studies
// through the menus' code path, panel controls, compare mode, exports, cancel, bad input.
#include <QApplication>
#include <QCheckBox>
#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QImage>
#include <QLabel>
#include <QMouseEvent>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QPushButton>
#include <QSettings>
#include <QSignalSpy>
#include <QSpinBox>
#include <QStandardPaths>
#include <QSurfaceFormat>
#include <QTest>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>

#include <gtest/gtest.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/xray/spectrum_model.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/messages_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/study_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_keys.h>
#include <fvr/ui/settings_model.h>

#include "image_metrics.h"
#include "test_support.h"
#include "ui/ui_support.h"

using namespace fvr;
using fvr::test::app;
using fvr::test::openAndWait;
using fvr::test::Workstation;
using fvr::ui::MainWindow;
using fvr::ui::StudySource;

namespace {

/** Waits for a new spectrum after a panel change. */
bool waitSpectrum(MainWindow& w, const std::function<void()>& change) {
    QSignalSpy ready(&w.study(), &ui::StudyController::spectrumReady);
    change();
    return ready.wait(60000);
}

core::ProjectionImage cpuReference(MainWindow& w, const ui::ProjectionView& v) {
    (void)w;
    core::CpuFourierRenderer r(v.spectrum(), 2); // the view's own (compare kernels have theirs)
    // The view's full-quality parameters: voxel model, depth cue, filters, clip, as it renders.
    return r.render(v.renderParams(v.settings().size, v.settings().kernel));
}

} // namespace

TEST_F(Workstation, OpensPhantomAndShowsTheRendererProjection) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    auto* v = window->views()[0];
    const auto p = v->projection();
    ASSERT_TRUE(p);
    std::printf("[ui] backend %s %s\n", v->usingGpu() ? "GPU" : "CPU",
                v->backendNotice().toStdString().c_str());
    EXPECT_GT(test::compare(p->pixels, cpuReference(*window, *v).pixels).psnr, 90.0);
    EXPECT_TRUE(window->windowTitle().contains("phantom"));
    // The window is set from the image, and the view is not blank.
    const QImage shot = v->screenshot();
    ASSERT_FALSE(shot.isNull());
    int bright = 0;
    for (int y = 0; y < shot.height(); y += 4)
        for (int x = 0; x < shot.width(); x += 4) bright += qGray(shot.pixel(x, y)) > 128;
    EXPECT_GT(bright, 50);
}

TEST_F(Workstation, PanelControlsChangeSettingsAndImage) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    auto* v = window->views()[0];
    const auto before = *v->projection();

    auto* kernel = window->renderingPanel()->kernelCombo();
    // With the gridding correction on, a new kernel needs a spectrum made for it.
    ASSERT_TRUE(waitSpectrum(*window, [&] {
        kernel->setCurrentIndex(kernel->findData(int(core::Kernel::KaiserBessel6)));
    }));
    EXPECT_EQ(window->study().spectrum()->deapodizedFor, core::Kernel::KaiserBessel6);
    QApplication::processEvents();
    EXPECT_EQ(v->settings().kernel, core::Kernel::KaiserBessel6);
    EXPECT_GT(test::compare(v->projection()->pixels, cpuReference(*window, *v).pixels).psnr, 90.0);
    ASSERT_TRUE(waitSpectrum(
        *window, [&] { window->renderingPanel()->deapodizeCheck()->setChecked(false); }));
    EXPECT_FALSE(window->study().spectrum()->deapodizedFor.has_value());
    kernel->setCurrentIndex(kernel->findData(int(core::Kernel::Nearest)));
    EXPECT_EQ(v->settings().kernel, core::Kernel::Nearest);
    const auto nearest = *v->projection();
    EXPECT_LT(test::compare(nearest.pixels, before.pixels).psnr, 80.0); // a different image
    EXPECT_GT(test::compare(nearest.pixels, cpuReference(*window, *v).pixels).psnr, 90.0);

    auto* size = window->renderingPanel()->sizeCombo();
    size->setCurrentIndex(size->findData(256));
    EXPECT_EQ(v->settings().size, 256);
    EXPECT_EQ(v->projection()->width, 256);

    ASSERT_TRUE(waitSpectrum(*window, [&] {
        window->renderingPanel()->oversamplingCombo()->setCurrentIndex(
            window->renderingPanel()->oversamplingCombo()->findData(1.5));
    }));
    EXPECT_EQ(window->study().spectrum()->padded[0], 60);
    ASSERT_TRUE(waitSpectrum(*window, [&] {
        window->renderingPanel()->transformCombo()->setCurrentIndex(
            window->renderingPanel()->transformCombo()->findData(int(core::TransformKind::Fht)));
    }));
    EXPECT_EQ(window->study().spectrum()->kind, core::TransformKind::Fht);
    QTest::qWait(50);
    EXPECT_GT(test::compare(v->projection()->pixels, cpuReference(*window, *v).pixels).psnr, 90.0);
    ASSERT_TRUE(waitSpectrum(*window, [&] {
        window->renderingPanel()->valuesCombo()->setCurrentIndex(
            window->renderingPanel()->valuesCombo()->findData(int(core::ValueMapping::Raw)));
    }));
    EXPECT_EQ(window->study().spectrum()->mapping, core::ValueMapping::Raw);

    window->displayPanel()->invertCheck()->setChecked(true);
    EXPECT_TRUE(v->window().invert);
    window->displayPanel()->windowWidthSpin()->setValue(1234.0);
    EXPECT_NEAR(v->window().high - v->window().low, 1234.0, 1e-6);
    window->displayPanel()->windowLevelSpin()->setValue(-50.0);
    EXPECT_NEAR((v->window().high + v->window().low) / 2, -50.0, 1e-6);
}

static double meanOf(const std::vector<float>& p) {
    double s = 0;
    for (float x : p) s += x;
    return s / double(p.size());
}

/** Waits until every view has its spectrum and no job runs (compare spectra come one by one). */
static bool waitAllViewsReady(MainWindow& w) {
    return QTest::qWaitFor(
        [&] {
            if (w.study().busy()) return false;
            for (auto* v : w.views())
                if (!v->spectrum()) return false;
            return true;
        },
        60000);
}

// On a software OpenGL (llvmpipe, slower than the CPU renderer) the views render on the
// CPU and the status bar says why; View ▸ Use a software GPU takes it anyway. A hardware GPU is
// always used.
TEST_F(Workstation, SoftwareOpenGlRendersOnTheCpu) {
    QSettings().setValue("render/softwareGpu", false); // the default
    window = std::make_unique<MainWindow>();
    window->resize(1200, 800);
    window->show();
    ASSERT_TRUE(QTest::qWaitForWindowExposed(window.get()));
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    auto* v = window->views()[0];
    EXPECT_FALSE(window->softwareGpuAction()->isChecked());
    EXPECT_EQ(v->usingGpu(), !v->softwareGl());
    const auto cpuFrame = *v->projection();
    EXPECT_GT(test::compare(cpuFrame.pixels, cpuReference(*window, *v).pixels).psnr, 90.0);
    if (v->softwareGl()) {
        EXPECT_TRUE(window->messages()->toPlainText().contains("the OpenGL is software"))
            << window->messages()->toPlainText().toStdString();
        window->softwareGpuAction()->setChecked(true); // View ▸ Use a software GPU
        EXPECT_TRUE(v->usingGpu());
        EXPECT_TRUE(window->settings().rendering().softwareGpu);
        EXPECT_TRUE(QSettings().value("render/softwareGpu").toBool());
        // The same image from the GPU renderer.
        EXPECT_GT(test::compare(v->projection()->pixels, cpuFrame.pixels).psnr, 90.0);
        window->softwareGpuAction()->setChecked(false);
        EXPECT_FALSE(v->usingGpu());
    }
}

// Compare mode is fair: gridding correction stays on, every kernel renders from its
// own corrected spectrum, every view's mean is that of the single view, the memory is shown,
// and single view comes back as it was.
TEST_F(Workstation, CompareViewRendersEachKernelAtItsBest) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    ASSERT_TRUE(window->renderingPanel()->deapodizeCheck()->isChecked()); // the default
    ASSERT_EQ(window->study().spectrum()->deapodizedFor, core::Kernel::KaiserBessel4);
    const auto single = *window->views()[0]->projection();
    const core::DisplayWindow singleWindow = window->views()[0]->window();
    const double singleMiB = window->study().spectraMiB();

    window->setCompareCount(4);
    ASSERT_TRUE(waitAllViewsReady(*window)) << window->messages()->toPlainText().toStdString();
    EXPECT_TRUE(window->renderingPanel()->deapodizeCheck()->isChecked());
    ASSERT_EQ(window->views().size(), 4u);
    std::set<core::Kernel> kernels;
    for (auto* v : window->views()) {
        const core::Kernel k = v->settings().kernel;
        kernels.insert(k);
        EXPECT_EQ(v->spectrum()->deapodizedFor,
                  core::griddingCorrectionHelps(k) ? std::optional(k) : std::nullopt)
            << core::kernelName(k);
        const auto p = v->projection();
        ASSERT_TRUE(p);
        EXPECT_GT(test::compare(p->pixels, cpuReference(*window, *v).pixels).psnr, 90.0)
            << core::kernelName(k);
        // The mean is the projected mass: within 5 % for the accurate kernels. Nearest, linear
        // and the windowed sinc at 1.25x miss it on this phantom deapodized or not (measured:
        // nearest -11 / -20 %, sinc4 +5 / -11 %, linear +16 / -10 % with / without; README,
        // compare mode); without gridding correction Kaiser-Bessel 4 lost 47 %.
        const bool coarse =
            k == core::Kernel::Nearest || k == core::Kernel::Linear || k == core::Kernel::Sinc4;
        const double tolerance = coarse ? 0.15 : 0.05;
        EXPECT_NEAR(meanOf(p->pixels), meanOf(single.pixels), tolerance * meanOf(single.pixels))
            << core::kernelName(k);
        EXPECT_EQ(v->viewFrame().d, window->views()[0]->viewFrame().d); // synchronised
        EXPECT_EQ(v->window().low, singleWindow.low); // one window, from the corrected view 1
        EXPECT_EQ(v->window().high, singleWindow.high);
    }
    EXPECT_EQ(kernels.size(), 4u);
    EXPECT_TRUE(kernels.count(core::Kernel::KaiserBessel4)); // view 1 keeps the main kernel
    EXPECT_EQ(window->study().spectrumCount(), 4);
    EXPECT_NEAR(window->study().spectraMiB(), 4 * singleMiB, 1e-6);
    const QString memory = window->renderingPanel()->memoryLabel()->text();
    EXPECT_TRUE(memory.contains(QString::number(4 * singleMiB, 'f', 1)) &&
                memory.contains(QStringLiteral("in 4 spectra")))
        << memory.toStdString();

    window->setDifferenceMode(true);
    QTest::qWait(100);
    EXPECT_TRUE(window->views()[1]->projection().has_value());
    window->setDifferenceMode(false);

    window->setCompareCount(1); // back as it was: gridding on, one spectrum, the same image
    ASSERT_EQ(window->views().size(), 1u);
    EXPECT_TRUE(window->renderingPanel()->deapodizeCheck()->isChecked());
    EXPECT_EQ(window->study().spectrumCount(), 1);
    EXPECT_GT(test::compare(window->views()[0]->projection()->pixels, single.pixels).psnr, 120.0);
    EXPECT_EQ(window->views()[0]->window().high, singleWindow.high);
}

// The difference views show the difference (not an empty view), in 2 and 4 views.
TEST_F(Workstation, DifferenceViewsShowTheDifference) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    for (int n : {2, 4}) {
        window->setCompareCount(n); // each kernel's own corrected spectrum is prepared
        ASSERT_TRUE(waitAllViewsReady(*window));
        window->setDifferenceMode(true);
        for (int i = 0; i < 20; ++i) QTest::qWait(50);
        for (std::size_t v = 1; v < window->views().size(); ++v) {
            auto* view = window->views()[v];
            const QImage shot = view->screenshot().convertToFormat(QImage::Format_Grayscale8);
            // The image area (the middle half) is not uniform: the difference shows structure.
            int lo = 255, hi = 0;
            for (int y = shot.height() / 4; y < 3 * shot.height() / 4; ++y)
                for (int x = shot.width() / 4; x < 3 * shot.width() / 4; ++x) {
                    const int g = qGray(shot.pixel(x, y));
                    lo = std::min(lo, g);
                    hi = std::max(hi, g);
                }
            EXPECT_GT(hi - lo, 40) << n << " views, view " << v + 1;
        }
        window->setDifferenceMode(false);
    }
}

// No progress bar is left behind once the jobs of quick setting changes end
// (the GUI asked busy(), which races with the worker's last instructions).
TEST_F(Workstation, NoProgressBarLeftAfterQuickChanges) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(64)));
    auto* gridding = window->renderingPanel()->deapodizeCheck();
    for (int round = 0; round < 3; ++round) {
        window->setCompareCount(4);
        window->setCompareCount(1);
        gridding->setChecked(!gridding->isChecked());
        gridding->setChecked(true);
        ASSERT_TRUE(QTest::qWaitFor([&] { return !window->study().busy(); }, 60000));
        QTest::qWait(200); // queued results and progress polls arrive
        EXPECT_FALSE(window->progressBar()->isVisible())
            << "round " << round << ": " << window->progressBar()->format().toStdString();
        EXPECT_TRUE(window->study().spectrum()->deapodizedFor.has_value());
        EXPECT_EQ(window->study().spectrumCount(), 1); // single view: no compare spectra kept
    }
}

// Compare spectra under interruptions: a cancelled compare job leaves no progress bar and views
// that say why they show nothing (Compare again retries); leaving compare mode mid-preparation
// frees what was being prepared; the user's window survives entering and leaving compare mode.
TEST_F(Workstation, CompareSpectraSurviveCancelsAndModeChanges) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(64)));
    window->study().setSimulatedCompareDelayMs(1500); // each compare spectrum: time to cancel
    window->displayPanel()->windowWidthSpin()->setValue(
        window->displayPanel()->windowWidthSpin()->value() * 0.5); // a window set by hand
    const core::DisplayWindow mine = window->views()[0]->window();
    window->setCompareCount(4);
    for (auto* v : window->views()) EXPECT_EQ(v->window().high, mine.high);
    ASSERT_TRUE(QTest::qWaitFor([&] { return window->cancelButton()->isVisible(); }, 10000));
    QTest::mouseClick(window->cancelButton(), Qt::LeftButton);
    ASSERT_TRUE(QTest::qWaitFor([&] { return !window->study().busy(); }, 60000));
    QTest::qWait(200);
    EXPECT_FALSE(window->progressBar()->isVisible())
        << window->progressBar()->format().toStdString();
    int waiting = 0;
    for (auto* v : window->views())
        if (!v->spectrum()) {
            ++waiting;
            EXPECT_TRUE(v->pendingFailed());
            EXPECT_TRUE(v->pendingText().startsWith("Not prepared"))
                << v->pendingText().toStdString();
        }
    EXPECT_GT(waiting, 0);
    window->study().setSimulatedCompareDelayMs(0);
    window->setCompareCount(4); // Compare again: retried, every view gets its spectrum
    ASSERT_TRUE(waitAllViewsReady(*window));
    window->study().setSimulatedCompareDelayMs(1500);
    for (auto* v : window->views()) EXPECT_EQ(v->window().high, mine.high);
    // Leaving compare mode while a compare spectrum is being prepared frees it.
    window->setCompareCount(1);
    window->setCompareCount(2);
    ASSERT_TRUE(QTest::qWaitFor([&] { return window->study().busy(); }, 5000));
    window->setCompareCount(1);
    ASSERT_TRUE(QTest::qWaitFor([&] { return !window->study().busy(); }, 60000));
    QTest::qWait(200);
    EXPECT_EQ(window->study().spectrumCount(), 1);
    EXPECT_FALSE(window->progressBar()->isVisible());
    EXPECT_EQ(window->views()[0]->window().high, mine.high);
}

TEST_F(Workstation, ExportsMatchTheRendererProjection) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    const auto dir = test::tmpDir() / "ui_export";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const auto p = *window->views()[0]->projection();
    ASSERT_TRUE(window->exportProjection(QString::fromStdString((dir / "p.npy").string())));
    std::vector<std::int64_t> shape;
    EXPECT_EQ(core::readNpy(dir / "p.npy", shape), p.pixels);
    ASSERT_TRUE(window->exportProjection(QString::fromStdString((dir / "p.png").string())));
    const QImage png(QString::fromStdString((dir / "p.png").string()));
    EXPECT_EQ(png.width(), p.width);
    EXPECT_EQ(png.format(), QImage::Format_Grayscale16);
    ASSERT_TRUE(window->exportScreenshot(QString::fromStdString((dir / "shot.png").string())));
    EXPECT_FALSE(QImage(QString::fromStdString((dir / "shot.png").string())).isNull());
    ASSERT_TRUE(
        window->exportSweep(QString::fromStdString((dir / "sweep").string()), 4, {0, 1, 0}));
    const auto stack = core::readNpy(dir / "sweep" / "sweep.npy", shape);
    EXPECT_EQ(shape, (std::vector<std::int64_t>{4, p.height, p.width}));
    EXPECT_TRUE(std::equal(p.pixels.begin(), p.pixels.end(), stack.begin())); // frame 0 = the view
    EXPECT_TRUE(std::filesystem::exists(dir / "sweep" / "frame_0003.png"));
    EXPECT_FALSE(window->exportProjection("/no/such/dir/p.npy"));
    EXPECT_TRUE(window->messages()->toPlainText().contains("/no/such/dir/p.npy"));
}

TEST_F(Workstation, CancelDuringPreprocessingKeepsTheStudy) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(32)));
    const auto spectrumBefore = window->study().spectrum();
    QSignalSpy cancelled(&window->study(), &ui::StudyController::cancelled);
    window->openStudy(StudySource::phantom(200));
    ASSERT_TRUE(QTest::qWaitFor([&] { return window->cancelButton()->isVisible(); }, 5000));
    ASSERT_TRUE(window->study().busy()); // 200³ takes seconds: the cancel lands mid-job
    QTest::mouseClick(window->cancelButton(), Qt::LeftButton);
    // The cancel shows at once, while the job winds down.
    EXPECT_TRUE(window->progressBar()->format().startsWith("cancelling"))
        << window->progressBar()->format().toStdString();
    EXPECT_FALSE(window->cancelButton()->isEnabled());
    ASSERT_TRUE(cancelled.wait(60000));
    EXPECT_EQ(window->study().spectrum(), spectrumBefore);
    EXPECT_TRUE(window->views()[0]->projection().has_value());
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(36))); // still usable
    EXPECT_EQ(window->study().volume()->dims[0], 36);
}

// After a cancelled change the panel shows the settings in effect, and the
// next study opens with them.
TEST_F(Workstation, CancelledChangeLeavesThePanelShowingWhatIsInEffect) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(256)));
    const double inEffect = window->study().spectrumSettings().oversampling;
    const double mib = double(window->study().spectrum()->bytes()) / (1 << 20);
    auto* os = window->renderingPanel()->oversamplingCombo();
    QSignalSpy cancelled(&window->study(), &ui::StudyController::cancelled);
    os->setCurrentIndex(os->findData(2.0)); // 512^3: long enough to cancel
    ASSERT_TRUE(window->study().busy());
    // Meanwhile the memory readout says what is in use and what the 2x spectrum will take.
    const QString preparing = window->renderingPanel()->memoryLabel()->text();
    const double estimate = window->study().estimatedSpectrumMiB(window->study().targetSettings());
    EXPECT_GT(estimate, 2 * mib);
    EXPECT_TRUE(preparing.startsWith(QString::number(mib, 'f', 1)) &&
                preparing.contains(QString::number(estimate, 'f', 1) + " MiB once"))
        << preparing.toStdString();
    window->study().cancel();
    ASSERT_TRUE(cancelled.wait(60000));
    EXPECT_DOUBLE_EQ(os->currentData().toDouble(), inEffect);
    EXPECT_DOUBLE_EQ(window->study().requestedSettings().oversampling, inEffect);
    const QString after = window->renderingPanel()->memoryLabel()->text();
    EXPECT_TRUE(after.contains(QString::number(mib, 'f', 1)) && !after.contains("once"))
        << after.toStdString();
    EXPECT_FALSE(window->progressBar()->isVisible());
}

// The preset combo says where the window came from.
// Orientation labels never under the overlay box (compare views), the last frame's
// time at rest instead of "0 fps", and Shift+R resets the view like R.
TEST_F(Workstation, LabelsClearTheOverlayRestShowsFrameTimeShiftRResets) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(32)));
    window->setCompareCount(4);
    ASSERT_TRUE(waitAllViewsReady(*window));
    for (int i = 0; i < 10; ++i) QTest::qWait(30);
    for (auto* v : window->views()) {
        const QRect box = v->overlayBox();
        ASSERT_FALSE(box.isNull());
        const QList<QRect> labels = v->orientationLabelRects();
        ASSERT_EQ(labels.size(), 4);
        for (const QRect& r : labels) EXPECT_FALSE(r.intersects(box));
        const QStringList lines = v->overlayText().split('\n');
        ASSERT_GE(lines.size(), 2);
        EXPECT_TRUE(lines[1].startsWith("frame ")) << lines[1].toStdString(); // after the title
        EXPECT_FALSE(lines[1].contains("fps")) << lines[1].toStdString();
    }
    window->setCompareCount(1);
    auto* v = window->views()[0];
    const core::ViewFrame ap =
        core::patientViewFrame(*window->study().volume(), core::PatientView::AP);
    v->setViewFrame(ap.rotated(ap.u, 0.7));
    v->setZoom(2.0);
    window->activateWindow();
    ASSERT_TRUE(QTest::qWaitForWindowActive(window.get()));
    QTest::keyClick(window.get(), Qt::Key_R, Qt::ShiftModifier);
    EXPECT_EQ(v->viewFrame().d, ap.d);
    EXPECT_EQ(v->zoom(), 1.0);
}

// The Bone preset shows the skull vault (thin bone seen edge-on), not only the
// skull base: on the Philips head phantom's lateral view the vault projects to 42 % of the range.
TEST_F(Workstation, BonePresetKeepsTheSkullVault) {
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140");
    const auto dir = test::sharedData() / "dicom/ct_phantom_philips_512x512x140";
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(dir.string()))));
    window->showPatientView(core::PatientView::Left);
    auto* preset = window->displayPanel()->presetCombo();
    preset->setCurrentIndex(preset->findData(int(ui::WindowPreset::Bone)));
    emit preset->activated(preset->currentIndex());
    auto* v = window->views()[0];
    const auto p = v->projection();
    ASSERT_TRUE(p);
    const core::DisplayWindow bone = v->window();
    const core::DisplayWindow wide = core::autoWindow(p->pixels);
    EXPECT_GT(bone.low, wide.low + 0.2 * (wide.high - wide.low)); // a bone window: air, soft
                                                                  // tissue below it
    // The vault: the first rows of the head from the top (the LEFT view has the head up).
    const int M = p->width;
    auto rowMax = [&](int r) {
        return *std::max_element(p->pixels.begin() + r * M, p->pixels.begin() + (r + 1) * M);
    };
    int top = 0;
    while (top < M && rowMax(top) < wide.low + 0.05 * (wide.high - wide.low)) ++top;
    ASSERT_LT(top + 8, M);
    for (int r = top + 2; r < top + 8; ++r)
        EXPECT_GT(bone.map(rowMax(r)), 0.1) << "row " << r - top << " of the head is black";
}

TEST_F(Workstation, PresetComboSaysWhereTheWindowCameFrom) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    auto* preset = window->displayPanel()->presetCombo();
    auto shown = [&] { return ui::WindowPreset(preset->currentData().toInt()); };
    EXPECT_EQ(shown(), ui::WindowPreset::Auto); // the auto window applied on loading
    preset->setCurrentIndex(preset->findData(int(ui::WindowPreset::Bone)));
    emit preset->activated(preset->currentIndex());
    EXPECT_EQ(shown(), ui::WindowPreset::Bone);
    window->displayPanel()->windowWidthSpin()->setValue(
        window->displayPanel()->windowWidthSpin()->value() * 0.5);
    EXPECT_EQ(shown(), ui::WindowPreset::Custom);
    // A window drag in the view is a manual change too.
    auto* view = window->views()[0];
    const QPoint c = view->rect().center();
    QTest::mousePress(view, Qt::RightButton, {}, c);
    QMouseEvent move(QEvent::MouseMove, QPointF(c + QPoint(40, 10)),
                     view->mapToGlobal(QPointF(c + QPoint(40, 10))), Qt::NoButton, Qt::RightButton,
                     Qt::NoModifier);
    emit preset->activated(preset->findData(int(ui::WindowPreset::Auto)));
    EXPECT_EQ(shown(), ui::WindowPreset::Auto);
    QApplication::sendEvent(view, &move);
    QTest::mouseRelease(view, Qt::RightButton, {}, c + QPoint(40, 10));
    EXPECT_EQ(shown(), ui::WindowPreset::Custom);
}

TEST_F(Workstation, MalformedStudyShowsTheErrorAndStaysUsable) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(32)));
    const auto bad = test::tmpDir() / "broken.mhd";
    std::ofstream(bad)
        << "NDims = 3\nDimSize = 4 4\nElementType = MET_SHORT\nElementDataFile = x.raw\n";
    QSignalSpy failed(&window->study(), &ui::StudyController::failed);
    window->openStudy(StudySource::fromPath(QString::fromStdString(bad.string())));
    ASSERT_TRUE(failed.wait(30000));
    const QString log = window->messages()->toPlainText();
    EXPECT_TRUE(log.contains("broken.mhd")) << log.toStdString();
    EXPECT_TRUE(log.contains("DimSize")) << log.toStdString();
    EXPECT_EQ(window->study().volume()->dims[0], 32);
    EXPECT_TRUE(window->views()[0]->projection().has_value());
}

// A path that does not exist says so, and only studies that opened are recent.
TEST_F(Workstation, MissingPathSaysSoAndIsNotRecent) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(32)));
    const auto missing = test::tmpDir() / "no_such_study.nii.gz";
    std::filesystem::remove(missing);
    QSignalSpy failed(&window->study(), &ui::StudyController::failed);
    window->openStudy(StudySource::fromPath(QString::fromStdString(missing.string())));
    ASSERT_TRUE(failed.wait(30000));
    const QString details = failed.first().at(1).toString();
    EXPECT_TRUE(details.contains("no_such_study.nii.gz: no such file or folder"))
        << details.toStdString();
    const QStringList recent = QSettings().value(ui::keys::kRecentStudies).toStringList();
    EXPECT_FALSE(recent.join('\n').contains("no_such_study")) << recent.join(", ").toStdString();
    FVR_REQUIRE_DATA("volumes/headsq/headsq.mhd");
    const auto real = test::sharedData() / "volumes/headsq/headsq.mhd";
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(real.string()))));
    EXPECT_EQ(QSettings().value(ui::keys::kRecentStudies).toStringList().value(0),
              QString::fromStdString(real.string()));
}

// Export dialogs never start in the study's own folder.
TEST_F(Workstation, ExportDialogsStartOutsideTheStudyFolder) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const auto dir = test::sharedData() / "dicom/ct_head_slicer_64x64x93";
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(dir.string()))));
    const QString start = MainWindow::exportFolder();
    EXPECT_NE(QDir(start).canonicalPath(),
              QDir(QString::fromStdString(dir.string())).canonicalPath());
    const QString pictures = QStandardPaths::writableLocation(QStandardPaths::PicturesLocation);
    EXPECT_TRUE(start == pictures || start == QDir::homePath()) << start.toStdString();
    // After an export, dialogs start where it went.
    const auto out = test::tmpDir() / "exports";
    std::filesystem::create_directories(out);
    QSettings().setValue(ui::keys::kLastExportFolder, QString::fromStdString(out.string()));
    EXPECT_EQ(MainWindow::exportFolder(), QString::fromStdString(out.string()));
}

// The Study panel and the title show the patient, study and series of DICOM data.
TEST_F(Workstation, StudyPanelShowsPatientStudyAndSeries) {
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140");
    const auto dir = test::sharedData() / "dicom/ct_phantom_philips_512x512x140";
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(dir.string()))));
    const auto scan = core::scanDicomFolder(dir);
    ASSERT_EQ(scan.series.size(), 1u);
    const auto& s = scan.series[0];
    ASSERT_FALSE(s.patientName.empty());
    const QString panel = window->studyPanel()->text();
    EXPECT_TRUE(panel.contains("Patient: ")) << panel.toStdString();
    EXPECT_TRUE(panel.contains("2015-02-06")) << panel.toStdString();
    EXPECT_TRUE(panel.contains(QString::fromStdString(s.description).toHtmlEscaped()))
        << panel.toStdString();
    EXPECT_TRUE(panel.contains("CT")) << panel.toStdString();
    EXPECT_TRUE(window->windowTitle().contains(QString::fromStdString(s.description)))
        << window->windowTitle().toStdString();
    // A volume file has no such lines.
    FVR_REQUIRE_DATA("volumes/headsq/headsq.mhd");
    const auto mhd = test::sharedData() / "volumes/headsq/headsq.mhd";
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(mhd.string()))));
    EXPECT_FALSE(window->studyPanel()->text().contains("Patient: "));
    EXPECT_TRUE(window->windowTitle().contains("headsq.mhd"));
}

// A file without orientation says which one is assumed: Study panel, Messages and
// the orientation labels; a file with one does not.
TEST_F(Workstation, AssumedOrientationIsSaid) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    const auto dir = test::sharedData() / "volumes/body_ct_hu_3mm";
    ASSERT_TRUE(openAndWait(
        *window, StudySource::fromPath(QString::fromStdString((dir / "example_ct.mhd").string()))));
    EXPECT_TRUE(window->studyPanel()->text().contains("states no orientation"));
    EXPECT_TRUE(window->messages()->toPlainText().contains("states no orientation"));
    for (const QString& l : window->views()[0]->orientationLabels())
        EXPECT_TRUE(l.endsWith("(assumed)")) << l.toStdString();
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(
                                         (dir / "example_ct.nii.gz").string()))));
    EXPECT_FALSE(window->studyPanel()->text().contains("states no orientation"));
    const QStringList labels = window->views()[0]->orientationLabels();
    EXPECT_EQ(labels, (QStringList{"R", "L", "S", "I"})); // AP view of a stated orientation
}

TEST_F(Workstation, OpensRealVolumeFile) {
    FVR_REQUIRE_DATA("volumes/headsq/headsq.mhd");
    const auto path = test::sharedData() / "volumes/headsq/headsq.mhd";
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(path.string()))));
    EXPECT_EQ(window->study().volume()->dims, (core::Dims3{64, 64, 93}));
    EXPECT_GT(test::compare(window->views()[0]->projection()->pixels,
                            cpuReference(*window, *window->views()[0]).pixels)
                  .psnr,
              90.0);
}

// The values follow the user, not the previous study. An MR study integrates raw
// values (not HU); the CT opened next gets attenuation again, also after another panel change.
TEST_F(Workstation, ValuesDoNotCarryOverFromOneStudyToTheNext) {
    FVR_REQUIRE_DATA("volumes/mr_head_mhd/HeadMRVolume.mhd");
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.nii.gz");
    const auto mr = test::sharedData() / "volumes/mr_head_mhd/HeadMRVolume.mhd";
    const auto ct = test::sharedData() / "volumes/body_ct_hu_3mm/example_ct.nii.gz";
    auto open = [&](const std::filesystem::path& p) {
        return openAndWait(*window, StudySource::fromPath(QString::fromStdString(p.string())));
    };
    auto* values = window->renderingPanel()->valuesCombo();
    ASSERT_TRUE(open(mr));
    EXPECT_EQ(window->study().spectrumSettings().mapping, core::ValueMapping::Raw);
    EXPECT_EQ(core::ValueMapping(values->currentData().toInt()), core::ValueMapping::Raw);
    ASSERT_TRUE(open(ct));
    EXPECT_EQ(window->study().spectrumSettings().mapping, core::ValueMapping::Mu);
    EXPECT_EQ(core::ValueMapping(values->currentData().toInt()), core::ValueMapping::Mu);
    // Attenuation line integrals: positive, with a window inside their range.
    const auto p = window->views()[0]->projection();
    ASSERT_TRUE(p.has_value());
    const auto [lo, hi] = std::minmax_element(p->pixels.begin(), p->pixels.end());
    EXPECT_GE(*lo, 0.0f);
    const auto w = window->views()[0]->window();
    EXPECT_GE(w.low, 0.0);
    EXPECT_LE(w.high, double(*hi) * 1.001);
    EXPECT_GT(w.high, w.low);

    // MR again, a panel change while its raw values are shown, then the CT: attenuation.
    ASSERT_TRUE(open(mr));
    ASSERT_TRUE(waitSpectrum(*window, [&] {
        auto* os = window->renderingPanel()->oversamplingCombo();
        os->setCurrentIndex(os->findData(1.5));
    }));
    EXPECT_EQ(window->study().spectrumSettings().mapping, core::ValueMapping::Raw);
    ASSERT_TRUE(open(ct));
    EXPECT_EQ(window->study().spectrumSettings().mapping, core::ValueMapping::Mu);
    // Asking for attenuation on the MR changes nothing in effect, and the panel says so.
    ASSERT_TRUE(open(mr));
    values->setCurrentIndex(values->findData(int(core::ValueMapping::Mu)));
    EXPECT_FALSE(window->study().busy());
    EXPECT_EQ(window->study().spectrumSettings().mapping, core::ValueMapping::Raw);
    EXPECT_EQ(core::ValueMapping(values->currentData().toInt()), core::ValueMapping::Raw);
}

TEST_F(Workstation, OpensDicomFolder) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const auto path = test::sharedData() / "dicom/ct_head_slicer_64x64x93";
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(path.string()))));
    EXPECT_EQ(window->study().volume()->dims, (core::Dims3{64, 64, 93}));
}

TEST_F(Workstation, AccuracyReadoutAgainstRayCasting) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    QSignalSpy measured(window.get(), &MainWindow::accuracyMeasured);
    window->measureAccuracy();
    ASSERT_TRUE(measured.wait(60000));
    const double psnr = measured.first().at(0).toDouble();
    std::printf("[ui] default setting vs ray casting: %.2f dB\n", psnr);
    EXPECT_GT(psnr, 35.0); // Kaiser-Bessel, deapodized, 1.25x against trilinear ray casting
    EXPECT_TRUE(window->messages()->toPlainText().contains("PSNR"));
}

TEST_F(Workstation, XRayPanelTransmissionDepthCueAndFilters) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    ui::ProjectionView* v = window->views()[0];
    const auto L = *v->projection(); // line integrals (mu)

    // Beer-Lambert: the film look by default, window on the intensity.
    window->xrayPanel()->energySpin()->setValue(60.0);
    window->xrayPanel()->exposureSpin()->setValue(1.5);
    window->xrayPanel()->outputCombo()->setCurrentIndex(1);
    const double mu = core::waterAttenuationPerMm(60.0);
    EXPECT_TRUE(v->window().transmission.active());
    EXPECT_NEAR(v->window().transmission.muWaterPerMm, mu, 1e-12);
    EXPECT_DOUBLE_EQ(v->window().transmission.exposure, 1.5);
    EXPECT_TRUE(v->window().invert);
    // The exported float image is exposure exp(-mu_water L) of the line integrals.
    const auto npy = test::tmpDir() / "ui_transmission.npy";
    ASSERT_TRUE(window->exportProjection(QString::fromStdString(npy.string())));
    std::vector<std::int64_t> shape;
    const auto I = core::readNpy(npy, shape);
    ASSERT_EQ(I.size(), L.pixels.size());
    double worst = 0;
    for (std::size_t i = 0; i < I.size(); ++i)
        worst = std::max(worst, std::abs(I[i] - 1.5 * std::exp(-mu * L.pixels[i])));
    EXPECT_LT(worst, 1.5e-5);
    // The screen shows a radiograph: dark air (film exposed), bright skull.
    const QImage shot = v->screenshot();
    int dark = 0, bright = 0;
    for (int y = 0; y < shot.height(); y += 4)
        for (int x = 0; x < shot.width(); x += 4) {
            dark += qGray(shot.pixel(x, y)) < 40;
            bright += qGray(shot.pixel(x, y)) > 200;
        }
    EXPECT_GT(dark, 50);
    EXPECT_GT(bright, 20);
    // Leaving a difference comparison keeps the transmission on every view.
    window->setCompareCount(2);
    window->setDifferenceMode(true);
    window->setDifferenceMode(false);
    for (auto* view : window->views()) EXPECT_TRUE(view->window().transmission.active());
    window->setCompareCount(1);
    v = window->views()[0];
    // Raw values have no transmission: the output falls back to line integrals.
    ASSERT_TRUE(waitSpectrum(*window, [&] {
        window->renderingPanel()->valuesCombo()->setCurrentIndex(
            window->renderingPanel()->valuesCombo()->findData(int(core::ValueMapping::Raw)));
    }));
    // (the compare round trip above started a preprocessing of its own: wait for the raw one)
    ASSERT_TRUE(QTest::qWaitFor(
        [&] {
            return !window->study().busy() &&
                   window->study().spectrum()->mapping == core::ValueMapping::Raw;
        },
        60000));
    QApplication::processEvents();
    EXPECT_EQ(window->xrayPanel()->outputCombo()->currentIndex(), 0);
    EXPECT_FALSE(v->window().transmission.active())
        << v->window().low << " " << v->window().high << " views " << window->views().size()
        << " same " << (v == window->views()[0]) << "\n"
        << window->messages()->toPlainText().toStdString();
    // Transmission from raw values switches to mu; the window follows the new image (log exposure
    // of a few decades, not the raw spectrum's range).
    ASSERT_TRUE(
        waitSpectrum(*window, [&] { window->xrayPanel()->outputCombo()->setCurrentIndex(1); }));
    QApplication::processEvents();
    EXPECT_EQ(window->study().spectrum()->mapping, core::ValueMapping::Mu)
        << window->messages()->toPlainText().toStdString();
    EXPECT_GT(v->window().low, -10.0);
    EXPECT_LE(v->window().high, 0.01);
    EXPECT_GT(v->window().high - v->window().low, 0.2);
    window->xrayPanel()->outputCombo()->setCurrentIndex(0);
    ASSERT_TRUE(waitSpectrum(*window, [&] {
        window->renderingPanel()->valuesCombo()->setCurrentIndex(
            window->renderingPanel()->valuesCombo()->findData(int(core::ValueMapping::MuBone)));
    }));
    EXPECT_EQ(window->study().spectrum()->mapping, core::ValueMapping::MuBone);

    // The panel is usable: every control visible inside the dock (nothing clipped).
    auto* dock = window->findChild<QDockWidget*>("dock.xray");
    ASSERT_NE(dock, nullptr);
    dock->raise();
    QApplication::processEvents();
    for (QWidget* c : {static_cast<QWidget*>(window->xrayPanel()->outputCombo()),
                       static_cast<QWidget*>(window->xrayPanel()->bandLimitSpin())}) {
        EXPECT_TRUE(c->isVisible());
        const QRect r(c->mapTo(dock, QPoint(0, 0)), c->size());
        EXPECT_TRUE(dock->rect().contains(r)) << "clipped control";
    }
    dock->grab().save(QString::fromStdString((test::tmpDir() / "xray_dock.png").string()));

    // Depth cueing and filters: every frame equals the CPU renderer with the same parameters.
    window->xrayPanel()->depthCueSpin()->setValue(60);
    window->xrayPanel()->sharpenSpin()->setValue(1.5);
    window->xrayPanel()->sharpenRadiusSpin()->setValue(3.0);
    window->xrayPanel()->bandLimitSpin()->setValue(0.4);
    EXPECT_DOUBLE_EQ(v->effects().depthCue, 0.6);
    EXPECT_EQ(v->effects().filter, (core::SliceFilter{1.5, 3.0, 0.4}));
    core::CpuFourierRenderer r(window->study().spectrum(), 2);
    const auto& vol = *window->study().volume();
    const int M = v->settings().size;
    core::RenderParams p{v->viewFrame(),
                         {M, core::defaultPixelSize(vol.dims, vol.spacing, M)},
                         v->settings().kernel};
    EXPECT_TRUE(v->effects().clip); // on by default
    p.clipToVolume = v->effects().clip;
    EXPECT_EQ(v->settings().voxelModel, core::VoxelModel::Trilinear); // the default voxel model
    EXPECT_TRUE(v->effects().nonNegative);
    p.voxelModel = core::VoxelModel::Trilinear;
    p.nonNegative = true;
    const auto plain = r.render(p);
    p.depthCue = 0.6;
    p.filter = {1.5, 3.0, 0.4};
    const auto want = r.render(p);
    const auto got = *v->projection();
    EXPECT_GT(test::compare(got.pixels, want.pixels).psnr, 90.0);
    EXPECT_LT(test::compare(plain.pixels, want.pixels).psnr, 40.0); // the effects change the image
}

TEST_F(Workstation, NewFramesMapTheDisplayInTheLastGpuPass) {
    // Once a window is set, a new GPU frame writes the display texture in the last pass of the
    // inverse transform: the view shows the same pixels as the separate display pass does after a
    // window round trip, and the overlay's stage times say so.
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    ui::ProjectionView* v = window->views()[0];
    if (!v->usingGpu()) GTEST_SKIP() << "no GPU renderer: " << v->backendNotice().toStdString();
    v->setOverlayVisible(false);
    const core::DisplayWindow w = v->window();
    v->setViewFrame(v->viewFrame().rotated({0.2, 0.9, 0.3}, 0.4));
    const QImage fused = v->screenshot();
    EXPECT_TRUE(v->frameStats().fused);
    EXPECT_TRUE(v->frameStats().displayFused);
    const int frames = v->framesRendered();
    core::DisplayWindow other = w;
    other.high = w.low + 0.5 * (w.high - w.low);
    v->setWindow(other);
    const QImage narrower = v->screenshot();
    v->setWindow(w);
    const QImage separate = v->screenshot();
    EXPECT_EQ(v->framesRendered(), frames); // window changes do not render again
    EXPECT_EQ(fused, separate);
    EXPECT_NE(fused, narrower);
    std::set<int> grays;
    for (int y = 0; y < fused.height(); y += 3)
        for (int x = 0; x < fused.width(); x += 3) grays.insert(qGray(fused.pixel(x, y)));
    EXPECT_GT(grays.size(), 40u); // a projection, not a blank view
}

TEST_F(Workstation, ProgressiveRefinementHoldsTheTargetWhileDragging) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    window->renderingPanel()->targetFpsSpin()->setValue(30);
    auto* v = window->views()[0];
    ASSERT_EQ(v->settings().size, 512);
    v->setSimulatedRenderCost(150.0); // a machine far too slow for 30 fps at full quality
    v->update();
    QTest::qWait(50);
    const QPoint c(v->width() / 2, v->height() / 2);
    QTest::mousePress(v, Qt::LeftButton, Qt::NoModifier, c);
    EXPECT_TRUE(v->progressive().interacting());
    for (int i = 1; i <= 6; ++i) {
        const int before = v->framesRendered();
        QTest::mouseMove(v, c + QPoint(6 * i, 2 * i));
        ASSERT_TRUE(QTest::qWaitFor([&] { return v->framesRendered() > before; }, 20000));
    }
    QTest::qWait(20);
    EXPECT_GT(v->displayedLevel(), 0);
    EXPECT_LT(v->displayedSize(), 512);
    std::printf("[ui] while dragging: level %d, %d x %d\n", v->displayedLevel(), v->displayedSize(),
                v->displayedSize());
    // Letting go brings the full-quality frame back.
    const int before = v->framesRendered();
    QTest::mouseRelease(v, Qt::LeftButton, Qt::NoModifier, c + QPoint(36, 12));
    ASSERT_TRUE(QTest::qWaitFor(
        [&] { return v->framesRendered() > before && v->displayedLevel() == 0; }, 20000));
    EXPECT_EQ(v->displayedSize(), 512);
    EXPECT_FALSE(v->progressive().interacting());
    EXPECT_EQ(v->projection()->width, 512);

    // Off: the drag stays at full quality however slow.
    window->renderingPanel()->targetFpsSpin()->setValue(0);
    QTest::mousePress(v, Qt::LeftButton, Qt::NoModifier, c);
    const int b2 = v->framesRendered();
    QTest::mouseMove(v, c + QPoint(10, 0));
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->framesRendered() > b2; }, 20000));
    QTest::qWait(20);
    EXPECT_EQ(v->displayedLevel(), 0);
    QTest::mouseRelease(v, Qt::LeftButton, Qt::NoModifier, c + QPoint(10, 0));
}

// The frame rate held is the one the user sees (the wall clock from a drag step to
// the frame on screen, display and every synchronised view included), also with 4 views: all of
// them follow the drag, at a lower level, within the budget.
TEST_F(Workstation, ProgressiveRefinementHoldsTheWallClockTargetInFourViews) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    window->renderingPanel()->targetFpsSpin()->setValue(10); // 100 ms per frame
    window->setCompareCount(4);
    ASSERT_TRUE(waitAllViewsReady(*window));
    const auto views = window->views();
    // Each view alone at full quality costs 160 ms (in real time, outside the stage timers):
    // the 4 views together 640 ms. At 128² they cost 40 ms together.
    for (auto* v : views) v->setSimulatedRenderCost(160.0);
    QTest::qWait(100);
    auto* v0 = views[0];
    const QPoint c(v0->width() / 2, v0->height() / 2);
    QTest::mousePress(v0, Qt::LeftButton, Qt::NoModifier, c);
    std::vector<double> wall;
    for (int i = 1; i <= 14; ++i) {
        std::vector<int> before;
        for (auto* v : views) before.push_back(v->framesRendered());
        QTest::mouseMove(v0, c + QPoint(4 * i, i));
        for (std::size_t k = 0; k < views.size(); ++k)
            ASSERT_TRUE(
                QTest::qWaitFor([&] { return views[k]->framesRendered() > before[k]; }, 20000))
                << "view " << k + 1 << " did not follow the drag at step " << i;
        QTest::qWait(10); // the window's frame reaches the screen
        wall.push_back(v0->frameStats().wallMs);
    }
    for (auto* v : views) {
        EXPECT_TRUE(v->progressive().interacting());
        EXPECT_GT(v->displayedLevel(), 0);
    }
    // The last frames are within the budget (the stage timers alone, as before, saw 10 ms at
    // full quality and kept it: 640 ms per frame).
    const double last = *std::min_element(wall.end() - 3, wall.end());
    std::printf("[ui] 4 views dragging: level %d (%d²), wall %.0f ms (first %.0f ms)\n",
                v0->displayedLevel(), v0->displayedSize(), last, wall.front());
    EXPECT_LT(last, 150.0); // the budget, with room for a loaded machine's composition
    QTest::mouseRelease(v0, Qt::LeftButton, Qt::NoModifier, c + QPoint(56, 14));
    ASSERT_TRUE(QTest::qWaitFor(
        [&] {
            return std::all_of(views.begin(), views.end(),
                               [](auto* v) { return v->displayedLevel() == 0; });
        },
        20000));
}

TEST_F(Workstation, VoxelModelControlChangesTheImageNotTheSpectrum) {
    // The body CT ends inside the body at the top and the bottom: the band-limited model rings
    // there (stripes, negative line integrals); the default trilinear model does not.
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    const auto path = test::sharedData() / "volumes/body_ct_hu_3mm/example_ct.mhd";
    ASSERT_TRUE(openAndWait(*window, StudySource::fromPath(QString::fromStdString(path.string()))));
    ui::ProjectionView* v = window->views()[0];
    EXPECT_EQ(core::VoxelModel(window->renderingPanel()->voxelModelCombo()->currentData().toInt()),
              core::VoxelModel::Trilinear);
    const auto spectrum = window->study().spectrum();
    const auto trilinear = *v->projection();
    EXPECT_EQ(core::mostNegativeFraction(trilinear.pixels), 0.0);

    window->renderingPanel()->nonNegativeCheck()->setChecked(false);
    EXPECT_FALSE(v->effects().nonNegative);
    auto* model = window->renderingPanel()->voxelModelCombo();
    model->setCurrentIndex(model->findData(int(core::VoxelModel::BandLimited)));
    EXPECT_EQ(v->settings().voxelModel, core::VoxelModel::BandLimited);
    EXPECT_EQ(window->study().spectrum(), spectrum); // the same spectrum: no preprocessing
    const auto band = *v->projection();
    EXPECT_GT(test::compare(band.pixels, cpuReference(*window, *v).pixels).psnr, 90.0);
    EXPECT_LT(test::compare(band.pixels, trilinear.pixels).psnr, 50.0); // a different image
    EXPECT_LT(core::mostNegativeFraction(band.pixels), -0.02); // the ringing
    EXPECT_EQ(QSettings().value("render/voxelModel").toString(), QString("bandlimited"));

    // The accuracy readout says which ray caster it compares with.
    QSignalSpy measured(window.get(), &MainWindow::accuracyMeasured);
    window->measureAccuracy();
    ASSERT_TRUE(measured.wait(60000));
    const double bandPsnr = measured.takeFirst().at(0).toDouble();
    EXPECT_TRUE(window->messages()->toPlainText().contains("which has no ray caster"));
    model->setCurrentIndex(model->findData(int(core::VoxelModel::Trilinear)));
    window->measureAccuracy();
    ASSERT_TRUE(measured.wait(60000));
    const double triPsnr = measured.takeFirst().at(0).toDouble();
    std::printf("[ui] body CT, view 1 against trilinear ray casting: band-limited %.2f dB, "
                "trilinear %.2f dB\n",
                bandPsnr, triPsnr);
    EXPECT_GT(triPsnr, bandPsnr + 5.0);
    EXPECT_TRUE(window->messages()->toPlainText().contains(
        "trilinear ray casting (step s/4, one ray per pixel)"));

    // The pixel aperture reaches the frame (parameters built here, independently of the view).
    window->renderingPanel()->pixelApertureCheck()->setChecked(true);
    const auto& vol = *window->study().volume();
    core::RenderParams p{
        v->viewFrame(),
        {v->settings().size, core::defaultPixelSize(vol.dims, vol.spacing, v->settings().size)},
        v->settings().kernel};
    p.voxelModel = core::VoxelModel::Trilinear;
    p.pixelAperture = true;
    p.clipToVolume = true;
    core::CpuFourierRenderer cpu(window->study().spectrum(), 2);
    EXPECT_GT(test::compare(v->projection()->pixels, cpu.render(p).pixels).psnr, 90.0);
    EXPECT_TRUE(QSettings().value("render/pixelAperture").toBool());
    EXPECT_FALSE(QSettings().value("render/nonNegative").toBool());
    window->renderingPanel()->pixelApertureCheck()->setChecked(false);

    // Compare mode: each view has its own voxel model ("Applies to"), side by side; changing it
    // for all views keeps each view's kernel.
    ASSERT_TRUE(
        waitSpectrum(*window, [&] { window->setCompareCount(2); })); // view 2: its own spectrum
    const core::Kernel k0 = window->views()[0]->settings().kernel,
                       k1 = window->views()[1]->settings().kernel;
    ASSERT_NE(k0, k1);
    window->renderingPanel()->appliesToCombo()->setCurrentIndex(2); // view 2
    model->setCurrentIndex(model->findData(int(core::VoxelModel::BandLimited)));
    EXPECT_EQ(window->views()[0]->settings().voxelModel, core::VoxelModel::Trilinear);
    EXPECT_EQ(window->views()[1]->settings().voxelModel, core::VoxelModel::BandLimited);
    EXPECT_EQ(QSettings().value("render/voxelModel").toString(), QString("trilinear")); // view 1's
    window->renderingPanel()->appliesToCombo()->setCurrentIndex(
        1); // the panel shows view 1's model again
    EXPECT_EQ(core::VoxelModel(model->currentData().toInt()), core::VoxelModel::Trilinear);
    window->renderingPanel()->appliesToCombo()->setCurrentIndex(0); // all views
    model->setCurrentIndex(model->findData(int(core::VoxelModel::BSpline)));
    for (auto* view : window->views())
        EXPECT_EQ(view->settings().voxelModel, core::VoxelModel::BSpline);
    EXPECT_EQ(window->views()[0]->settings().kernel, k0);
    EXPECT_EQ(window->views()[1]->settings().kernel, k1);
}

TEST_F(Workstation, PanelsRoundTripTheirValuesWithoutSignals) {
    ui::RenderingPanel rendering;
    ui::RenderingPanel::Values r;
    r.kernel = core::Kernel::Linear;
    r.size = 256;
    r.voxelModel = core::VoxelModel::BSpline;
    r.transform = core::TransformKind::Fht;
    r.oversampling = 1.5;
    r.mapping = core::ValueMapping::MuBone;
    r.deapodize = false;
    r.targetFps = 12;
    r.pixelAperture = true;
    r.clip = false;
    r.nonNegative = false;
    ASSERT_NE(r, rendering.values());
    QSignalSpy renderingChanged(&rendering, &ui::RenderingPanel::changed);
    rendering.setValues(r);
    EXPECT_EQ(rendering.values(), r);
    EXPECT_EQ(renderingChanged.count(), 0); // setValues never renders again by itself

    ui::DisplayPanel display;
    const ui::DisplayPanel::Values d{2.5, -1.25, true};
    QSignalSpy displayChanged(&display, &ui::DisplayPanel::changed);
    display.setValues(d);
    EXPECT_EQ(display.values(), d);
    EXPECT_EQ(displayChanged.count(), 0);
    // Presets are chosen by their id, not their (translated) label.
    std::vector<ui::WindowPreset> asked;
    QObject::connect(&display, &ui::DisplayPanel::presetRequested,
                     [&](ui::WindowPreset p) { asked.push_back(p); });
    emit display.presetCombo()->activated(
        display.presetCombo()->findData(int(ui::WindowPreset::Bone)));
    EXPECT_EQ(asked, std::vector<ui::WindowPreset>{ui::WindowPreset::Bone});

    ui::XrayPanel xray;
    const ui::XrayPanel::Values x{ui::XrayOutput::Transmission, 90.0, 2.5, 40, 1.25, 2.0, 0.5};
    QSignalSpy xrayChanged(&xray, &ui::XrayPanel::changed);
    EXPECT_FALSE(xray.energySpin()->isEnabled()); // line integrals: no beam
    xray.setValues(x);
    EXPECT_EQ(xray.values(), x);
    EXPECT_EQ(xrayChanged.count(), 0);
    EXPECT_TRUE(xray.energySpin()->isEnabled());
    EXPECT_TRUE(xray.exposureSpin()->isEnabled());
    EXPECT_NEAR(xray.transmission().muWaterPerMm, core::waterAttenuationPerMm(90.0), 1e-12);
    EXPECT_EQ(xray.sliceFilter(), (core::SliceFilter{1.25, 2.0, 0.5}));
    xray.setOutput(ui::XrayOutput::LineIntegrals);
    EXPECT_FALSE(xray.transmission().active());
    EXPECT_FALSE(xray.exposureSpin()->isEnabled());
    EXPECT_EQ(xrayChanged.count(), 0);
}

// One source of truth: the panels show the settings model, a user's edit lands in it, and a
// change of the model (from anywhere) is what the window acts on.
TEST_F(Workstation, PanelsShowTheSettingsModelAndTheWindowActsOnIt) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    ui::SettingsModel& model = window->settings();
    auto* rp = window->renderingPanel();
    ASSERT_TRUE(waitSpectrum(*window, [&] {
        rp->oversamplingCombo()->setCurrentIndex(rp->oversamplingCombo()->findData(1.5));
    }));
    EXPECT_EQ(model.rendering().oversampling, 1.5); // the user's edit is in the model
    EXPECT_EQ(window->study().spectrumSettings().oversampling, 1.5);

    ui::RenderingPanel::Values r = model.rendering();
    r.mapping = core::ValueMapping::Raw;
    r.clip = false;
    ASSERT_TRUE(waitSpectrum(*window, [&] { model.setRendering(r); }));
    EXPECT_EQ(core::ValueMapping(rp->valuesCombo()->currentData().toInt()),
              core::ValueMapping::Raw);
    EXPECT_FALSE(rp->clipCheck()->isChecked());
    EXPECT_EQ(rp->values(), model.rendering());
    EXPECT_EQ(window->study().spectrumSettings().mapping, core::ValueMapping::Raw);
    EXPECT_FALSE(window->views()[0]->effects().clip);

    ui::XrayPanel::Values x = model.xray();
    x.depthCuePercent = 30;
    model.setXray(x);
    EXPECT_EQ(window->xrayPanel()->depthCueSpin()->value(), 30);
    EXPECT_DOUBLE_EQ(window->views()[0]->effects().depthCue, 0.3);
    EXPECT_EQ(window->xrayPanel()->values(), model.xray());
}

TEST_F(Workstation, PanelSettingsPersistForTheNextWindow) {
    // Changed like a user does (no study open), then read back by a fresh window.
    auto* rp = window->renderingPanel();
    auto* xp = window->xrayPanel();
    ui::RenderingPanel::Values defaults;
    defaults.softwareGpu = true; // the fixture's (the GPU path under test)
    EXPECT_EQ(rp->values(), defaults); // no other settings saved: the defaults
    EXPECT_EQ(xp->values(), ui::XrayPanel::Values{});
    auto pick = [](QComboBox* c, const QVariant& data) { c->setCurrentIndex(c->findData(data)); };
    pick(rp->kernelCombo(), int(core::Kernel::Linear));
    pick(rp->sizeCombo(), 256);
    pick(rp->voxelModelCombo(), int(core::VoxelModel::BSpline));
    pick(rp->transformCombo(), int(core::TransformKind::Fht));
    pick(rp->oversamplingCombo(), 1.5);
    pick(rp->valuesCombo(), int(core::ValueMapping::MuBone));
    rp->deapodizeCheck()->setChecked(false);
    rp->targetFpsSpin()->setValue(12);
    rp->pixelApertureCheck()->setChecked(true);
    rp->clipCheck()->setChecked(false);
    rp->nonNegativeCheck()->setChecked(false);
    xp->energySpin()->setValue(90.0);
    xp->exposureSpin()->setValue(2.5);
    xp->depthCueSpin()->setValue(40);
    xp->sharpenSpin()->setValue(1.25);
    xp->sharpenRadiusSpin()->setValue(2.0);
    xp->bandLimitSpin()->setValue(0.5);
    xp->outputCombo()->setCurrentIndex(
        xp->outputCombo()->findData(int(ui::XrayOutput::Transmission)));
    window->displayPanel()->invertCheck()->setChecked(true);
    const auto rendering = rp->values();
    const auto xray = xp->values();
    ASSERT_EQ(rendering,
              (ui::RenderingPanel::Values{core::Kernel::Linear, 256, core::VoxelModel::BSpline,
                                          core::TransformKind::Fht, 1.5, core::ValueMapping::MuBone,
                                          false, 12, true, false, false, true}));
    ASSERT_EQ(xray,
              (ui::XrayPanel::Values{ui::XrayOutput::Transmission, 90.0, 2.5, 40, 1.25, 2.0, 0.5}));
    window.reset();

    // The keys users' saved settings already hold; choices by name.
    const QSettings s;
    EXPECT_EQ(s.value("render/kernel").toString(), QString("linear"));
    EXPECT_EQ(s.value("render/transform").toString(), QString("fht"));
    EXPECT_EQ(s.value("render/values").toString(), QString("mu-bone"));
    EXPECT_EQ(s.value("render/size").toInt(), 256);
    EXPECT_EQ(s.value("render/voxelModel").toString(), QString("bspline"));
    EXPECT_EQ(s.value("render/oversampling").toDouble(), 1.5);
    EXPECT_FALSE(s.value("render/deapodize").toBool());
    EXPECT_EQ(s.value("render/targetFps").toInt(), 12);
    EXPECT_EQ(s.value("xray/output").toString(), QString("transmission"));
    EXPECT_EQ(s.value("xray/energyKeV").toDouble(), 90.0);
    EXPECT_EQ(s.value("xray/sharpenRadius").toDouble(), 2.0);
    EXPECT_TRUE(s.value("display/invert").toBool());

    MainWindow fresh;
    EXPECT_EQ(fresh.renderingPanel()->values(), rendering);
    EXPECT_EQ(fresh.xrayPanel()->values(), xray);
    EXPECT_TRUE(fresh.displayPanel()->values().invert);
    EXPECT_TRUE(fresh.currentTransmission().active());
    EXPECT_EQ(fresh.views()[0]->settings(),
              (ui::ViewSettings{core::Kernel::Linear, 256, core::VoxelModel::BSpline}));
    EXPECT_EQ(fresh.views()[0]->effects().filter, (core::SliceFilter{1.25, 2.0, 0.5}));
}

// The polychromatic output renders the material spectra (prepared once, in the
// background) through the spectral response; kVp, detector and what is shown re-render without
// preprocessing again.
TEST_F(Workstation, PolychromaticOutputRendersTheMaterialsWithoutPreprocessingAgain) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    ui::ProjectionView* v = window->views()[0];
    const auto mono = *v->projection(); // mm of water, the view's own (gridding-corrected) kernel
    auto* x = window->xrayPanel();
    x->kvpSpin()->setValue(70.0);
    x->outputCombo()->setCurrentIndex(
        x->outputCombo()->findData(int(ui::XrayOutput::Polychromatic)));
    auto polyReady = [&] {
        return v->polychromatic() && !v->polychromatic()->spectra.empty() && v->showsCurrentFrame();
    };
    ASSERT_TRUE(QTest::qWaitFor(polyReady, 60000))
        << window->messages()->toPlainText().toStdString();
    const auto source = v->polychromatic();
    ASSERT_EQ(source->spectra.size(), 3u);
    const auto shown = *v->projection(); // -ln(I/I0)
    // The fixture's views render on the (software) GPU: so does the spectral sum, in one compute
    // pass over the material frames (no read-back per material).
    EXPECT_EQ(v->polychromaticOnGpu(), v->usingGpu());
    std::printf("[ui-poly] spectral sum on the %s\n", v->polychromaticOnGpu() ? "GPU" : "CPU");
    // The reference: the same material spectra rendered here, the exact double sum per pixel.
    const core::RenderParams params = v->renderParams(v->settings().size, v->settings().kernel);
    std::vector<core::ProjectionImage> rhoL;
    for (const auto& s : source->spectra)
        rhoL.push_back(core::CpuFourierRenderer(s, 2).render(params));
    double worst = 0.0, peak = 0.0;
    for (std::size_t p = 0; p < shown.pixels.size(); ++p) {
        const double d[3] = {0.1 * rhoL[0].pixels[p], 0.1 * rhoL[1].pixels[p],
                             0.1 * rhoL[2].pixels[p]};
        const double ref = -std::log(source->response->exact(d));
        worst = std::max(worst, std::abs(shown.pixels[p] - ref));
        peak = std::max(peak, ref);
    }
    EXPECT_GT(peak, 1.0);
    EXPECT_LT(worst, 1e-3);
    // The materials are prepared for the view's kernel (gridding-corrected like its own
    // spectrum) and keep the attenuation at 70 keV: sum_m mu_m rhoL_m = mu_water x line integral.
    EXPECT_EQ(source->spectra[0]->deapodizedFor, v->spectrum()->deapodizedFor);
    const char* names[3] = {"Air, Dry (near sea level)", "Tissue, Soft (ICRP)",
                            "Bone, Cortical (ICRP)"};
    double monoWorst = 0.0, monoPeak = 0.0;
    for (std::size_t p = 0; p < mono.pixels.size(); ++p) {
        double a = 0.0;
        for (int m = 0; m < 3; ++m)
            a += core::massAttenuation(names[m], 70.0) * 0.1 * rhoL[std::size_t(m)].pixels[p];
        const double b = core::massAttenuation("Water, Liquid", 70.0) * mono.pixels[p] / 10.0;
        monoWorst = std::max(monoWorst, std::abs(a - b));
        monoPeak = std::max(monoPeak, b);
    }
    EXPECT_LT(monoWorst, 1e-2 * monoPeak); // the clamp at 0 acts per material there
    // A higher kVp: the same spectra (no preprocessing), less attenuation everywhere.
    x->kvpSpin()->setValue(120.0);
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->polychromatic() != source && polyReady(); }));
    EXPECT_EQ(v->polychromatic()->spectra, source->spectra);
    const auto hard = *v->projection();
    for (std::size_t p = 0; p < shown.pixels.size(); ++p)
        if (shown.pixels[p] > 0.5f) {
            ASSERT_LT(hard.pixels[p], shown.pixels[p]) << p;
        }
    // The material view: soft tissue's mass thickness in g/cm^2.
    x->showCombo()->setCurrentIndex(x->showCombo()->findData(1));
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->polychromatic()->show == 1 && polyReady(); }));
    const auto soft = *v->projection();
    double softWorst = 0.0;
    for (std::size_t p = 0; p < soft.pixels.size(); ++p)
        softWorst =
            std::max(softWorst, double(std::abs(soft.pixels[p] - 0.1f * rhoL[1].pixels[p])));
    EXPECT_LT(softWorst, 1e-4);
    // Quantum noise on -ln(I/I0) (on the GPU view: I/I0 read back once, the noise drawn on the
    // CPU): z = (noisy - I) / sqrt(I / quanta) has mean 0 and variance 1 (Poisson in quanta).
    x->showCombo()->setCurrentIndex(x->showCombo()->findData(-1));
    x->noiseSpin()->setValue(0.05);
    ASSERT_TRUE(QTest::qWaitFor([&] {
        return v->polychromatic()->show == -1 && v->polychromatic()->noise.active() && polyReady();
    }));
    EXPECT_EQ(v->polychromaticOnGpu(), v->usingGpu());
    const auto noisy = *v->projection();
    core::NoiseModel n = v->polychromatic()->noise;
    n.pixelAreaMm2 = params.image.pixelSize * params.image.pixelSize;
    const double quanta = core::unattenuatedQuanta(*v->polychromatic()->response, n);
    double zSum = 0.0, z2Sum = 0.0;
    for (std::size_t p = 0; p < noisy.pixels.size(); ++p) {
        const double d[3] = {0.1 * rhoL[0].pixels[p], 0.1 * rhoL[1].pixels[p],
                             0.1 * rhoL[2].pixels[p]};
        const double i = v->polychromatic()->response->exact(d);
        const double z = (std::exp(-double(noisy.pixels[p])) - i) / std::sqrt(i / quanta);
        zSum += z;
        z2Sum += z * z;
    }
    const double count = double(noisy.pixels.size());
    std::printf("[ui-poly] noise: %.0f quanta per pixel, z mean %.4f, variance %.4f\n", quanta,
                zSum / count, z2Sum / count);
    EXPECT_NEAR(zSum / count, 0.0, 0.05);
    EXPECT_NEAR(z2Sum / count, 1.0, 0.05);
    // Back to line integrals: the views render their own spectrum again.
    x->outputCombo()->setCurrentIndex(
        x->outputCombo()->findData(int(ui::XrayOutput::LineIntegrals)));
    EXPECT_FALSE(v->polychromatic());
}
