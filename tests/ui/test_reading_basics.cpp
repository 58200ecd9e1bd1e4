// The workstation's small reading basics: --view on the command line is for its own study only;
// the status bar's message stops before the renderer label; nothing exports without a study;
// the series chooser names the patient, warns of a folder that mixes patients and labels a
// series without description readably; --help needs no display; the window fits a small
// (high scale factor) screen; the view keys act without a click into the view; and a DICOM
// export carries the window the user sees.
#include <QAction>
#include <QDockWidget>
#include <QImage>
#include <QLabel>
#include <QScreen>
#include <QStatusBar>

#include <cmath>
#include <filesystem>
#include <unistd.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include "ui_support.h"
#include "workstation_options.h"

namespace fvr::test {
namespace {

namespace fs = std::filesystem;

/** Whether two view frames look the same way with the same up. */
bool sameFrame(const core::ViewFrame& a, const core::ViewFrame& b) {
    return glm::length(a.d - b.d) < 1e-9 && glm::length(a.u - b.u) < 1e-9;
}

TEST_F(Workstation, CommandLineViewIsForTheFirstStudyOnly) {
    app::WorkstationOptions o;
    o.view = core::PatientView::Left;
    app::applyWorkstationOptions(*window, o);
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    const auto first = window->study().volume();
    EXPECT_TRUE(sameFrame(window->views()[0]->viewFrame(),
                          core::patientViewFrame(*first, core::PatientView::Left)));
    // A study opened later starts at the default view, as without the option.
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    const auto second = window->study().volume();
    ASSERT_NE(first, second);
    EXPECT_TRUE(sameFrame(window->views()[0]->viewFrame(),
                          core::patientViewFrame(*second, core::RenderSettings{}.view)));
}

TEST_F(Workstation, StatusBarMessageStopsBeforeTheRendererLabel) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    QLabel* renderer = nullptr;
    for (QLabel* l : window->statusBar()->findChildren<QLabel*>())
        if (l->text().startsWith("Renderer")) renderer = l;
    ASSERT_TRUE(renderer);
    ASSERT_TRUE(renderer->isVisible());
    // A long message, as a deep path makes one: an export that fails names its file.
    const QString path = "/no/such/dir/" + QString(400, 'x') + ".npy";
    EXPECT_FALSE(window->exportProjection(path));
    const QString shown = window->statusBar()->currentMessage();
    const int width = window->statusBar()->fontMetrics().horizontalAdvance(shown);
    // The message's right end, from the status bar's left: a gap before the label's left edge.
    EXPECT_LE(width + 8, renderer->x()) << shown.toStdString();
    EXPECT_TRUE(shown.endsWith(QChar(0x2026))) << shown.toStdString(); // elided: "…"
    EXPECT_TRUE(window->messages()->toPlainText().contains(path)); // the whole text stays
}

/** The File menu's export items (and Send to PACS). */
QList<QAction*> exportActions(MainWindow& w) {
    QList<QAction*> out;
    for (QAction* a : w.findChildren<QAction*>())
        if (a->text().startsWith("Export") || a->text().startsWith("&Copy view") ||
            a->text().startsWith("Send projection"))
            out << a;
    return out;
}

TEST_F(Workstation, ExportItemsAreDisabledWithoutAStudy) {
    const QList<QAction*> actions = exportActions(*window);
    ASSERT_EQ(actions.size(), 5); // screenshot, projection, sweep, clipboard, PACS
    for (QAction* a : actions) EXPECT_FALSE(a->isEnabled()) << a->text().toStdString();
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    for (QAction* a : actions) EXPECT_TRUE(a->isEnabled()) << a->text().toStdString();
}

TEST(SeriesChooser, LabelsASeriesWithoutDescriptionReadablyAndNamesThePatient) {
    app();
    core::DicomSeriesInfo s;
    s.seriesUid = s.key = "1.2.840.113619.2.55.3.604688119";
    s.patientName = "DOE^JANE";
    s.patientId = "ID42";
    s.modality = "CT";
    s.studyDate = "20150206";
    s.seriesNumber = "3";
    s.imageCount = s.frameCount = 28;
    s.dims = {512, 512, 28};
    const QString label = ui::StudyController::seriesChoiceLabel(s);
    EXPECT_FALSE(label.contains("1.2.840")) << label.toStdString();
    EXPECT_TRUE(label.contains("series 3, 28 slices")) << label.toStdString();
    EXPECT_TRUE(label.contains("DOE JANE (ID42)")) << label.toStdString();
    EXPECT_TRUE(label.contains("CT")) << label.toStdString();
    s.description = "HEAD 5mm";
    EXPECT_TRUE(ui::StudyController::seriesChoiceLabel(s).contains("series 3: HEAD 5mm"));
    core::DicomScanResult scan;
    scan.series = {s, s};
    QString prompt = ui::StudyController::seriesChoicePrompt("/data/x", scan);
    EXPECT_TRUE(prompt.contains("DOE JANE (ID42)")) << prompt.toStdString();
    EXPECT_FALSE(prompt.contains("mixes")) << prompt.toStdString();
    scan.series[1].patientName = "ROE^RICHARD";
    scan.series[1].patientId = "ID7";
    prompt = ui::StudyController::seriesChoicePrompt("/data/x", scan);
    EXPECT_TRUE(prompt.contains("mixes patients")) << prompt.toStdString();
    EXPECT_TRUE(prompt.contains("2 different patients")) << prompt.toStdString();
    EXPECT_TRUE(prompt.contains("ROE RICHARD (ID7)")) << prompt.toStdString();
}

TEST(SeriesChooser, AFolderOfTwoPatientsWarnsInTheChooser) {
    app();
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    FVR_REQUIRE_DATA("dicom/ct_head_ge_gantrytilt_28");
    // Two real series of two patients in one folder (links to the files).
    const fs::path dir = tmpDir() / ("two_patients_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    for (const char* series : {"ct_head_slicer_64x64x93", "ct_head_ge_gantrytilt_28"}) {
        fs::create_directories(dir / series);
        for (const auto& e : fs::directory_iterator(sharedData() / "dicom" / series))
            fs::create_symlink(e.path(), dir / series / e.path().filename());
    }
    ui::StudyController study;
    QSignalSpy choice(&study, &ui::StudyController::seriesChoiceNeeded);
    study.open(StudySource::fromPath(QString::fromStdString(dir.string())));
    ASSERT_TRUE(choice.wait(60000));
    const QStringList labels = choice.first().at(2).toStringList();
    const QString prompt = choice.first().at(3).toString();
    // The names in the files (dcmdump): "Austrialian" (8775070) and "REMOVED" (QMNx85rKkkg).
    EXPECT_TRUE(prompt.contains("mixes patients")) << prompt.toStdString();
    EXPECT_TRUE(prompt.contains("Austrialian (8775070)")) << prompt.toStdString();
    EXPECT_TRUE(prompt.contains("REMOVED (QMNx85rKkkg)")) << prompt.toStdString();
    ASSERT_EQ(labels.size(), 2);
    // The GE series has no description: its number and slices, not its UID.
    const QString ge = labels.filter("REMOVED").value(0);
    EXPECT_TRUE(ge.contains("series 2, 28 slices")) << ge.toStdString();
    EXPECT_FALSE(ge.contains("1.2.")) << ge.toStdString();
    fs::remove_all(dir);
}

TEST(WorkstationCommandLine, HelpNeedsNoDisplay) {
    // No X server at all: the help is printed, no abort ("could not connect to display").
    const auto r =
        runCommand(std::string("env -u DISPLAY -u WAYLAND_DISPLAY QT_QPA_PLATFORM=xcb ") +
                   FVR_WORKSTATION_EXE + " --help 2>&1");
    EXPECT_EQ(r.status, 0) << r.out;
    EXPECT_NE(r.out.find("Usage:"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("--view"), std::string::npos) << r.out;
    const auto v =
        runCommand(std::string("env -u DISPLAY -u WAYLAND_DISPLAY QT_QPA_PLATFORM=xcb ") +
                   FVR_WORKSTATION_EXE + " --version 2>&1");
    EXPECT_EQ(v.status, 0) << v.out;
}

TEST_F(Workstation, WindowFitsAScreenOf960By540) {
    // QT_SCALE_FACTOR=2 on a 1920 x 1080 screen leaves 960 x 540 in the window's units, less
    // the task bar: the window's smallest size and its size must fit there.
    const QSize available(960, 500);
    const QSize before = window->minimumSizeHint().expandedTo(window->minimumSize());
    window->fitInto(available);
    QTest::qWait(50); // the layout settles
    const QSize smallest = window->minimumSizeHint().expandedTo(window->minimumSize());
    EXPECT_LE(smallest.width(), available.width()) << before.width() << " before";
    EXPECT_LE(smallest.height(), available.height()) << before.height() << " before";
    EXPECT_LE(window->width(), available.width());
    EXPECT_LE(window->height(), available.height());
    // Every panel is still there, as a tab.
    for (const char* name : {"dock.study", "dock.rendering", "dock.display", "dock.messages"}) {
        auto* d = window->findChild<QDockWidget*>(name);
        ASSERT_TRUE(d) << name;
        EXPECT_FALSE(d->isHidden()) << name;
    }
    // The first size without saved geometry: at most the screen's free area.
    QScreen* screen = QGuiApplication::primaryScreen();
    ASSERT_TRUE(screen);
    const QSize first = MainWindow::defaultWindowSize(screen);
    EXPECT_LE(first.width(), screen->availableGeometry().width());
    EXPECT_LE(first.height(), screen->availableGeometry().height());
    EXPECT_EQ(MainWindow::defaultWindowSize(nullptr), QSize(1400, 900));
}

TEST(WorkstationCommandLine, OpensWithinAFullHdScreenAtScaleFactorTwo) {
    if (runCommand("command -v xvfb-run").status != 0) GTEST_SKIP() << "xvfb-run is missing";
    // A screen of its own, 1920 x 1080, and QT_SCALE_FACTOR=2: the window's screenshot (in
    // the screen's pixels) fits it.
    const fs::path dir = tmpDir() / ("scale2_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir / "config");
    const fs::path shot = dir / "window.png";
    const auto r =
        runCommand("xvfb-run -a -s '-screen 0 1920x1080x24' env XDG_CONFIG_HOME='" +
                   (dir / "config").string() + "' QT_SCALE_FACTOR=2 QT_QPA_PLATFORM=xcb '" +
                   FVR_WORKSTATION_EXE + "' --script-timeout 120 --screenshot '" + shot.string() +
                   "' --quit 2>&1");
    ASSERT_EQ(r.status, 0) << r.out;
    const QImage image(QString::fromStdString(shot.string()));
    ASSERT_FALSE(image.isNull()) << r.out;
    EXPECT_LE(image.width(), 1920);
    EXPECT_LE(image.height(), 1080);
    EXPECT_GE(image.width(), 960); // it is the scaled window, not a thumbnail
    fs::remove_all(dir);
}

TEST_F(Workstation, ViewKeysWorkWithoutAClickIntoTheView) {
    // As fvr-workstation starts: shown, then the command line's compare count (which makes the
    // views anew) before the window is active; the keyboard focus is then wherever Qt puts it.
    window.reset();
    auto w = std::make_unique<MainWindow>();
    w->resize(1200, 800);
    w->show();
    w->setCompareCount(1);
    ASSERT_TRUE(openAndWait(*w, StudySource::phantom(48)));
    // The window becomes active (again) after the views were made anew: the window manager's
    // activation at start, or the user coming back from another window.
    const auto activate = [&] {
        QApplication::processEvents(); // views made anew are deleted
        QWidget other;
        other.show();
        other.activateWindow();
        ASSERT_TRUE(QTest::qWaitForWindowActive(&other));
        w->activateWindow();
        ASSERT_TRUE(QTest::qWaitForWindowActive(w.get()));
    };
    const auto volume = w->study().volume();
    const std::pair<Qt::Key, core::PatientView> keys[] = {{Qt::Key_3, core::PatientView::Left},
                                                          {Qt::Key_2, core::PatientView::PA}};
    for (const auto& [key, view] : keys) {
        activate();
        // The key goes where the keyboard focus is, as a user's would.
        QWidget* focus = QApplication::focusWidget();
        QTest::keyClick(focus ? focus : w.get(), key);
        EXPECT_TRUE(sameFrame(w->views()[0]->viewFrame(), core::patientViewFrame(*volume, view)))
            << "focus on " << (focus ? focus->metaObject()->className() : "nothing");
        // And after the compare mode changed from the toolbar.
        w->setCompareCount(2);
        w->setCompareCount(1);
    }
}

TEST_F(Workstation, DicomExportCarriesTheWindowTheUserSees) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    core::DisplayWindow w = window->views()[0]->window();
    w.low = 1.5;
    w.high = 9.5;
    window->views()[0]->setWindow(w);
    const auto path = tmpDir() / "ui-window.dcm";
    fs::remove(path);
    ASSERT_TRUE(window->exportProjection(QString::fromStdString(path.string())));
    DcmFileFormat file;
    ASSERT_TRUE(file.loadFile(path.c_str()).good());
    Float64 centre = 0, width = 0;
    file.getDataset()->findAndGetFloat64(DCM_WindowCenter, centre);
    file.getDataset()->findAndGetFloat64(DCM_WindowWidth, width);
    EXPECT_NEAR(centre, 5.5, 1e-9);
    EXPECT_NEAR(width, 8.0, 1e-9);
    // A second export is a series of its own.
    const auto again = tmpDir() / "ui-window-2.dcm";
    ASSERT_TRUE(window->exportProjection(QString::fromStdString(again.string())));
    DcmFileFormat second;
    ASSERT_TRUE(second.loadFile(again.c_str()).good());
    OFString a, b;
    file.getDataset()->findAndGetOFString(DCM_SeriesNumber, a);
    second.getDataset()->findAndGetOFString(DCM_SeriesNumber, b);
    EXPECT_NE(a, b);
}

} // namespace
} // namespace fvr::test
