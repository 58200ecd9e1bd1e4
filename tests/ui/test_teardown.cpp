// The workstation closed while its background work runs: a PACS retrieve (C-GET of the
// 140-image Philips series from a real Orthanc, destroyed after the first images came) and the
// polychromatic output's material preprocessing. Neither may crash, hang or let a late result
// land; the interrupted retrieve stays a partial study (never listed as complete) and holds no
// half-written file. And a study opened while the previous one's materials are prepared gets
// its own materials.
#include <QComboBox>
#include <QEventLoop>
#include <QLabel>
#include <QProgressBar>
#include <QPushButton>
#include <QTimer>
#include <QTreeWidget>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include <fvr/core/pacs/local_store.h>
#include <fvr/ui/pacs_dialog.h>
#include <fvr/ui/pacs_service.h>
#include <fvr/ui/pacs_settings.h>
#include <fvr/ui/panels/xray_panel.h>

#include "pacs/orthanc_server.h"
#include "ui/ui_support.h"

using namespace fvr;
namespace fs = std::filesystem;
namespace pacs = fvr::core::pacs;

namespace {

constexpr const char* kOurAe = "FVRDOWN";
constexpr const char* kSeries = "dicom/ct_phantom_philips_512x512x140";

/** Files of a folder tree whose name ends in `suffix`. */
int filesEndingIn(const fs::path& root, const std::string& suffix) {
    int n = 0;
    if (!fs::exists(root)) return 0;
    for (const auto& e : fs::recursive_directory_iterator(root)) {
        const std::string name = e.path().filename().string();
        n += e.is_regular_file() && name.size() >= suffix.size() &&
             name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
    }
    return n;
}

/** Destroys the window; prints how long that took (what a user waits for at close). */
void closeWindow(std::unique_ptr<ui::MainWindow>& w, const char* what) {
    const auto t0 = std::chrono::steady_clock::now();
    w.reset();
    const std::chrono::duration<double, std::milli> ms = std::chrono::steady_clock::now() - t0;
    std::cout << "closed during " << what << " in " << ms.count() << " ms\n";
}

/** The workstation's fixture, for tests that close the window while it works. */
class WorkstationClosing : public test::Workstation {};

} // namespace

TEST_F(WorkstationClosing, ClosedDuringAPacsRetrieveStopsCleanlyAndKeepsAPartialStudy) {
    if (test::OrthancServer::executable().empty())
        GTEST_SKIP() << "Orthanc is not installed (Debian package orthanc)";
    FVR_REQUIRE_DATA(kSeries);
    window.reset(); // this test's own window, with its store in the test's folder
    const fs::path dir =
        test::tmpDir() / ("ui-teardown-" + std::to_string(QCoreApplication::applicationPid()));
    fs::remove_all(dir);
    fs::create_directories(dir / "data");
    qputenv("XDG_DATA_HOME", QByteArray::fromStdString((dir / "data").string()));
    test::OrthancServer orthanc(dir / "orthanc", kOurAe, test::freeLoopbackPort());
    ASSERT_EQ(orthanc.upload(test::sharedData() / kSeries), 140) << orthanc.log();

    ui::PacsSettings s;
    s.nodes = {pacs::Node{"Test PACS", "ORTHANC", "127.0.0.1", orthanc.dicomPort()}};
    s.local.aeTitle = kOurAe;
    s.save();
    window = std::make_unique<ui::MainWindow>();
    window->show();
    const fs::path store = window->pacs().store()->root();
    ui::PacsDialog* d = window->pacsDialog();
    d->reloadSettings();
    d->searchButton()->click();
    ASSERT_TRUE(QTest::qWaitFor([&] { return !d->busy(); }, 60000));
    ASSERT_EQ(d->results()->topLevelItemCount(), 1);
    d->results()->setCurrentItem(d->results()->topLevelItem(0));
    QSignalSpy opened(d, &ui::PacsDialog::openRequested);
    d->retrieveButton()->click();
    { // Back at once when the first image shows (qWaitFor sleeps 10 ms between looks, in which
        // tens of images arrive): the window closes with most of the retrieve still to come.
        QEventLoop firstImage;
        QObject::connect(d->progress(), &QProgressBar::valueChanged, &firstImage, [&](int v) {
            if (v >= 1) firstImage.quit();
        });
        QTimer::singleShot(60000, &firstImage, &QEventLoop::quit);
        firstImage.exec();
    }
    ASSERT_TRUE(d->busy()) << "the retrieve ended before the window closed: "
                           << d->status()->text().toStdString();
    const int received = d->progress()->value();
    std::printf("[ui] window closed after %d of 140 images\n", received);
    EXPECT_LT(received, 140);

    closeWindow(window, "a retrieve"); // cancels it, waits for its worker
    QTest::qWait(200); // anything still queued for the gone window would run (and crash) here
    EXPECT_EQ(opened.count(), 0);
    qunsetenv("XDG_DATA_HOME");

    const auto studies = pacs::LocalStore(store).studies();
    ASSERT_EQ(studies.size(), 1u);
    EXPECT_FALSE(studies[0].complete) << "an interrupted retrieve listed as complete";
    EXPECT_GE(studies[0].instances, received);
    EXPECT_LT(studies[0].instances, 140);
    EXPECT_EQ(filesEndingIn(store, ".part"), 0) << "a half-written file in " << store;
}

TEST_F(WorkstationClosing, ClosedDuringThePolychromaticPreprocessingStopsCleanly) {
    ASSERT_TRUE(test::openAndWait(*window, ui::StudySource::phantom(128)));
    ui::ProjectionView* v = window->views()[0];
    auto* x = window->xrayPanel();
    x->outputCombo()->setCurrentIndex(
        x->outputCombo()->findData(int(ui::XrayOutput::Polychromatic)));
    // The views wait for the material spectra: the job runs in the background now.
    ASSERT_TRUE(v->polychromatic());
    ASSERT_TRUE(v->polychromatic()->spectra.empty());
    closeWindow(window, "the material preprocessing"); // cancels the job, waits for it
    QTest::qWait(200); // its result, or the poll timer, would land on the gone window here
}

// A study opened while the polychromatic output still prepares the previous study's materials:
// the views must get the new study's materials, never the old job's result.
TEST_F(WorkstationClosing, AnotherStudyDuringThePreprocessingGetsItsOwnMaterials) {
    ASSERT_TRUE(test::openAndWait(*window, ui::StudySource::phantom(256)));
    ui::ProjectionView* v = window->views()[0];
    auto* x = window->xrayPanel();
    x->outputCombo()->setCurrentIndex(
        x->outputCombo()->findData(int(ui::XrayOutput::Polychromatic)));
    ASSERT_TRUE(v->polychromatic() && v->polychromatic()->spectra.empty()); // the job runs
    QSignalSpy ready(&window->study(), &ui::StudyController::spectrumReady);
    window->openStudy(ui::StudySource::phantom(40));
    ASSERT_TRUE(ready.wait(60000));
    const core::Dims3 dims = window->study().volume()->dims;
    ASSERT_EQ(dims, (core::Dims3{40, 40, 40}));
    ASSERT_TRUE(QTest::qWaitFor(
        [&] { return v->polychromatic() && !v->polychromatic()->spectra.empty(); }, 120000))
        << window->messages()->toPlainText().toStdString();
    for (const auto& s : v->polychromatic()->spectra) EXPECT_EQ(s->volumeDims, dims);
}

// Closed while Test connection waits for a PACS that accepts the connection and never answers:
// the window must not wait for the network timeout (it froze for all of it: 10 s by default;
// here 300 s, so a close that waits runs into CTest's limit), and the late result, once the
// peer goes, must not reach the gone dialog.
TEST_F(WorkstationClosing, ClosedDuringAnEchoToASilentPacsDoesNotWaitForIt) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof addr;
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    ASSERT_EQ(::listen(fd, 4), 0); // connections queue; nobody answers
    ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len), 0);
    ui::PacsSettings s;
    s.nodes = {pacs::Node{"Silent", "PACS", "127.0.0.1", int(ntohs(addr.sin_port))}};
    s.local.timeoutSeconds = 300;
    s.save();
    ui::PacsDialog* d = window->pacsDialog();
    d->reloadSettings();
    d->echoButton()->click();
    ASSERT_TRUE(d->busy());
    closeWindow(window, "an echo to a silent PACS");
    ::close(fd); // the peer goes: the echo ends now, its result has no dialog to go to
    QTest::qWait(500);
}
