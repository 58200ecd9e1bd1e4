// The reader's tools (Measure menu): ruler, angle, ROI statistics, the value under the cursor,
// the scale bar, arrow and text annotations kept in the exports, and the image's turns and
// mirrors. The oracles are independent of the tools: a box phantom of known size, numpy on the
// exported .npy, hand-worked angles, the exported PNG's and DICOM's own pixels, dciodvfy.
#include <QComboBox>
#include <QMouseEvent>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <fvr/core/io/image_io.h>
#include <fvr/ui/measure_geometry.h>
#include <fvr/ui/measure_layer.h>
#include <fvr/ui/panels/geometry_panel.h>
#include <fvr/ui/panels/rendering_panel.h>

#include "ui/ui_support.h"

namespace fvr::test {
namespace {

namespace fs = std::filesystem;
using ui::Annotation;
using ui::MeasureLayer;
using ui::MeasureTool;
using ui::ProjectionView;
using ui::measure::Point;

#ifdef FVR_PYTHON_EXE
const std::string kPython = FVR_PYTHON_EXE; // the python3 the project's module is built for
#else
const std::string kPython = "python3";
#endif

void choose(QComboBox* c, int data) { c->setCurrentIndex(c->findData(data)); }

/** A 64^3 volume of 1 mm voxels, 0 outside a box of `nx` x `ny` x `nz` voxels whose first voxel
 *  is (x0, y0, z0), 1000 inside (int16 MetaImage). */
fs::path writeBox(const std::string& name, int x0, int nx, int y0, int ny, int z0, int nz) {
    const fs::path dir = tmpDir() / "measure";
    fs::create_directories(dir);
    const int n = 64;
    std::vector<std::int16_t> v(std::size_t(n) * n * n, 0);
    for (int z = z0; z < z0 + nz; ++z)
        for (int y = y0; y < y0 + ny; ++y)
            for (int x = x0; x < x0 + nx; ++x) v[(std::size_t(z) * n + y) * n + x] = 1000;
    std::ofstream(dir / (name + ".raw"), std::ios::binary)
        .write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * 2));
    std::ofstream(dir / (name + ".mhd"))
        << "ObjectType = Image\nNDims = 3\nDimSize = 64 64 64\nElementType = MET_SHORT\n"
           "ElementSpacing = 1 1 1\nElementByteOrderMSB = False\nElementDataFile = "
        << name << ".raw\n";
    return dir / (name + ".mhd");
}

StudySource source(const fs::path& p) {
    return StudySource::fromPath(QString::fromStdString(p.string()));
}

void send(QWidget* w, QEvent::Type type, QPointF pos, Qt::MouseButtons buttons) {
    const Qt::MouseButton b = type == QEvent::MouseMove ? Qt::NoButton : Qt::LeftButton;
    QMouseEvent e(type, pos, w->mapToGlobal(pos), b, buttons, Qt::NoModifier);
    QApplication::sendEvent(w, &e);
}

/** A left-button drag from a to b (image pixels) on the view. */
void drag(ProjectionView* v, Point a, Point b) {
    MeasureLayer& m = v->measure();
    send(v, QEvent::MouseButtonPress, m.toWidget(a), Qt::LeftButton);
    send(v, QEvent::MouseMove, m.toWidget({(a.x + b.x) / 2, (a.y + b.y) / 2}), Qt::LeftButton);
    send(v, QEvent::MouseMove, m.toWidget(b), Qt::LeftButton);
    send(v, QEvent::MouseButtonRelease, m.toWidget(b), Qt::NoButton);
}

TEST(MeasureGeometry, HandWorkedDistancesAnglesStatisticsAndTurns) {
    using namespace ui::measure;
    EXPECT_DOUBLE_EQ(distanceMm({0, 0}, {3, 4}, 0.5), 2.5);
    EXPECT_NEAR(angleDeg({4, 0}, {0, 0}, {0, 3}), 90.0, 1e-12);
    EXPECT_NEAR(angleDeg({1, 0}, {0, 0}, {1, 1}), 45.0, 1e-12);
    EXPECT_NEAR(angleDeg({1, 0}, {0, 0}, {-1, 0}), 180.0, 1e-12);
    // A 4 x 3 image 0..11; the rectangle (1,0)-(3,2) holds the centres of cols 1-2, rows 0-1.
    std::vector<float> px(12);
    for (int i = 0; i < 12; ++i) px[i] = float(i);
    const RoiStats r = roiStats(px, 4, 3, RoiShape::Rectangle, {1, 0}, {3, 2}, 2.0);
    EXPECT_EQ(r.count, 4u); // 1, 2, 5, 6
    EXPECT_DOUBLE_EQ(r.mean, 3.5);
    EXPECT_DOUBLE_EQ(r.sd, std::sqrt((6.25 + 2.25 + 2.25 + 6.25) / 4));
    EXPECT_EQ(r.min, 1.0);
    EXPECT_EQ(r.max, 6.0);
    EXPECT_DOUBLE_EQ(r.areaMm2, 16.0);
    // The ellipse inscribed in (0,0)-(4,3): centre (2, 1.5), radii 2 and 1.5. Row 1 (dy = 0):
    // all four centres, |dx| <= 0.75. Rows 0 and 2 (dy^2 = 4/9): cols 1 and 2 (dx^2 = 1/16);
    // cols 0 and 3 have dx^2 = 9/16, 9/16 + 4/9 > 1: out.
    const RoiStats e = roiStats(px, 4, 3, RoiShape::Ellipse, {0, 0}, {4, 3}, 1.0);
    EXPECT_EQ(e.count, 8u); // 1 2 / 4 5 6 7 / 9 10
    EXPECT_DOUBLE_EQ(e.mean, (1 + 2 + 4 + 5 + 6 + 7 + 9 + 10) / 8.0);
    EXPECT_EQ(roundScaleLength(37.0), 20.0);
    EXPECT_EQ(roundScaleLength(100.0), 100.0);
    EXPECT_EQ(roundScaleLength(0.7), 0.5);
    EXPECT_EQ(roundScaleLength(9.99), 5.0);
    const Point c = turned({1, 2}, Turn::Clockwise, 10);
    EXPECT_EQ(c.x, 8.0); // the left goes to the top
    EXPECT_EQ(c.y, 1.0);
    const Point h = turned({1, 2}, Turn::FlipHorizontal, 10);
    EXPECT_EQ(h.x, 9.0);
    EXPECT_EQ(h.y, 2.0);
}

/** The view looks along the volume's z (columns along x, rows along y), whatever the study's
 *  first view, and its frame is rendered. */
core::ProjectionImage lookAlongZ(ProjectionView* v) {
    v->setViewFrame(core::ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0}));
    auto img = v->projection();
    EXPECT_TRUE(img);
    QTest::qWait(50);
    return img ? *img : core::ProjectionImage{};
}

/** The half-way crossings of a profile (n values, `at(i)` the value at i) about `inside`:
 *  continuous coordinates (pixel centres at i + 0.5). */
std::pair<double, double> edgesOf(const std::function<double(int)>& at, int n, int inside) {
    const double bg = 0.5 * (at(1) + at(n - 2)), top = at(inside);
    const double half = 0.5 * (bg + top);
    const auto cross = [&](int a, int b) {
        return a + 0.5 + (at(a) - half) / (at(a) - at(b)) * (b - a);
    };
    int l = inside, r = inside;
    while (l > 1 && (at(l - 1) - half) * (top - half) > 0) --l;
    while (r < n - 2 && (at(r + 1) - half) * (top - half) > 0) ++r;
    return {cross(l, l - 1), cross(r, r + 1)};
}

std::pair<double, double> rowEdges(const core::ProjectionImage& img, int row, int inside) {
    return edgesOf([&](int c) { return double(img.at(c, row)); }, img.width, inside);
}
std::pair<double, double> columnEdges(const core::ProjectionImage& img, int col, int inside) {
    return edgesOf([&](int r) { return double(img.at(col, r)); }, img.height, inside);
}

TEST_F(Workstation, RulerReadsABoxOfKnownSizeInAParallelViewAtAnyZoomAndPan) {
    // 24 x 16 x 4 voxels of 1 mm, centred in the volume.
    ASSERT_TRUE(openAndWait(*window, source(writeBox("box", 20, 24, 24, 16, 30, 4))));
    ProjectionView* v = window->views()[0];
    const core::ProjectionImage img = lookAlongZ(v);
    const int M = img.width;
    const double d = img.pixelSize;
    const auto [xl, xr] = rowEdges(img, M / 2, M / 2);
    window->setMeasureTool(MeasureTool::Ruler);
    MeasureLayer& m = v->measure();
    drag(v, {xl, M / 2 + 0.5}, {xr, M / 2 + 0.5});
    ASSERT_EQ(m.annotations().size(), 1u);
    const double width = m.lengthMm(0).value_or(0);
    std::printf("[measure] box 24 mm: ruler %.4f mm (pixel %.4f mm, M %d)\n", width, d, M);
    EXPECT_NEAR(width, 24.0, 0.5 * d);
    EXPECT_EQ(m.label(0), QString("%1 mm").arg(width, 0, 'f', 1));
    // Zoomed in: the ruler stays on the image's points and reads the same; a new one drawn
    // at this zoom and pan reads the box's height.
    v->setZoom(2.5);
    EXPECT_NEAR(m.annotations()[0].points[1].x * M, xr, 1e-9);
    EXPECT_NEAR(m.lengthMm(0).value_or(0), width, 1e-9);
    // Panned by a middle drag: the image moves, the ruler with it.
    const QPointF end0 = m.toWidget({xr, M / 2 + 0.5});
    const QPointF from(v->width() / 2, v->height() / 2), to = from + QPointF(37, -21);
    for (auto [type, at, button, buttons] :
         {std::tuple{QEvent::MouseButtonPress, from, Qt::MiddleButton, Qt::MiddleButton},
          std::tuple{QEvent::MouseMove, to, Qt::NoButton, Qt::MiddleButton},
          std::tuple{QEvent::MouseButtonRelease, to, Qt::MiddleButton, Qt::NoButton}}) {
        QMouseEvent e(type, at, v->mapToGlobal(at), button, buttons, Qt::NoModifier);
        QApplication::sendEvent(v, &e);
    }
    EXPECT_NEAR(m.toWidget({xr, M / 2 + 0.5}).x(), end0.x() + 37, 1e-9);
    EXPECT_NEAR(m.annotations()[0].points[1].x * M, xr, 1e-9);
    EXPECT_NEAR(m.lengthMm(0).value_or(0), width, 1e-9);
    const auto [yt, yb] = columnEdges(img, M / 2, M / 2);
    drag(v, {M / 2 + 0.5, yt}, {M / 2 + 0.5, yb});
    ASSERT_EQ(m.annotations().size(), 2u);
    const double height = m.lengthMm(1).value_or(0);
    std::printf("[measure] box 16 mm at zoom 2.5: ruler %.4f mm\n", height);
    EXPECT_NEAR(height, 16.0, 0.5 * d);
    // The pointer draws nothing (the drag rotates the view, as before).
    window->setMeasureTool(MeasureTool::Pointer);
    drag(v, {M * 0.2, M * 0.2}, {M * 0.3, M * 0.25});
    EXPECT_EQ(m.annotations().size(), 2u);
}

TEST_F(Workstation, RulerOnAConeBeamViewMeasuresAtTheIsocentreAndSaysSo) {
    ASSERT_TRUE(openAndWait(*window, source(writeBox("box", 20, 24, 24, 16, 30, 4))));
    ProjectionView* v = window->views()[0];
    choose(window->geometryPanel()->projectionCombo(), int(ui::ProjectionKind::Cone));
    ASSERT_EQ(v->settings().projection, ui::ProjectionKind::Cone);
    const core::ProjectionImage img = lookAlongZ(v);
    const int M = img.width;
    const double d = img.pixelSize; // the detector's pitch at the isocentre
    const auto [xl, xr] = rowEdges(img, M / 2, M / 2);
    window->setMeasureTool(MeasureTool::Ruler);
    MeasureLayer& m = v->measure();
    drag(v, {xl, M / 2 + 0.5}, {xr, M / 2 + 0.5});
    const double width = m.lengthMm(0).value_or(0);
    std::printf("[measure] cone SID %.0f SOD %.0f: box 24 mm reads %.4f mm at the isocentre "
                "(pixel %.4f mm)\n",
                v->settings().cone.sid, v->settings().cone.sod, width, d);
    // A thin box at the isocentre: its true width (the detector shows it SID/SOD larger).
    EXPECT_NEAR(width, 24.0, 0.5 * d);
    EXPECT_TRUE(m.label(0).endsWith(" mm at isocentre")) << m.label(0).toStdString();
    EXPECT_TRUE(m.scaleBarLabel().endsWith(" mm at isocentre")) << m.scaleBarLabel().toStdString();
    // Mirrored: the C-arm on the other side sees the thin centred box the same size.
    window->turnImage(ui::measure::Turn::FlipHorizontal);
    const auto mirrored = v->projection();
    ASSERT_TRUE(mirrored);
    EXPECT_TRUE(v->renderError().isEmpty()) << v->renderError().toStdString();
    const auto [ml, mr] = rowEdges(*mirrored, M / 2, M / 2);
    EXPECT_NEAR((mr - ml) * mirrored->pixelSize, 24.0, 0.5 * d);
    EXPECT_NEAR(m.lengthMm(0).value_or(0), width, 1e-9);
}

TEST_F(Workstation, AngleReadsAKnownConfigurationAndItsHandlesMoveAndDelete) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ProjectionView* v = window->views()[0];
    v->setFocus();
    const int M = v->projection()->width;
    MeasureLayer& m = v->measure();
    window->setMeasureTool(MeasureTool::Angle);
    // The first arm from A to the vertex V, then a click at B: 60° at V.
    const Point a{M * 0.2, M * 0.6}, vx{M * 0.5, M * 0.6};
    const double arm = M * 0.3;
    const Point b{vx.x - arm * 0.5, vx.y - arm * std::sqrt(3.0) / 2}; // up and left
    drag(v, a, vx);
    send(v, QEvent::MouseMove, m.toWidget(b), Qt::NoButton);
    send(v, QEvent::MouseButtonPress, m.toWidget(b), Qt::LeftButton);
    send(v, QEvent::MouseButtonRelease, m.toWidget(b), Qt::NoButton);
    ASSERT_EQ(m.annotations().size(), 1u);
    EXPECT_NEAR(m.angleDeg(0).value_or(0), 60.0, 1e-6);
    EXPECT_EQ(m.label(0), QString::fromUtf8("60.0°"));
    // B's handle dragged straight above V (any tool grabs a handle): a right angle.
    window->setMeasureTool(MeasureTool::Pointer);
    drag(v, b, {vx.x, vx.y - arm});
    EXPECT_NEAR(m.angleDeg(0).value_or(0), 90.0, 1e-6);
    EXPECT_EQ(m.selected(), 0);
    QTest::keyClick(v, Qt::Key_Delete);
    EXPECT_TRUE(m.annotations().empty());
}

/** numpy's statistics of the exported image inside a rectangle or an ellipse given by corners
 *  (image pixels), with its own pixel mask: count mean std min max. */
std::vector<double> numpyStats(const fs::path& npy, bool ellipse, Point a, Point b) {
    std::ostringstream py;
    py.precision(17);
    py << "import numpy as np\n"
       << "img = np.load('" << npy.string() << "').astype(np.float64)\n"
       << "x0, x1 = sorted([" << a.x << ", " << b.x << "])\n"
       << "y0, y1 = sorted([" << a.y << ", " << b.y << "])\n"
       << "yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]] + 0.5\n"
       << "m = (xx >= x0) & (xx <= x1) & (yy >= y0) & (yy <= y1)\n";
    if (ellipse)
        py << "rx, ry = (x1 - x0) / 2, (y1 - y0) / 2\n"
           << "m &= ((xx - x0 - rx) / rx) ** 2 + ((yy - y0 - ry) / ry) ** 2 <= 1\n";
    py << "v = img[m]\n"
       << "print(repr(float(v.size)), repr(v.mean()), repr(v.std()), repr(v.min()), "
          "repr(v.max()))\n";
    const fs::path script = tmpDir() / "measure" / "roi.py";
    std::ofstream(script) << py.str();
    const auto r = runCommand("'" + kPython + "' '" + script.string() + "' 2>&1");
    EXPECT_EQ(r.status, 0) << r.out;
    std::istringstream in(r.out);
    std::vector<double> out(5, -1);
    for (double& x : out) in >> x;
    return out;
}

TEST_F(Workstation, RoiStatisticsEqualNumpysOnTheExportedNpy) {
    if (runCommand("'" + kPython + "' -c 'import numpy'").status != 0)
        GTEST_SKIP() << "numpy is missing";
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ProjectionView* v = window->views()[0];
    const int M = v->projection()->width;
    MeasureLayer& m = v->measure();
    const Point ra{M * 0.31, M * 0.27}, rb{M * 0.62, M * 0.58};
    const Point ea{M * 0.22, M * 0.41}, eb{M * 0.71, M * 0.77};
    window->setMeasureTool(MeasureTool::Rectangle);
    drag(v, ra, rb);
    window->setMeasureTool(MeasureTool::Ellipse);
    drag(v, ea, eb);
    ASSERT_EQ(m.annotations().size(), 2u);
    const fs::path npy = tmpDir() / "measure" / "roi.npy";
    fs::create_directories(npy.parent_path());
    ASSERT_TRUE(window->exportProjection(QString::fromStdString(npy.string())));
    for (int i = 0; i < 2; ++i) {
        const auto s = m.roiStats(i);
        ASSERT_TRUE(s);
        // The corners as the layer holds them (fractions of the side, back in pixels).
        const auto& p = m.annotations()[i].points;
        const auto np = numpyStats(npy, i == 1, {p[0].x * M, p[0].y * M}, {p[1].x * M, p[1].y * M});
        std::printf("[measure] ROI %d: %zu px mean %.6g SD %.6g min %.6g max %.6g (numpy %.0f "
                    "%.6g %.6g %.6g %.6g)\n",
                    i, s->count, s->mean, s->sd, s->min, s->max, np[0], np[1], np[2], np[3], np[4]);
        EXPECT_GT(s->count, 100u);
        EXPECT_EQ(double(s->count), np[0]);
        EXPECT_NEAR(s->mean, np[1], 1e-9 * std::max(1.0, std::abs(np[1])));
        EXPECT_NEAR(s->sd, np[2], 1e-9 * std::max(1.0, np[2]));
        EXPECT_EQ(s->min, np[3]);
        EXPECT_EQ(s->max, np[4]);
        EXPECT_NEAR(s->areaMm2, np[0] * v->projection()->pixelSize * v->projection()->pixelSize,
                    1e-9);
        EXPECT_TRUE(m.label(i).contains(v->valueUnits())) << m.label(i).toStdString();
    }
}

TEST_F(Workstation, ValueUnderTheCursorAndTheScaleBar) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ProjectionView* v = window->views()[0];
    const auto img = v->projection();
    ASSERT_TRUE(img);
    MeasureLayer& m = v->measure();
    const int c = img->width / 2 + 3, r = img->height / 2 - 5;
    send(v, QEvent::MouseMove, m.toWidget({c + 0.5, r + 0.5}), Qt::NoButton);
    const QString expected = QString("x %1  y %2   %3 %4")
                                 .arg(c)
                                 .arg(r)
                                 .arg(double(img->at(c, r)), 0, 'g', 5)
                                 .arg(v->valueUnits());
    EXPECT_EQ(window->cursorReadout(), expected);
    EXPECT_FALSE(v->valueUnits().isEmpty());
    // The scale bar: a round length of about a quarter of the image's width.
    QTest::qWait(50);
    const double bar = m.scaleBarMm(), fov = img->width * img->pixelSize;
    std::printf("[measure] scale bar %.3g mm of a %.1f mm field\n", bar, fov);
    EXPECT_EQ(bar, ui::measure::roundScaleLength(0.25 * fov));
    EXPECT_GT(bar, 0.25 * fov / 2.5);
    EXPECT_EQ(m.scaleBarLabel(), QString("%1 mm").arg(bar, 0, 'g', 4));
    // Drawn: white along the bar's line at the bottom right.
    const QImage shot = v->screenshot().scaled(v->size());
    const int y = v->height() - 12, x1 = v->width() - 14;
    const int len = int(bar / img->pixelSize / img->width * v->imageRectInWidget().width());
    int white = 0;
    for (int x = x1 - len + 2; x < x1 - 1; ++x) white += qGray(shot.pixel(x, y)) > 240;
    EXPECT_GT(white, (len - 4) * 9 / 10) << "of " << len;
    // The overlay off (F): the image alone, no bar.
    v->setOverlayVisible(false);
    const QImage bare = v->screenshot().scaled(v->size());
    int whiteBare = 0;
    for (int x = x1 - len + 2; x < x1 - 1; ++x) whiteBare += qGray(bare.pixel(x, y)) > 240;
    EXPECT_EQ(whiteBare, 0);
}

/** The bit of an overlay plane's data (16-bit words, the first pixel in the lowest bit). */
bool overlayBit(const Uint16* words, std::size_t i) { return (words[i / 16] >> (i % 16)) & 1u; }

TEST_F(Workstation, AnnotationsAreInTheExportedPngPixelsAndInTheDicomOverlay) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ProjectionView* v = window->views()[0];
    const int M = v->projection()->width;
    const fs::path dir = tmpDir() / "measure";
    fs::create_directories(dir);
    const auto out = [&](const char* n) { return QString::fromStdString((dir / n).string()); };
    ASSERT_TRUE(window->exportProjection(out("plain.png")));
    ASSERT_TRUE(window->exportProjection(out("plain.dcm")));
    window->setMeasureTool(MeasureTool::Arrow);
    const Point head{M * 0.30, M * 0.30}, tail{M * 0.45, M * 0.42};
    drag(v, head, tail);
    v->measure().add({Annotation::Kind::Text, {{0.55, 0.75}}, "lesion"});
    ASSERT_EQ(v->measure().annotations().size(), 2u);
    ASSERT_TRUE(window->exportProjection(out("annotated.png")));
    ASSERT_TRUE(window->exportProjection(out("annotated.dcm")));

    // PNG: the arrow's shaft and the text's box are white (the window's brightest value).
    int rows = 0, cols = 0;
    const auto plain = core::readPng((dir / "plain.png").string(), rows, cols);
    const auto ann = core::readPng((dir / "annotated.png").string(), rows, cols);
    ASSERT_EQ(cols, M);
    const auto at = [&](const std::vector<float>& img, Point p) {
        return img[std::size_t(p.y) * cols + std::size_t(p.x)];
    };
    const Point mid{(head.x + tail.x) / 2, (head.y + tail.y) / 2};
    EXPECT_EQ(at(ann, mid), 1.0f);
    int changed = 0, textInk = 0;
    for (std::size_t i = 0; i < ann.size(); ++i) changed += ann[i] != plain[i];
    for (int y = int(0.75 * M); y < int(0.75 * M) + 14; ++y)
        for (int x = int(0.55 * M); x < int(0.55 * M) + 40; ++x)
            textInk +=
                ann[std::size_t(y) * cols + x] == 1.0f && plain[std::size_t(y) * cols + x] != 1.0f;
    std::printf("[measure] PNG: %d pixels burned in, %d of them in the text's box\n", changed,
                textInk);
    EXPECT_GT(changed, 40);
    EXPECT_GT(textInk, 10);

    // DICOM: an overlay plane over untouched pixel values; the plain export has none.
    DcmFileFormat a, p;
    ASSERT_TRUE(a.loadFile((dir / "annotated.dcm").c_str()).good());
    ASSERT_TRUE(p.loadFile((dir / "plain.dcm").c_str()).good());
    DcmDataset* ds = a.getDataset();
    Uint16 orows = 0, ocols = 0;
    ds->findAndGetUint16(DCM_OverlayRows, orows);
    ds->findAndGetUint16(DCM_OverlayColumns, ocols);
    EXPECT_EQ(orows, M);
    EXPECT_EQ(ocols, M);
    OFString type;
    ds->findAndGetOFString(DCM_OverlayType, type);
    EXPECT_EQ(type, "G");
    const Uint16* words = nullptr;
    unsigned long nwords = 0;
    ASSERT_TRUE(ds->findAndGetUint16Array(DCM_OverlayData, words, &nwords).good());
    ASSERT_EQ(nwords, (std::size_t(M) * M + 15) / 16);
    std::size_t on = 0;
    for (std::size_t i = 0; i < std::size_t(M) * M; ++i) on += overlayBit(words, i);
    EXPECT_EQ(int(on), changed); // the same pixels as the PNG's burned-in ones
    EXPECT_TRUE(overlayBit(words, std::size_t(mid.y) * M + std::size_t(mid.x)));
    EXPECT_FALSE(p.getDataset()->tagExists(DCM_OverlayData));
    const Uint16 *pa = nullptr, *pp = nullptr;
    unsigned long na = 0, npix = 0;
    ASSERT_TRUE(ds->findAndGetUint16Array(DCM_PixelData, pa, &na).good());
    ASSERT_TRUE(p.getDataset()->findAndGetUint16Array(DCM_PixelData, pp, &npix).good());
    ASSERT_EQ(na, npix);
    EXPECT_TRUE(std::equal(pa, pa + na, pp)); // the values stay the image's
    if (runCommand("command -v dciodvfy").status != 0) GTEST_SKIP() << "dciodvfy is missing";
    const auto r = runCommand("dciodvfy -new '" + (dir / "annotated.dcm").string() + "' 2>&1");
    std::istringstream in(r.out);
    for (std::string line; std::getline(in, line);) {
        EXPECT_NE(line.rfind("Error", 0), 0u) << line;
        if (line.rfind("Warning", 0) == 0) std::printf("[measure] dciodvfy: %s\n", line.c_str());
    }
}

/** The centroid (continuous image coordinates) of the pixels above half the image's maximum. */
Point brightCentroid(const core::ProjectionImage& img) {
    const float top = *std::max_element(img.pixels.begin(), img.pixels.end());
    double sx = 0, sy = 0, n = 0;
    for (int r = 0; r < img.height; ++r)
        for (int c = 0; c < img.width; ++c)
            if (img.at(c, r) > 0.5f * top) sx += c + 0.5, sy += r + 0.5, n += 1;
    return {sx / n, sy / n};
}

TEST_F(Workstation, FlipAndRotateMoveALeftFeatureItsLabelsAndItsRuler) {
    // A box left of the volume's centre (x 8..20 of 64), centred in y and z.
    ASSERT_TRUE(openAndWait(*window, source(writeBox("left", 8, 12, 26, 12, 28, 8))));
    ProjectionView* v = window->views()[0];
    const core::ProjectionImage img = lookAlongZ(v);
    const int M = img.width;
    const Point c0 = brightCentroid(img);
    ASSERT_LT(c0.x, M / 2.0 - 10); // on the left
    const QStringList l0 = v->orientationLabels(); // left, right, top, bottom
    const auto [xl, xr] = rowEdges(img, int(c0.y), int(c0.x));
    window->setMeasureTool(MeasureTool::Ruler);
    MeasureLayer& m = v->measure();
    drag(v, {xl, c0.y}, {xr, c0.y});
    const double len = m.lengthMm(0).value_or(0);
    EXPECT_NEAR(len, 12.0, 0.5 * img.pixelSize);
    const auto rulerMid = [&] {
        const auto& p = m.annotations()[0].points;
        return Point{(p[0].x + p[1].x) / 2 * M, (p[0].y + p[1].y) / 2 * M};
    };

    window->turnImage(ui::measure::Turn::FlipHorizontal);
    const auto flipped = v->projection();
    ASSERT_TRUE(flipped);
    const Point c1 = brightCentroid(*flipped);
    std::printf("[measure] feature at x %.3f; mirrored %.3f (M + 1 - x = %.3f)\n", c0.x, c1.x,
                M + 1 - c0.x);
    EXPECT_NEAR(c1.x, M + 1 - c0.x, 0.5);
    EXPECT_NEAR(c1.y, c0.y, 0.5);
    const QStringList l1 = v->orientationLabels();
    EXPECT_EQ(l1[0], l0[1]);
    EXPECT_EQ(l1[1], l0[0]);
    EXPECT_EQ(l1[2], l0[2]);
    EXPECT_NEAR(rulerMid().x, c1.x, 0.5);
    EXPECT_NEAR(m.lengthMm(0).value_or(0), len, 1e-9);

    window->turnImage(ui::measure::Turn::Clockwise);
    const auto turned = v->projection();
    ASSERT_TRUE(turned);
    const Point c2 = brightCentroid(*turned);
    std::printf("[measure] turned clockwise: feature at (%.3f, %.3f), expected (%.3f, %.3f)\n",
                c2.x, c2.y, M + 1 - c1.y, c1.x);
    EXPECT_NEAR(c2.x, M + 1 - c1.y, 0.5);
    EXPECT_NEAR(c2.y, c1.x, 0.5);
    const QStringList l2 = v->orientationLabels();
    EXPECT_EQ(l2[2], l1[0]); // what was on the left is at the top
    EXPECT_EQ(l2[1], l1[2]); // what was at the top is on the right
    EXPECT_NEAR(rulerMid().x, c2.x, 0.5);
    EXPECT_NEAR(rulerMid().y, c2.y, 0.5);
    EXPECT_NEAR(m.lengthMm(0).value_or(0), len, 1e-9);
    // Back: counter-clockwise and the vertical mirror twice give the first image's feature.
    window->turnImage(ui::measure::Turn::CounterClockwise);
    window->turnImage(ui::measure::Turn::FlipVertical);
    window->turnImage(ui::measure::Turn::FlipVertical);
    window->turnImage(ui::measure::Turn::FlipHorizontal);
    const Point c3 = brightCentroid(*v->projection());
    EXPECT_NEAR(c3.x, c0.x, 0.5);
    EXPECT_NEAR(c3.y, c0.y, 0.5);
    EXPECT_EQ(v->orientationLabels(), l0);
}

TEST_F(Workstation, DifferenceViewMeasuresTheDifferenceItShowsAndAnnotationsStayOnViewOne) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    const int M = window->views()[0]->projection()->width;
    window->setMeasureTool(MeasureTool::Ruler);
    drag(window->views()[0], {M * 0.2, M * 0.5}, {M * 0.7, M * 0.5});
    window->setCompareCount(2);
    window->setDifferenceMode(true);
    ASSERT_EQ(window->views().size(), 2u);
    EXPECT_EQ(window->views()[0]->measure().annotations().size(), 1u); // kept
    ProjectionView* v = window->views()[1];
    ASSERT_TRUE(QTest::qWaitFor([&] { return v->showsCurrentFrame(); }, 60000));
    window->setMeasureTool(MeasureTool::Rectangle);
    const Point a{M * 0.3, M * 0.3}, b{M * 0.66, M * 0.61};
    drag(v, a, b);
    const auto s = v->measure().roiStats(0);
    ASSERT_TRUE(s);
    // The oracle: both views' own projections, subtracted here, over the rectangle's centres.
    const auto own = v->projection(), ref = window->views()[0]->projection();
    ASSERT_TRUE(own && ref);
    const auto& p = v->measure().annotations()[0].points;
    double sum = 0, n = 0, lo = 1e300, hi = -1e300;
    for (int r = 0; r < M; ++r)
        for (int c = 0; c < M; ++c) {
            const double x = c + 0.5, y = r + 0.5;
            if (x < p[0].x * M || x > p[1].x * M || y < p[0].y * M || y > p[1].y * M) continue;
            const double d = double(own->at(c, r) - ref->at(c, r));
            sum += d, n += 1, lo = std::min(lo, d), hi = std::max(hi, d);
        }
    std::printf("[measure] difference ROI: %zu px mean %.4g min %.4g max %.4g\n", s->count, s->mean,
                s->min, s->max);
    EXPECT_EQ(double(s->count), n);
    EXPECT_NEAR(s->mean, sum / n, 1e-9 * std::max(1.0, std::abs(sum / n)));
    EXPECT_EQ(s->min, lo);
    EXPECT_EQ(s->max, hi);
    EXPECT_NE(s->min, s->max); // the kernels differ: not an empty difference
    EXPECT_TRUE(v->measure().label(0).contains("(difference)"))
        << v->measure().label(0).toStdString();
}

TEST_F(Workstation, ASavedSessionKeepsTheAnnotations) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ProjectionView* v = window->views()[0];
    const int M = v->projection()->width;
    window->setMeasureTool(MeasureTool::Ruler);
    drag(v, {M * 0.21, M * 0.33}, {M * 0.64, M * 0.58});
    window->setMeasureTool(MeasureTool::Ellipse);
    drag(v, {M * 0.3, M * 0.3}, {M * 0.5, M * 0.45});
    v->measure().add({Annotation::Kind::Text, {{0.55, 0.75}}, "lesion, 2nd"});
    const std::vector<Annotation> before = v->measure().annotations();
    const double length = v->measure().lengthMm(0).value_or(0);
    const fs::path path = tmpDir() / "measure" / "annotated.fvrsession";
    fs::create_directories(path.parent_path());
    ASSERT_TRUE(window->saveSession(QString::fromStdString(path.string())));
    window->views()[0]->measure().clear();
    QSignalSpy restored(window.get(), &MainWindow::sessionRestored);
    ASSERT_TRUE(window->openSession(QString::fromStdString(path.string())));
    ASSERT_TRUE(restored.count() > 0 || restored.wait(60000));
    MeasureLayer& m = window->views()[0]->measure();
    ASSERT_EQ(m.annotations().size(), before.size());
    for (std::size_t i = 0; i < before.size(); ++i) {
        EXPECT_EQ(m.annotations()[i].kind, before[i].kind);
        EXPECT_EQ(m.annotations()[i].text, before[i].text);
        ASSERT_EQ(m.annotations()[i].points.size(), before[i].points.size());
        for (std::size_t k = 0; k < before[i].points.size(); ++k) {
            EXPECT_EQ(m.annotations()[i].points[k].x, before[i].points[k].x); // 17 digits
            EXPECT_EQ(m.annotations()[i].points[k].y, before[i].points[k].y);
        }
    }
    EXPECT_NEAR(m.lengthMm(0).value_or(0), length, 1e-9);
}

// A real CT as a reader sees it: a ruler across the body, an ellipse ROI, an arrow and a text
// (the README's screenshot, written to the test's folder as measure.png).
TEST_F(Workstation, MeasuresOnARealCtAndItsScreenshot) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    const fs::path ct = fs::path(FVR_SHARED_DATA_DIR) / "volumes/body_ct_hu_3mm/example_ct.mhd";
    window->resize(1280, 860);
    ASSERT_TRUE(openAndWait(*window, source(ct)));
    ProjectionView* v = window->views()[0];
    const auto img = v->projection();
    ASSERT_TRUE(img);
    const int M = img->width;
    // The body's width along the row through its middle, from skin to skin (a tenth of the
    // row's largest line integral).
    const int row = M / 2;
    float top = 0;
    for (int c = 0; c < M; ++c) top = std::max(top, img->at(c, row));
    int l = 0, r = M - 1;
    while (l < M - 1 && img->at(l, row) < 0.1f * top) ++l;
    while (r > 0 && img->at(r, row) < 0.1f * top) --r;
    const double xl = l, xr = r + 1.0;
    window->setMeasureTool(MeasureTool::Ruler);
    MeasureLayer& m = v->measure();
    drag(v, {xl, row + 0.5}, {xr, row + 0.5});
    const double body = m.lengthMm(0).value_or(0);
    std::printf("[measure] body CT: %.1f mm edge to edge at row %d (pixel %.3f mm)\n", body, row,
                img->pixelSize);
    EXPECT_NEAR(body, (xr - xl) * img->pixelSize, 1e-6);
    EXPECT_GT(body, 150.0); // an adult's trunk
    window->setMeasureTool(MeasureTool::Ellipse);
    drag(v, {M * 0.43, M * 0.36}, {M * 0.52, M * 0.44});
    window->setMeasureTool(MeasureTool::Arrow);
    drag(v, {M * 0.56, M * 0.60}, {M * 0.68, M * 0.70});
    m.add({Annotation::Kind::Text, {{0.685, 0.715}}, "note"});
    window->setMeasureTool(MeasureTool::Pointer);
    m.select(-1);
    send(v, QEvent::MouseMove, m.toWidget({M * 0.47, M * 0.55}), Qt::NoButton);
    EXPECT_TRUE(window->cursorReadout().endsWith(v->valueUnits()));
    const auto roi = m.roiStats(1);
    ASSERT_TRUE(roi);
    EXPECT_GT(roi->count, 50u);
    QTest::qWait(200);
    const fs::path shot = tmpDir() / "measure" / "measure.png";
    fs::create_directories(shot.parent_path());
    EXPECT_TRUE(window->grabWithViews(window.get()).save(QString::fromStdString(shot.string())));
    std::printf("[measure] screenshot %s\n", shot.c_str());
}

} // namespace
} // namespace fvr::test
