// What the workstation says stays true: the window follows the quantity shown, exports and the
// overlay name the polychromatic quantity and tube, the accuracy readout compares like with
// like, and the overlay's frame time is the shown frame's own.
#include <QApplication>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QElapsedTimer>
#include <QFile>
#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QLabel>
#include <QPlainTextEdit>
#include <QRegularExpression>
#include <QSignalSpy>
#include <QTest>

#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <filesystem>

#include <gtest/gtest.h>

#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/messages_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/scripted_run.h>

#include "test_support.h"
#include "ui/ui_support.h"

using namespace fvr;
using fvr::test::openAndWait;
using fvr::test::Workstation;
using fvr::ui::MainWindow;
using fvr::ui::StudySource;

namespace {

QString log(MainWindow& w) { return w.messages()->toPlainText(); }

/** The last line of the Messages panel. */
QString lastMessage(MainWindow& w) { return log(w).split('\n', Qt::SkipEmptyParts).last(); }

void chooseOutput(MainWindow& w, ui::XrayOutput o) {
    auto* c = w.xrayPanel()->outputCombo();
    c->setCurrentIndex(c->findData(int(o)));
}

void chooseShow(MainWindow& w, int show) {
    auto* c = w.xrayPanel()->showCombo();
    c->setCurrentIndex(c->findData(show));
}

/** View 1 shows the full-quality polychromatic frame of `show` (its materials have come). */
bool waitPolychromatic(MainWindow& w, int show) {
    ui::ProjectionView* v = w.views()[0];
    return QTest::qWaitFor(
        [&] {
            return v->polychromatic() && !v->polychromatic()->spectra.empty() &&
                   v->polychromatic()->show == show && v->showsCurrentFrame();
        },
        60000);
}

/** The window of view 1 (and the Display panel's) is the auto window of what it shows now: the
 *  0.5 and 99.5 percentiles of its projection (sorted here), to 2 % of that range; the preset
 *  says Auto. */
void expectAutoWindowOfShownQuantity(MainWindow& w, const char* what) {
    ui::ProjectionView* v = w.views()[0];
    const auto p = v->projection();
    ASSERT_TRUE(p) << what;
    std::vector<float> s = p->pixels;
    std::sort(s.begin(), s.end());
    const double lo = s[std::size_t(0.005 * (s.size() - 1))];
    const double hi = s[std::size_t(0.995 * (s.size() - 1))];
    const double tol = 0.02 * (hi - lo);
    std::printf("[ui-truth] %s: window %.4g..%.4g, percentiles %.4g..%.4g\n", what, v->window().low,
                v->window().high, lo, hi);
    EXPECT_NEAR(v->window().low, lo, tol) << what;
    EXPECT_NEAR(v->window().high, hi, tol) << what;
    EXPECT_EQ(w.displayPanel()->presetCombo()->currentData().toInt(), int(ui::WindowPreset::Auto))
        << what;
}

/** The ImageComments of a DICOM file. */
std::string imageComments(const std::filesystem::path& path) {
    DcmFileFormat file;
    if (!file.loadFile(path.c_str()).good()) return "(unreadable)";
    OFString c;
    file.getDataset()->findAndGetOFStringArray(DCM_ImageComments, c);
    return c.c_str();
}

} // namespace

// A changed quantity gets its own window every time: line integrals -> -ln(I/I0) -> bone's
// g/cm^2 -> line integrals -> bone again (the window of bone stayed on the line integrals, a
// white rectangle, and the line integrals' on bone, almost black; the preset said Auto).
TEST_F(Workstation, WindowFollowsTheOutputQuantity) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    expectAutoWindowOfShownQuantity(*window, "line integrals");
    chooseOutput(*window, ui::XrayOutput::Polychromatic);
    ASSERT_TRUE(waitPolychromatic(*window, -1)) << log(*window).toStdString();
    expectAutoWindowOfShownQuantity(*window, "-ln(I/I0)");
    chooseShow(*window, 2);
    ASSERT_TRUE(waitPolychromatic(*window, 2));
    expectAutoWindowOfShownQuantity(*window, "bone g/cm2");
    chooseOutput(*window, ui::XrayOutput::LineIntegrals);
    ASSERT_TRUE(QTest::qWaitFor([&] {
        return !window->views()[0]->polychromatic() && window->views()[0]->showsCurrentFrame();
    }));
    expectAutoWindowOfShownQuantity(*window, "line integrals again");
    chooseOutput(*window, ui::XrayOutput::Polychromatic); // its materials are kept: at once
    ASSERT_TRUE(waitPolychromatic(*window, 2));
    expectAutoWindowOfShownQuantity(*window, "bone g/cm2 again");
}

// Polychromatic exports say what they hold (-ln(I/I0) or a material's g/cm^2, with the tube),
// in the Messages panel and the DICOM ImageComments; never "line integrals".
TEST_F(Workstation, PolychromaticExportsNameTheirQuantity) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    chooseOutput(*window, ui::XrayOutput::Polychromatic);
    ASSERT_TRUE(waitPolychromatic(*window, -1)) << log(*window).toStdString();
    const auto dir = test::tmpDir() / "ui-truth-exports";
    std::filesystem::create_directories(dir);
    ASSERT_TRUE(window->exportProjection(QString::fromStdString((dir / "poly.npy").string())));
    QString m = lastMessage(*window);
    EXPECT_TRUE(m.contains(QString::fromUtf8("−ln(I/I0)")) && m.contains("80 kVp, 2.5 mm Al"))
        << m.toStdString();
    EXPECT_FALSE(m.contains("line integral")) << m.toStdString();
    const auto dcm = dir / "poly.dcm";
    ASSERT_TRUE(window->exportProjection(QString::fromStdString(dcm.string())));
    std::string c = imageComments(dcm);
    EXPECT_NE(c.find("values: polychromatic -ln(I/I0), 80 kVp, 2.5 mm Al"), std::string::npos) << c;
    EXPECT_EQ(c.find("line integral"), std::string::npos) << c;
    EXPECT_TRUE(std::all_of(c.begin(), c.end(), [](char ch) { return ch > 0; })) << c; // ASCII
    chooseShow(*window, 2);
    ASSERT_TRUE(waitPolychromatic(*window, 2));
    ASSERT_TRUE(window->exportProjection(QString::fromStdString(dcm.string())));
    c = imageComments(dcm);
    EXPECT_NE(c.find("values: polychromatic bone mass thickness (g/cm^2), 80 kVp"),
              std::string::npos)
        << c;
    m = lastMessage(*window);
    EXPECT_TRUE(m.contains(QString::fromUtf8("bone mass thickness (g/cm²)"))) << m.toStdString();
    // The scripted run's views.json says the same of its .npy.
    ui::ScriptedRunOptions opts;
    opts.exportDir = QString::fromStdString((dir / "scripted").string());
    ui::ScriptedRun run(*window, opts);
    run.writeOutputs();
    QFile json(opts.exportDir + "/views.json");
    ASSERT_TRUE(json.open(QIODevice::ReadOnly));
    const QJsonObject view1 =
        QJsonDocument::fromJson(json.readAll()).object()["views"].toArray()[0].toObject();
    EXPECT_EQ(view1["npyValues"].toString(),
              QString::fromUtf8("polychromatic bone mass thickness (g/cm²), 80 kVp, 2.5 mm Al"));
    // Line integrals again: labelled so.
    chooseOutput(*window, ui::XrayOutput::LineIntegrals);
    ASSERT_TRUE(window->exportProjection(QString::fromStdString((dir / "li.npy").string())));
    EXPECT_TRUE(lastMessage(*window).contains("line integrals"))
        << lastMessage(*window).toStdString();
}

// Ctrl+A compared -ln(I/I0) with mu ray casting (19 dB where the line integrals give 45): in
// Polychromatic mode it says that it cannot and why, and measures nothing; in line integrals it
// measures as before.
TEST_F(Workstation, AccuracyReadoutComparesLikeWithLike) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    chooseOutput(*window, ui::XrayOutput::Polychromatic);
    ASSERT_TRUE(waitPolychromatic(*window, -1)) << log(*window).toStdString();
    QSignalSpy measured(window.get(), &MainWindow::accuracyMeasured);
    window->measureAccuracy();
    QTest::qWait(2000); // a measurement of this size took well under a second
    EXPECT_EQ(measured.count(), 0) << "PSNR " << measured.first().at(0).toDouble();
    const QString m = lastMessage(*window);
    EXPECT_TRUE(m.contains(QString::fromUtf8("−ln(I/I0)")) && m.contains("Line integrals"))
        << m.toStdString();
    chooseOutput(*window, ui::XrayOutput::LineIntegrals);
    window->measureAccuracy();
    ASSERT_TRUE(measured.wait(60000));
    std::printf("[ui-truth] line integrals vs ray casting: %.2f dB\n",
                measured.first().at(0).toDouble());
    EXPECT_GT(measured.first().at(0).toDouble(), 35.0);
}

// The polychromatic overlay names the mode, the tube and the quantity; the single energy's rows
// (energy, mu water, exposure) are hidden there. With a material shown, noise does not apply
// (it is the detected intensity's): the control is disabled and says why, the source has none,
// and the overlay claims none.
TEST_F(Workstation, PolychromaticOverlayNamesModeAndTube) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    auto* x = window->xrayPanel();
    chooseOutput(*window, ui::XrayOutput::Polychromatic);
    x->noiseSpin()->setValue(0.5);
    ASSERT_TRUE(QTest::qWaitFor(
        [&] {
            auto p = window->views()[0]->polychromatic();
            return p && p->noise.active() && waitPolychromatic(*window, -1);
        },
        60000))
        << log(*window).toStdString();
    ui::ProjectionView* v = window->views()[0];
    QString o = v->overlayText();
    EXPECT_TRUE(o.contains(QString::fromUtf8("polychromatic 80 kVp, 2.5 mm Al: −ln(I/I0)  noise "
                                             "0.5 mAs")))
        << o.toStdString();
    EXPECT_FALSE(o.contains(QString::fromUtf8("μ"))) << o.toStdString();
    const QList<QLabel*> labels = x->findChildren<QLabel*>();
    const auto muWater = std::find_if(labels.begin(), labels.end(), [](QLabel* l) {
        return l->text() == QString::fromUtf8("μ water");
    });
    ASSERT_NE(muWater, labels.end());
    EXPECT_FALSE((*muWater)->isVisibleTo(x));
    EXPECT_FALSE(x->energySpin()->isVisibleTo(x));
    EXPECT_TRUE(x->noiseSpin()->isEnabled());
    chooseShow(*window, 2);
    ASSERT_TRUE(waitPolychromatic(*window, 2));
    EXPECT_FALSE(x->noiseSpin()->isEnabled());
    EXPECT_TRUE(x->noiseSpin()->toolTip().contains("no measurement"))
        << x->noiseSpin()->toolTip().toStdString();
    EXPECT_FALSE(v->polychromatic()->noise.active());
    o = v->overlayText();
    EXPECT_TRUE(o.contains(QString::fromUtf8("polychromatic 80 kVp, 2.5 mm Al: bone mass "
                                             "thickness (g/cm²)")))
        << o.toStdString();
    EXPECT_FALSE(o.contains("noise")) << o.toStdString();
    chooseOutput(*window, ui::XrayOutput::LineIntegrals); // the single energy's rows are back
    EXPECT_TRUE((*muWater)->isVisibleTo(x));
    EXPECT_FALSE(window->views()[0]->overlayText().contains("polychromatic"));
}

// The frame time in the overlay is the shown frame's own: a frame made off screen (for an export
// or a preset) says its render time, not the frame time of the frame before; a new study starts
// without the last one's times; compare and difference views say a number, never a bare "–".
TEST_F(Workstation, OverlayFrameTimeIsTheShownFramesOwn) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    ui::ProjectionView* v = window->views()[0];
    // The performance box's first line (not a compare view's title): speed, kernel, M×M, ...
    auto firstLine = [](ui::ProjectionView* view) {
        for (const QString& l : view->overlayText().split('\n'))
            if (l.contains(QString::fromUtf8("×")) && !l.startsWith("View ")) return l;
        return QString();
    };
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->frameStats().wallMs > 0; }, 10000));
    EXPECT_TRUE(firstLine(v).startsWith("frame ")) << firstLine(v).toStdString();
    // A new view, rendered by an export before the view paints it.
    v->setViewFrame(v->viewFrame().rotated(v->viewFrame().u, 0.5));
    const int before = v->framesRendered();
    ASSERT_TRUE(v->projection());
    ASSERT_EQ(v->framesRendered(), before + 1);
    QTest::qWait(300); // its paint and presentation
    EXPECT_EQ(v->framesRendered(), before + 1);
    EXPECT_EQ(v->frameStats().wallMs, 0.0) << "the frame before's time on screen";
    EXPECT_TRUE(firstLine(v).startsWith("render ")) << firstLine(v).toStdString();
    // The next change is timed from itself again, and bounded by the time since it.
    QElapsedTimer since;
    since.start();
    v->setViewFrame(v->viewFrame().rotated(v->viewFrame().u, 0.5));
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->frameStats().wallMs > 0; }, 10000));
    EXPECT_LE(v->frameStats().wallMs, double(since.elapsed()) + 1.0);
    EXPECT_GE(v->frameStats().wallMs, 0.0);
    // A new study: none of the old one's times.
    since.restart();
    window->openStudy(StudySource::phantom(48));
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->volume() && v->volume()->dims[0] == 48; }, 60000));
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->showsCurrentFrame(); }, 60000));
    QTest::qWait(300);
    EXPECT_LE(v->frameStats().wallMs, double(since.elapsed()) + 1.0);
    // Compare and difference views: each says its own number, with what it is.
    window->setCompareCount(2);
    ASSERT_TRUE(QTest::qWaitFor(
        [&] {
            return std::all_of(window->views().begin(), window->views().end(),
                               [](ui::ProjectionView* w) { return w->showsCurrentFrame(); });
        },
        60000));
    window->setDifferenceMode(true);
    QTest::qWait(1000);
    for (ui::ProjectionView* w : window->views()) {
        const QString l = firstLine(w);
        std::printf("[ui-truth] %s\n", l.toStdString().c_str());
        EXPECT_TRUE(l.contains(QRegularExpression("^(frame|render) [0-9.]+ ms")))
            << l.toStdString();
    }
}
