// ViewOverlay: what a projection view writes over its image, laid out from a state made up here
// (no GL, no widget): the lines of the performance box, the box, the orientation labels clear
// of it, and what painting puts on an image.
#include <QImage>
#include <QPainter>

#include <gtest/gtest.h>

#include <fvr/ui/view_overlay.h>

#include "ui_support.h"

using fvr::ui::OverlayState;
using fvr::ui::ViewOverlay;
namespace core = fvr::core;

namespace {

/** A CPU frame of 256² linear at interactive level 1 of 2, 40 ms on screen, with the pixel
 *  aperture, depth cue and Beer-Lambert display, in difference mode. */
OverlayState knownState() {
    fvr::test::app();
    OverlayState s;
    s.widget = QSize(400, 300);
    s.image = QRectF(50, 0, 300, 300);
    s.hasImage = true;
    s.title = "view 2";
    s.differenceTo = "view 1";
    s.labels = {"R", "L", "A", "P"};
    s.shown = {256, core::Kernel::Linear};
    s.voxelModel = core::VoxelModel::Trilinear;
    s.effects.pixelAperture = true;
    s.effects.depthCue = 0.5;
    s.stats.sliceMs = 1.25;
    s.stats.inverseMs = 2.5;
    s.stats.displayMs = 0.75;
    s.stats.totalMs = 4.0;
    s.stats.wallMs = 40.0;
    s.progressive = true;
    s.targetFps = 20;
    s.level = 1;
    s.lastLevel = 2;
    s.window = {0.0, 2.0, false};
    s.window.transmission.muWaterPerMm = 0.019;
    return s;
}

QStringList lines(const OverlayState& s) { return ViewOverlay(s).text().split('\n'); }

} // namespace

TEST(ViewOverlay, LinesOfAKnownState) {
    const QStringList expected = {
        "view 2",
        "frame 40 ms  linear  256×256  CPU  trilinear voxels, area pixels",
        "interactive level 1/2 (target 20 fps)",
        "depth cue 50 %  Beer-Lambert μw 0.0190/mm ×1",
        "slice 1.25  inverse 2.50 ms",
        "W 2  L 1",
        "difference to view 1",
    };
    EXPECT_EQ(lines(knownState()), expected) << ViewOverlay(knownState()).text().toStdString();
}

TEST(ViewOverlay, LinesFollowTheFrame) {
    OverlayState s = knownState();
    s.interacting = true; // a drag: the frame rate the user sees, not the frame time
    EXPECT_EQ(lines(s)[1], "25 fps  linear  256×256  CPU  trilinear voxels, area pixels");
    s.stats.wallMs = 0; // not on screen yet: the renderer's own time, named so (never a bare -)
    EXPECT_TRUE(lines(s)[1].startsWith("render 4.0 ms  linear")) << lines(s)[1].toStdString();
    s.stats.totalMs = 0; // nothing rendered at all
    EXPECT_TRUE(lines(s)[1].startsWith("–  linear"));
    s.stats.totalMs = 4.0;
    s.level = 0;
    EXPECT_EQ(lines(s)[2], "full quality (interactive target 20 fps)");
    s.gpu = true;
    EXPECT_EQ(lines(s)[4], "slice 1.25  inverse 2.50  display 0.75 ms");
    s.stats.fused = true;
    EXPECT_EQ(lines(s)[4], "slice+inverse 2.50 ms  display 0.75 ms");
    s.stats.displayFused = true;
    EXPECT_EQ(lines(s)[4], "slice+inverse+display 2.50 ms (fused)");
    s.effects = {};
    s.effects.filter.sharpenAmount = 1.5;
    s.effects.filter.sharpenSigmaMm = 0.8;
    s.effects.filter.bandLimitLpMm = 0.25;
    s.window.transmission = {};
    EXPECT_EQ(lines(s)[3], "edges ×1.5 (σ 0.8 mm)  band limit 0.25 lp/mm");
    s.effects = {};
    s.progressive = false;
    EXPECT_EQ(ViewOverlay(s).performanceLines().size(), 3); // speed, stages, window
    s.performance = false; // the overlay switched off: the title and the difference note
    EXPECT_EQ(lines(s), (QStringList{"view 2", "difference to view 1"}));
}

TEST(ViewOverlay, LabelsKeepClearOfTheBox) {
    OverlayState s = knownState();
    s.image = QRectF(0, 0, 300, 300); // a compare view: the image starts under the box
    s.widget = QSize(300, 300);
    const ViewOverlay o(s);
    const QRect box = o.box();
    ASSERT_FALSE(box.isNull());
    EXPECT_EQ(box.topLeft(), QPoint(4, 4)); // 8, 6 from the corner, less the box's margin
    const QList<QRect> labels = o.labelRects();
    ASSERT_EQ(labels.size(), 4);
    for (const QRect& r : labels) {
        EXPECT_FALSE(r.intersects(box));
        EXPECT_TRUE(QRect(0, 0, 300, 300).contains(r));
    }
    EXPECT_LT(labels[0].center().x(), labels[1].center().x()); // left, right
    EXPECT_LT(labels[2].center().y(), labels[3].center().y()); // top, bottom
    s.hasImage = false;
    EXPECT_TRUE(ViewOverlay(s).box().isNull()); // no image: no box
}

// The default view looks along +z with -y up: the patient's right (-x in LPS) on the image's
// left, anterior at the top; a file without orientation says it is assumed.
TEST(ViewOverlay, OrientationLabelsOfTheDefaultView) {
    core::Volume v;
    const core::ViewFrame view = core::ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0});
    EXPECT_EQ(ViewOverlay::orientationLabels(v, view), (QStringList{"R", "L", "A", "P"}));
    v.orientationStated = false;
    EXPECT_EQ(ViewOverlay::orientationLabels(v, view).front(), "R (assumed)");
}

TEST(ViewOverlay, PaintsTheBoxOverTheImage) {
    const OverlayState s = knownState();
    QImage img(s.widget, QImage::Format_ARGB32_Premultiplied);
    img.fill(Qt::white);
    {
        QPainter p(&img);
        ViewOverlay(s).paint(p);
    }
    const QRect box = ViewOverlay(s).box();
    // Inside the box's margin (no text there): white under black at alpha 150.
    EXPECT_NEAR(qGray(img.pixel(box.left() + 1, box.bottom() - 1)), 255 - 150, 2);
    EXPECT_EQ(img.pixel(s.widget.width() - 1, 0), QColor(Qt::white).rgba()); // off the image
    // Without an image: the "no study" text in the middle instead, no box.
    OverlayState none = s;
    none.hasImage = false;
    img.fill(Qt::white);
    {
        QPainter p(&img);
        ViewOverlay(none).paint(p);
    }
    int dark = 0;
    for (int y = 100; y < 200; ++y)
        for (int x = 0; x < img.width(); ++x) dark += qGray(img.pixel(x, y)) < 230;
    EXPECT_GT(dark, 20);
    EXPECT_EQ(img.pixel(box.left() + 1, box.bottom() - 1), QColor(Qt::white).rgba());
}

// The polychromatic output names its mode, tube and quantity (and its noise, on -ln(I/I0)
// only), in both the parallel and the cone-beam box; no Beer-Lambert mu water there.
TEST(ViewOverlay, PolychromaticLineNamesTheModeTubeAndQuantity) {
    fvr::ui::PolychromaticSource src;
    EXPECT_EQ(ViewOverlay::polychromaticLine(nullptr), QString());
    EXPECT_TRUE(ViewOverlay::polychromaticLine(&src).contains("preparing the material spectra"));
    src.spectra.push_back(nullptr); // spectra have come (the line reads none of them)
    src.kvp = 80;
    src.filtrationAlMm = 2.5;
    src.noise.mAs = 0.5;
    EXPECT_EQ(ViewOverlay::polychromaticLine(&src),
              QString::fromUtf8("polychromatic 80 kVp, 2.5 mm Al: −ln(I/I0)  noise 0.5 mAs"));
    src.show = 2;
    src.filtrationCuMm = 0.1;
    EXPECT_EQ(ViewOverlay::polychromaticLine(&src),
              QString::fromUtf8("polychromatic 80 kVp, 2.5 mm Al, 0.1 mm Cu: bone mass thickness "
                                "(g/cm²)"));
    OverlayState s = knownState();
    s.window.transmission = {}; // the polychromatic output has no Beer-Lambert display
    s.output = ViewOverlay::polychromaticLine(&src);
    EXPECT_EQ(lines(s)[3], s.output);
    EXPECT_FALSE(ViewOverlay(s).text().contains(QString::fromUtf8("μw")));
    s.coneGeometry = "LAO 0° CRAN 0°  SID 1000  SOD 750 mm";
    EXPECT_TRUE(lines(s).contains(s.output));
}
