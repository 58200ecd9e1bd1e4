// Compare and difference views say what is true: the Rendering panel shows the kernel of the
// view it applies to, difference views share one symmetric scale (taken anew when a kernel
// changes) with a colour bar in units, each compare view states its own spectrum (on screen and
// in views.json), and Difference mode says why progressive refinement is off.
#include <QCheckBox>
#include <QComboBox>
#include <QFile>
#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QSignalSpy>
#include <QTest>

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/messages_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/scripted_run.h>

#include "test_support.h"
#include "ui/ui_support.h"

using namespace fvr;
using fvr::test::openAndWait;
using fvr::test::Workstation;
using fvr::ui::MainWindow;
using fvr::ui::StudySource;

namespace {

/** Every view has its spectrum, no job runs and every view shows its current frame. */
bool waitSettled(MainWindow& w) {
    return QTest::qWaitFor(
        [&] {
            if (w.study().busy()) return false;
            for (auto* v : w.views()) {
                if (!v->spectrum()) return false;
                v->update();
                if (!v->showsCurrentFrame()) return false;
            }
            return true;
        },
        90000);
}

core::Kernel comboKernel(const QComboBox* c) { return core::Kernel(c->currentData().toInt()); }

/** Selects `data` in a combo as a user would (the change signals are emitted). */
void choose(QComboBox* c, const QVariant& data) {
    const int i = c->findData(data);
    ASSERT_GE(i, 0) << data.toString().toStdString();
    c->setCurrentIndex(i);
}

/** The largest |view i - view 1| from the views' own full-quality projections (an oracle
 *  independent of the difference the view computes for display). */
double maxAbsDifference(MainWindow& w, std::size_t i) {
    const auto ref = w.views()[0]->projection();
    const auto own = w.views()[i]->projection();
    EXPECT_TRUE(ref && own);
    if (!ref || !own) return 0;
    double m = 0;
    for (std::size_t k = 0; k < own->pixels.size(); ++k)
        m = std::max(m, double(std::abs(own->pixels[k] - ref->pixels[k])));
    return m;
}

QJsonObject readJson(const std::filesystem::path& p) {
    QFile f(QString::fromStdString(p.string()));
    EXPECT_TRUE(f.open(QIODevice::ReadOnly)) << p;
    return QJsonDocument::fromJson(f.readAll()).object();
}

} // namespace

// Compare 2, Applies to = View 2 (linear), back to one view: the panel shows view 1's kernel
// (the one in use), and a later slice resolution change keeps it. In compare mode with All
// views, a new slice resolution leaves each view's own kernel.
TEST_F(Workstation, RenderingPanelShowsTheKernelOfTheViewItAppliesTo) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    auto* panel = window->renderingPanel();
    const core::Kernel main = window->views()[0]->settings().kernel;
    ASSERT_EQ(main, core::Kernel::KaiserBessel4); // the default
    window->setCompareCount(2);
    ASSERT_TRUE(waitSettled(*window));
    const core::Kernel second = window->views()[1]->settings().kernel;
    ASSERT_NE(second, main);
    panel->appliesToCombo()->setCurrentIndex(2); // View 2
    EXPECT_EQ(comboKernel(panel->kernelCombo()), second);

    // All views: the panel shows view 1's; a new size keeps each view's own kernel.
    panel->appliesToCombo()->setCurrentIndex(0);
    EXPECT_EQ(comboKernel(panel->kernelCombo()), main);
    choose(panel->sizeCombo(), 256);
    ASSERT_TRUE(waitSettled(*window));
    EXPECT_EQ(window->views()[0]->settings().kernel, main);
    EXPECT_EQ(window->views()[1]->settings().kernel, second);
    EXPECT_EQ(window->views()[0]->settings().size, 256);
    EXPECT_EQ(window->views()[1]->settings().size, 256);

    panel->appliesToCombo()->setCurrentIndex(2);
    window->setCompareCount(1);
    EXPECT_EQ(panel->appliesToCombo()->currentIndex(), 0);
    EXPECT_EQ(comboKernel(panel->kernelCombo()), main)
        << "the panel shows " << core::kernelName(comboKernel(panel->kernelCombo()));
    EXPECT_EQ(window->views()[0]->settings().kernel, main);

    // An unrelated change (slice resolution) keeps view 1's kernel.
    choose(panel->sizeCombo(), 512);
    ASSERT_TRUE(waitSettled(*window));
    EXPECT_EQ(window->views()[0]->settings().kernel, main)
        << "switched to " << core::kernelName(window->views()[0]->settings().kernel);
    EXPECT_EQ(window->views()[0]->settings().size, 512);
    EXPECT_EQ(comboKernel(panel->kernelCombo()), main);
    EXPECT_TRUE(
        window->views()[0]->overlayText().contains(QString::fromUtf8(core::kernelName(main))))
        << window->views()[0]->overlayText().toStdString();
}

// The difference view's window follows a kernel change (no flat grey until Difference is
// toggled): its symmetric range is the largest |difference| of the new kernel's frame.
TEST_F(Workstation, DifferenceWindowFollowsAKernelChange) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    window->setCompareCount(2);
    ASSERT_TRUE(waitSettled(*window));
    window->setDifferenceMode(true);
    ASSERT_TRUE(waitSettled(*window));
    auto* v2 = window->views()[1];
    const double before = maxAbsDifference(*window, 1);
    ASSERT_GT(before, 0);
    EXPECT_NEAR(v2->window().high, before, 1e-4 * before);
    EXPECT_NEAR(v2->window().low, -before, 1e-4 * before);

    auto* panel = window->renderingPanel();
    panel->appliesToCombo()->setCurrentIndex(2);
    choose(panel->kernelCombo(), int(core::Kernel::CatmullRom));
    ASSERT_TRUE(QTest::qWaitFor(
        [&] { return v2->spectrum() && v2->settings().kernel == core::Kernel::CatmullRom; },
        60000));
    ASSERT_TRUE(waitSettled(*window));
    const double after = maxAbsDifference(*window, 1);
    ASSERT_GT(std::abs(after - before), 0.05 * before) << "the kernels differ as much";
    EXPECT_NEAR(v2->window().high, after, 1e-4 * after) << "kept " << before;
    EXPECT_NEAR(v2->window().low, -after, 1e-4 * after);
}

// Four views in Difference mode: one symmetric scale for all (the largest |difference|), so
// errors 7x apart look 7x apart, and a colour bar that gives it with units.
TEST_F(Workstation, DifferenceViewsShareOneScaleWithAColourBar) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    window->setCompareCount(4);
    ASSERT_TRUE(waitSettled(*window));
    window->setDifferenceMode(true);
    ASSERT_TRUE(waitSettled(*window));
    QTest::qWait(200); // the shared scale reaches every view
    double scale = 0, smallest = 1e30;
    for (std::size_t i = 1; i < 4; ++i) {
        const double m = maxAbsDifference(*window, i);
        scale = std::max(scale, m);
        smallest = std::min(smallest, m);
    }
    ASSERT_GT(scale, 1.5 * smallest) << "the kernels' errors differ (the case of the issue)";
    for (std::size_t i = 1; i < 4; ++i) {
        auto* v = window->views()[i];
        EXPECT_NEAR(v->window().high, scale, 1e-4 * scale) << "view " << i + 1;
        EXPECT_NEAR(v->window().low, -scale, 1e-4 * scale) << "view " << i + 1;
        // The colour bar: +scale, 0, -scale in the values' units (attenuation: water mm).
        const QStringList labels = v->colourBarLabels();
        ASSERT_EQ(labels.size(), 3) << "view " << i + 1;
        const QString s = QString::number(scale, 'g', 3);
        EXPECT_EQ(labels[0], "+" + s + " mm");
        EXPECT_EQ(labels[1], "0 mm");
        EXPECT_EQ(labels[2], QStringLiteral("−") + s + " mm");
        // Drawn: white at the top (+scale), black at the bottom (-scale).
        const QImage shot = v->screenshot().convertToFormat(QImage::Format_RGB32);
        const QRect bar = v->colourBarRect();
        ASSERT_FALSE(bar.isNull());
        const double dpr = shot.devicePixelRatio();
        const QPoint top(int((bar.center().x()) * dpr), int((bar.top() + 3) * dpr));
        const QPoint bottom(int((bar.center().x()) * dpr), int((bar.bottom() - 3) * dpr));
        EXPECT_GT(qGray(shot.pixel(top)), 220);
        EXPECT_LT(qGray(shot.pixel(bottom)), 35);
    }
    EXPECT_TRUE(window->views()[0]->colourBarLabels().isEmpty()); // view 1 is no difference
    window->setDifferenceMode(false);
    EXPECT_TRUE(window->views()[1]->colourBarLabels().isEmpty());
}

// Each compare view states its own spectrum: gridding correction only where it is applied
// (not for linear), the oversampling, the values; the panel says when the view it shows renders
// without the correction; views.json records the same per view.
TEST_F(Workstation, CompareViewsStateTheirOwnSpectrum) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    window->setCompareCount(2);
    ASSERT_TRUE(waitSettled(*window));
    auto* v1 = window->views()[0];
    auto* v2 = window->views()[1];
    ASSERT_EQ(v2->settings().kernel, core::Kernel::Linear);
    ASSERT_EQ(v1->spectrum()->deapodizedFor, v1->settings().kernel);
    ASSERT_FALSE(v2->spectrum()->deapodizedFor);
    const double over = window->study().spectrumSettings().oversampling;
    EXPECT_TRUE(v1->overlayText().contains("gridding corrected"))
        << v1->overlayText().toStdString();
    EXPECT_FALSE(v1->overlayText().contains("no gridding correction"));
    EXPECT_TRUE(v2->overlayText().contains("no gridding correction"))
        << v2->overlayText().toStdString();
    EXPECT_TRUE(v2->overlayText().contains("oversampling")) << v2->overlayText().toStdString();

    auto* panel = window->renderingPanel();
    panel->appliesToCombo()->setCurrentIndex(2);
    EXPECT_TRUE(panel->deapodizeCheck()->text().contains("not applied to linear"))
        << panel->deapodizeCheck()->text().toStdString();
    panel->appliesToCombo()->setCurrentIndex(1);
    EXPECT_FALSE(panel->deapodizeCheck()->text().contains("not applied"));

    const auto dir = test::tmpDir() / "compare-truth-views";
    std::filesystem::remove_all(dir);
    ui::ScriptedRunOptions o;
    o.exportDir = QString::fromStdString(dir.string());
    ui::ScriptedRun run(*window, o);
    run.writeOutputs();
    const QJsonArray views = readJson(dir / "views.json")["views"].toArray();
    ASSERT_EQ(views.size(), 2);
    const QJsonObject s1 = views[0].toObject()["spectrum"].toObject();
    const QJsonObject s2 = views[1].toObject()["spectrum"].toObject();
    EXPECT_TRUE(s1["griddingCorrection"].toBool());
    EXPECT_EQ(s1["deapodizedFor"].toString(), core::kernelName(v1->settings().kernel));
    EXPECT_FALSE(s2["griddingCorrection"].toBool());
    EXPECT_TRUE(s2["deapodizedFor"].isNull());
    for (const auto& s : {s1, s2}) {
        EXPECT_EQ(s["oversampling"].toDouble(), over);
        EXPECT_EQ(s["values"].toString(), core::valueMappingName(v1->spectrum()->mapping));
        EXPECT_EQ(s["transform"].toString(), core::transformName(v1->spectrum()->kind));
        EXPECT_EQ(s["paddedDims"].toArray().size(), 3);
    }
}

// Difference mode renders full-quality frames: the overlay says that progressive refinement is
// off and why (the line does not vanish), and the interactive line comes back after it.
TEST_F(Workstation, DifferenceModeSaysProgressiveRefinementIsOff) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    window->setCompareCount(2);
    ASSERT_TRUE(waitSettled(*window));
    for (auto* v : window->views())
        ASSERT_TRUE(v->overlayText().contains("interactive target 30 fps"))
            << v->overlayText().toStdString();
    window->setDifferenceMode(true);
    ASSERT_TRUE(waitSettled(*window));
    for (auto* v : window->views()) {
        const QString t = v->overlayText();
        EXPECT_TRUE(t.contains("progressive refinement off")) << t.toStdString();
        EXPECT_TRUE(t.contains("Difference mode")) << t.toStdString();
        EXPECT_FALSE(t.contains("interactive level")) << t.toStdString();
        EXPECT_EQ(v->displayedLevel(), 0);
    }
    window->setDifferenceMode(false);
    ASSERT_TRUE(waitSettled(*window));
    for (auto* v : window->views()) {
        EXPECT_TRUE(v->overlayText().contains("interactive target 30 fps"));
        EXPECT_FALSE(v->overlayText().contains("progressive refinement off"));
    }
}
