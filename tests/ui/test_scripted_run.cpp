// The workstation driven from the command line (--export-views, --screenshot, --quit): the real
// fvr-workstation binary under the test's X display. Its exports are checked against fvr-render
// (the same view, kernel, size and spectrum: an independent program and renderer), the display
// window's mapping and the window's size.
#include <QFile>
#include <QImage>
#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>

#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include <fvr/core/io/image_io.h>
#include <fvr/core/xray/display_window.h>

#include "image_metrics.h"
#include "test_support.h"

namespace {
namespace fs = std::filesystem;
using fvr::test::CommandOutput;

/** Runs the workstation with `args`, its settings in a fresh folder (no user's saved settings);
 *  `out` gets its stderr. `guard` goes before the binary (e.g. a timeout). */
CommandOutput runWorkstation(const std::string& args, const fs::path& scratch,
                             const std::string& guard = {}) {
    const fs::path config = scratch / "config";
    fs::remove_all(config);
    fs::create_directories(config);
    std::string cmd = "XDG_CONFIG_HOME='";
    cmd += config.string();
    cmd += "' QT_QPA_PLATFORM=xcb " + guard + " '";
    cmd += FVR_WORKSTATION_EXE;
    cmd += "' --script-timeout 120 "; // a hang ends with a message, before CTest's timeout
    cmd += args;
    cmd += " 2>&1 >/dev/null";
    return fvr::test::runCommand(cmd);
}

QJsonObject readJson(const fs::path& path) {
    QFile f(QString::fromStdString(path.string()));
    if (!f.open(QIODevice::ReadOnly)) return {};
    return QJsonDocument::fromJson(f.readAll()).object();
}

std::vector<float> readImage(const fs::path& path, std::vector<std::int64_t>& shape) {
    shape.clear();
    if (!fs::exists(path)) return {};
    return fvr::core::readNpy(path, shape);
}

TEST(ScriptedRun, ExportsEveryViewAsShownAndQuits) {
    const fs::path dir = fvr::test::tmpDir() / "scripted_run";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path views = dir / "views";
    const fs::path shot = dir / "window.png";
    const CommandOutput r =
        runWorkstation("phantom:shepp-logan:64 --compare 2 --kernel catmull-rom --voxel-model "
                       "trilinear,bandlimited --size 128 --window-size "
                       "1100x1050 --export-views '" +
                           views.string() + "' --screenshot '" + shot.string() + "' --quit",
                       dir);
    ASSERT_EQ(r.status, 0) << r.out;

    // views.json: two views, view 1 with the kernel and size asked for.
    const QJsonObject info = readJson(views / "views.json");
    const QJsonArray list = info["views"].toArray();
    ASSERT_EQ(list.size(), 2) << QJsonDocument(info).toJson().toStdString();
    const QJsonObject v1 = list[0].toObject();
    EXPECT_EQ(v1["kernel"].toString(), "catmull-rom");
    EXPECT_EQ(v1["size"].toInt(), 128);
    EXPECT_EQ(list[1].toObject()["kernel"].toString(), "linear"); // compare mode's second kernel
    EXPECT_EQ(list[1].toObject()["size"].toInt(), 128); // --size: every view
    EXPECT_EQ(v1["voxelModel"].toString(), "trilinear"); // --voxel-model: one per view
    EXPECT_EQ(list[1].toObject()["voxelModel"].toString(), "bandlimited");
    EXPECT_TRUE(info["study"].toString().contains("phantom"));
    const QJsonObject spectrum = info["spectrum"].toObject();
    // Gridding correction stays on in compare mode: view 1's kernel has the main spectrum.
    EXPECT_EQ(spectrum["deapodizedFor"].toString(), "catmull-rom");

    std::vector<std::int64_t> shape;
    for (const char* name : {"view1.npy", "view2.npy"}) {
        EXPECT_EQ(readImage(views / name, shape).size(), 128u * 128u) << name;
        EXPECT_EQ(shape, (std::vector<std::int64_t>{128, 128})) << name;
    }
    const std::vector<float> view1 = readImage(views / "view1.npy", shape);
    ASSERT_EQ(view1.size(), 128u * 128u);

    // fvr-render: the same study, view (AP, the workstation's first view), kernel, size and
    // spectrum (values, transform, oversampling as views.json reports them), on the CPU.
    const fs::path ref = dir / "render.npy";
    std::string args = "phantom:shepp-logan:64 --view AP --kernel catmull-rom --size 128 ";
    args += "--deapodize on --values " + spectrum["values"].toString().toStdString();
    args += " --transform " + spectrum["transform"].toString().toStdString();
    args += " --oversampling " + std::to_string(spectrum["oversampling"].toDouble());
    args += " --out '" + ref.string() + "'";
    const CommandOutput cli =
        fvr::test::runCommand(std::string(FVR_RENDER_EXE) + " " + args + " 2>&1");
    ASSERT_EQ(cli.status, 0) << cli.out;
    const std::vector<float> expected = readImage(ref, shape);
    ASSERT_EQ(expected.size(), view1.size());
    const auto cmp = fvr::test::compare(view1, expected);
    std::printf("[scripted] view 1 vs fvr-render: PSNR %.1f dB, rel. RMSE %.2e (%s)\n", cmp.psnr,
                cmp.relRmse, v1["backend"].toString().toStdString().c_str());
    EXPECT_GT(cmp.psnr, 100.0); // measured 149 dB (Mesa llvmpipe against the CPU renderer)

    // view1.png: the projection through the view's window (DisplayWindow::map), row 0 at the top.
    const QJsonObject w = v1["window"].toObject();
    const fvr::core::DisplayWindow window{w["low"].toDouble(), w["high"].toDouble(),
                                          w["invert"].toBool()};
    ASSERT_LT(window.low, window.high);
    const QImage png(QString::fromStdString((views / "view1.png").string()));
    ASSERT_EQ(png.size(), QSize(128, 128));
    int worst = 0, distinct = 0, last = -1;
    for (int y = 0; y < 128; ++y)
        for (int x = 0; x < 128; ++x) {
            const int grey = qGray(png.pixel(x, y));
            const int want = int(std::lround(255.0 * window.map(view1[std::size_t(y) * 128 + x])));
            worst = std::max(worst, std::abs(grey - want));
            distinct += grey != last;
            last = grey;
        }
    EXPECT_LE(worst, 1);
    EXPECT_GT(distinct, 500); // an image, not a flat field

    // The screenshot: the whole window at its size, with the views' images in it (the skull's
    // white ring in view 1, left of the docks and below the toolbar).
    const QImage window_shot(QString::fromStdString(shot.string()));
    ASSERT_FALSE(window_shot.isNull());
    const QJsonArray size = info["windowSize"].toArray();
    EXPECT_EQ(window_shot.size(), QSize(size[0].toInt(), size[1].toInt()));
    EXPECT_EQ(window_shot.size(), QSize(1100, 1050)); // --window-size
    int white = 0;
    for (int y = 80; y < 600 && y < window_shot.height(); ++y)
        for (int x = 0; x < 250 && x < window_shot.width(); ++x)
            white += qGray(window_shot.pixel(x, y)) >= 250;
    EXPECT_GT(white, 50);
    // The views' overlays are in the screenshot (QWidget::grab alone lost them): view 1's green
    // overlay text in its top-left corner.
    int green = 0;
    for (int y = 60; y < 160 && y < window_shot.height(); ++y) // below the toolbar
        for (int x = 0; x < 300 && x < window_shot.width(); ++x) {
            const QColor c = window_shot.pixelColor(x, y);
            green += c.green() > 200 && c.red() < 180 && c.blue() < 180;
        }
    EXPECT_GT(green, 30);
}

// The same study with nothing chosen renders to the same image in the workstation and fvr-render
// (and, tests/python, the Python module): one set of defaults, core::RenderSettings.
TEST(ScriptedRun, DefaultSettingsRenderWhatFvrRenderRenders) {
    const fs::path dir = fvr::test::tmpDir() / "scripted_run_defaults";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path views = dir / "views";
    const CommandOutput r = runWorkstation(
        "phantom:shepp-logan:64 --size 128 --export-views '" + views.string() + "' --quit", dir);
    ASSERT_EQ(r.status, 0) << r.out;
    const QJsonObject info = readJson(views / "views.json");
    EXPECT_EQ(info["views"].toArray()[0].toObject()["kernel"].toString(), "kaiser-bessel4");
    const fs::path ref = dir / "render.npy";
    const CommandOutput cli = fvr::test::runCommand(std::string(FVR_RENDER_EXE) +
                                                    " phantom:shepp-logan:64 --size 128 --out '" +
                                                    ref.string() + "' 2>&1");
    ASSERT_EQ(cli.status, 0) << cli.out;
    std::vector<std::int64_t> shape;
    const std::vector<float> view1 = readImage(views / "view1.npy", shape);
    const std::vector<float> expected = readImage(ref, shape);
    ASSERT_EQ(view1.size(), 128u * 128u);
    ASSERT_EQ(expected.size(), view1.size());
    const auto cmp = fvr::test::compare(view1, expected);
    std::printf("[scripted] defaults: workstation view 1 vs fvr-render PSNR %.1f dB (%s)\n",
                cmp.psnr,
                info["views"].toArray()[0].toObject()["backend"].toString().toStdString().c_str());
    EXPECT_GT(cmp.psnr, 100.0); // GPU or CPU in either: float rounding apart, no more
}

// The first image (no study named) is the built-in chest phantom, at a window that shows its
// anatomy: the lung fields clearly darker than the mediastinum and spine between them.
TEST(ScriptedRun, FirstImageIsAChestRadiographShowingItsAnatomy) {
    const fs::path dir = fvr::test::tmpDir() / "scripted_run_first";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path views = dir / "views";
    const CommandOutput r =
        runWorkstation("--size 256 --export-views '" + views.string() + "' --quit", dir);
    ASSERT_EQ(r.status, 0) << r.out;
    const QJsonObject info = readJson(views / "views.json");
    EXPECT_TRUE(info["study"].toString().contains("Chest"))
        << info["study"].toString().toStdString();
    std::vector<std::int64_t> shape;
    const std::vector<float> p = readImage(views / "view1.npy", shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{256, 256}));
    const QImage png(QString::fromStdString((views / "view1.png").string()));
    ASSERT_EQ(png.size(), QSize(256, 256));
    // The body's extent in the projection.
    float peak = 0;
    for (float v : p) peak = std::max(peak, v);
    int x0 = 256, x1 = -1, y0 = 256, y1 = -1;
    for (int y = 0; y < 256; ++y)
        for (int x = 0; x < 256; ++x)
            if (p[std::size_t(y) * 256 + x] > 0.1f * peak) {
                x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y),
                y1 = std::max(y1, y);
            }
    ASSERT_GT(x1 - x0, 60);
    // Mid-chest row: the mediastinum in the middle, a lung field a quarter of the width out on
    // either side (grey levels as displayed).
    const int y = y0 + (y1 - y0) * 2 / 5, xc = (x0 + x1) / 2, dx = (x1 - x0) / 4;
    auto grey = [&](int x) {
        int sum = 0;
        for (int k = -2; k <= 2; ++k) sum += qGray(png.pixel(x + k, y));
        return sum / 5;
    };
    const int middle = grey(xc), right = grey(xc - dx), left = grey(xc + dx);
    std::printf("[scripted] first image: mediastinum %d, lung fields %d and %d (grey levels)\n",
                middle, right, left);
    EXPECT_GT(middle - right, 60);
    EXPECT_GT(middle - left, 60);
}

// A folder of several series: nobody to ask, so the default series opens (as fvr-render's),
// instead of a dialog waiting until the timeout.
TEST(ScriptedRun, SeveralSeriesOpenTheDefaultOne) {
    FVR_REQUIRE_DATA("dicom_edge/enhanced_multiframe_mr");
    const fs::path dir = fvr::test::tmpDir() / "scripted_run_series";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path study = fvr::test::sharedData() / "dicom_edge/enhanced_multiframe_mr";
    std::string args = "'";
    args += study.string();
    args += "' --size 128 --export-views '";
    args += (dir / "views").string();
    args += "' --quit";
    const CommandOutput r = runWorkstation(args, dir);
    ASSERT_EQ(r.status, 0) << r.out;
    std::vector<std::int64_t> shape;
    EXPECT_EQ(readImage(dir / "views" / "view1.npy", shape).size(), 128u * 128u);
}

TEST(ScriptedRun, FailedStudyExitsNonZeroNamingThePath) {
    const fs::path dir = fvr::test::tmpDir() / "scripted_run_failed";
    fs::create_directories(dir);
    const std::string missing = (dir / "no_such_study.mhd").string();
    const CommandOutput r = runWorkstation(
        "'" + missing + "' --export-views '" + (dir / "out").string() + "' --quit", dir);
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.out.find("fvr-workstation: "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(missing), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir / "out" / "views.json"));
}

// A FIFO as the study once hung the workstation for good, past its --script-timeout: the path
// was classified on the GUI thread, by opening the FIFO, before the timeout's timer started.
TEST(ScriptedRun, AFifoStudyFailsAtOnceNamingIt) {
    const fs::path dir = fvr::test::tmpDir() / "scripted_run_fifo";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path fifo = dir / "study.nii.gz";
    ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
    // The guard kills a regression (status 137) instead of hanging the suite.
    std::string args = "'";
    args += fifo.string();
    args += "' --script-timeout 20 --export-views '";
    args += (dir / "out").string();
    args += "' --quit";
    const CommandOutput r = runWorkstation(args, dir, "timeout -s KILL 90");
    EXPECT_EQ(r.status, 1) << r.out;
    EXPECT_NE(r.out.find(fifo.string() + ": a FIFO (named pipe), not a regular file"),
              std::string::npos)
        << r.out;
    EXPECT_FALSE(fs::exists(dir / "out" / "views.json"));
}

} // namespace

namespace {

TEST(ScriptedRun, ASessionFromTheCommandLineShowsItsStudyViewsAndWindows) {
    const fs::path dir = fvr::test::tmpDir() / "scripted_session";
    fs::remove_all(dir);
    fs::create_directories(dir);
    // A session as File ▸ Save session writes one (INI): two views, view 2 linear, a window.
    const fs::path session = dir / "two.fvrsession";
    {
        std::ofstream f(session);
        f << "[session]\nformat=1\n[study]\nsource=phantom:shepp-logan:64\n"
          << "[workstation]\ncompareCount=2\n"
          << "[view1]\nrender\\kernel=catmull-rom\nrender\\size=128\nwindow\\low=2\n"
          << "window\\high=40\n[view2]\nrender\\kernel=linear\nrender\\size=128\n"
          << "window\\low=2\nwindow\\high=40\n";
    }
    const fs::path views = dir / "views";
    const CommandOutput r = runWorkstation("--open-session '" + session.string() +
                                               "' --export-views '" + views.string() + "' --quit",
                                           dir);
    ASSERT_EQ(r.status, 0) << r.out;
    const QJsonObject info = readJson(views / "views.json");
    const QJsonArray list = info["views"].toArray();
    ASSERT_EQ(list.size(), 2) << QJsonDocument(info).toJson().toStdString();
    EXPECT_EQ(list[0].toObject()["kernel"].toString(), "catmull-rom");
    EXPECT_EQ(list[1].toObject()["kernel"].toString(), "linear");
    EXPECT_EQ(list[1].toObject()["size"].toInt(), 128);
    EXPECT_DOUBLE_EQ(list[0].toObject()["window"].toObject()["low"].toDouble(), 2.0);
    EXPECT_DOUBLE_EQ(list[0].toObject()["window"].toObject()["high"].toDouble(), 40.0);
    EXPECT_TRUE(info["study"].toString().contains("Shepp-Logan"));

    // Not a session: exit 1, naming the file.
    const fs::path bad = dir / "bad.fvrsession";
    std::ofstream(bad) << "hello\n";
    const CommandOutput b = runWorkstation("--open-session '" + bad.string() + "' --quit", dir);
    EXPECT_EQ(b.status, 1) << b.out;
    EXPECT_NE(b.out.find(bad.string()), std::string::npos) << b.out;
}

} // namespace
