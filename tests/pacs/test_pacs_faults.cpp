// A PACS that stops answering (SIGSTOP) or dies (SIGKILL) before or in the middle of each DIMSE
// operation: every call ends within its timeout + 1 s of the fault, and says what happened in
// words ("stopped answering", "the connection was lost"), never an unknown status or a guess
// about our AE title. The times are printed (a contract of the API, asserted with a margin,
// not a speed test).
#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>

#include "pacs_environment.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace fvr::core;
using namespace fvr::core::pacs;
using fvr::test::OrthancServer;
using fvr::test::PacsEnvironment;

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kTimeout = 2; // s: short, the tests wait for it

PacsEnvironment& env() { return PacsEnvironment::get(); }

LocalAe shortTimeout() {
    LocalAe l = env().local();
    l.timeoutSeconds = kTimeout;
    return l;
}

Node moveNode(Node n) {
    n.retrieve = RetrieveMethod::Move;
    return n;
}

std::string philipsStudy() {
    return fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kPhilips), "StudyInstanceUID");
}

/** How a call ended: its PacsError's message ("" when it did not throw one) and the seconds
 *  from the fault (or from the call, when the fault came first) to its end. */
struct Outcome {
    std::string message;
    double seconds = 0;
};

/** Runs `call`; `faultAt` is the moment of the fault, set by the call's progress callback
 *  (left at the call's start when the fault came before it). */
template <class F>
Outcome timed(const char* what, Clock::time_point& faultAt, F&& call) {
    Outcome o;
    faultAt = Clock::now();
    try {
        call();
    } catch (const PacsError& e) {
        o.message = e.what();
    }
    o.seconds = std::chrono::duration<double>(Clock::now() - faultAt).count();
    std::printf("[ timing   ] %s: %.2f s after the fault (timeout %d s): %s\n", what, o.seconds,
                kTimeout, o.message.c_str());
    std::fflush(stdout);
    return o;
}

/** The words a frozen PACS must get, and the ones it must not. */
void expectStoppedAnswering(const Outcome& o) {
    EXPECT_NE(o.message.find("stopped answering (no reply within 2 s)"), std::string::npos)
        << o.message;
    EXPECT_EQ(o.message.find("0xffff"), std::string::npos) << o.message;
    EXPECT_EQ(o.message.find("Unknown Status"), std::string::npos) << o.message;
    EXPECT_EQ(o.message.find("AE title"), std::string::npos) << o.message;
    EXPECT_LE(o.seconds, kTimeout + 1.0); // the contract: the timeout + 1 s
}

/** Thaws the shared Orthanc however the test ends, and checks that it answers again. */
struct ThawAfter {
    ~ThawAfter() {
        env().orthanc().cont();
        EXPECT_NO_THROW(echo(env().node(), env().local()));
    }
};

/** Freezes `orthanc` once `p` has 10 images: mid-transfer, at a known point. */
auto freezeAtTen(const OrthancServer& orthanc, Clock::time_point& faultAt) {
    return [&orthanc, &faultAt, done = false](const RetrieveProgress& p) mutable {
        if (!done && p.received >= 10) {
            orthanc.stop();
            faultAt = Clock::now();
            done = true;
        }
    };
}

} // namespace

TEST(PacsFaults, EchoToAFrozenPacs) {
    FVR_REQUIRE_ORTHANC();
    ThawAfter thaw;
    env().orthanc().stop();
    Clock::time_point at;
    expectStoppedAnswering(
        timed("C-ECHO, frozen before", at, [&] { echo(env().node(), shortTimeout()); }));
}

TEST(PacsFaults, FindOnAFrozenPacs) {
    FVR_REQUIRE_ORTHANC();
    ThawAfter thaw;
    env().orthanc().stop();
    Clock::time_point at;
    expectStoppedAnswering(timed("C-FIND studies, frozen before", at,
                                 [&] { findStudies(env().node(), shortTimeout(), {}); }));
    expectStoppedAnswering(timed("C-FIND series, frozen before", at, [&] {
        findSeries(env().node(), shortTimeout(), philipsStudy());
    }));
}

/** A retrieve of the Philips CT by `node`'s method, Orthanc frozen once 10 images came: it
 *  stops within the timeout + 1 s, saying the PACS stopped answering, and stays partial. */
void retrieveFrozenAtTen(const Node& node, const char* what, const std::string& storeName) {
    ThawAfter thaw;
    LocalStore store(fvr::test::storeRoot(storeName));
    Clock::time_point at;
    const Outcome o = timed(what, at, [&] {
        retrieve(node, shortTimeout(), philipsStudy(), "", store, freezeAtTen(env().orthanc(), at));
    });
    expectStoppedAnswering(o);
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_FALSE(entry->complete);
}

TEST(PacsFaults, GetFromAPacsFrozenMidTransfer) {
    FVR_REQUIRE_ORTHANC();
    retrieveFrozenAtTen(env().node(), "C-GET, frozen at 10 images", "fault-get");
}

TEST(PacsFaults, MoveFromAPacsFrozenMidTransfer) {
    FVR_REQUIRE_ORTHANC();
    retrieveFrozenAtTen(moveNode(env().node()), "C-MOVE, frozen at 10 images", "fault-move");
}

TEST(PacsFaults, StoreToAFrozenPacs) {
    FVR_REQUIRE_ORTHANC();
    ThawAfter thaw;
    ProjectionImage img;
    img.width = img.height = 16;
    img.pixelSize = 1.0;
    img.pixels.assign(16 * 16, 1.0f);
    const fs::path file = env().dir / "fault-send.dcm";
    writeDicomProjection(file, img, {"FAULT^SEND", "FAULT1", "", "FVR fault test", "mm"});
    env().orthanc().stop();
    Clock::time_point at;
    expectStoppedAnswering(timed("C-STORE, frozen before", at,
                                 [&] { sendFiles(env().node(), shortTimeout(), {file}); }));
}

/** Copies of `n` Philips images with new SOP instance UIDs (new to Orthanc: its instance count
 *  tells how many arrived). */
std::vector<fs::path> freshCopies(const fs::path& dir, int n) {
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::vector<fs::path> out;
    for (const auto& f : fs::directory_iterator(fvr::test::sharedData() / fvr::test::kPhilips)) {
        if (int(out.size()) == n) break;
        DcmFileFormat file;
        if (file.loadFile(f.path().c_str()).bad()) continue;
        char uid[100];
        dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT);
        file.getDataset()->putAndInsertString(DCM_SOPInstanceUID, uid);
        file.getMetaInfo()->putAndInsertString(DCM_MediaStorageSOPInstanceUID, uid);
        out.push_back(dir / f.path().filename());
        file.saveFile(out.back().c_str());
    }
    return out;
}

int orthancInstances() {
    const auto r = env().orthanc().get("/statistics");
    return r.status == 200 ? nlohmann::json::parse(r.body)["CountInstances"].get<int>() : -1;
}

TEST(PacsFaults, StoreToAPacsFrozenMidTransfer) {
    FVR_REQUIRE_ORTHANC();
    ThawAfter thaw;
    const auto files = freshCopies(env().dir / "fault-send-many", 40);
    ASSERT_EQ(files.size(), 40u);
    const int before = orthancInstances();
    Clock::time_point at = Clock::now();
    std::atomic<bool> frozen{false}, done{false};
    std::thread watcher([&] { // freezes Orthanc once 5 of the 40 arrived
        while (!done && orthancInstances() < before + 5)
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        if (done) return;
        env().orthanc().stop();
        at = Clock::now();
        frozen = true;
    });
    Outcome o;
    try {
        sendFiles(env().node(), shortTimeout(), files);
    } catch (const PacsError& e) {
        o.message = e.what();
    }
    const auto end = Clock::now();
    done = true;
    watcher.join();
    ASSERT_TRUE(frozen) << "all 40 arrived before the freeze";
    o.seconds = std::chrono::duration<double>(end - at).count();
    std::printf("[ timing   ] C-STORE of 40, frozen at 5: %.2f s after the fault (timeout %d s): "
                "%s\n",
                o.seconds, kTimeout, o.message.c_str());
    std::fflush(stdout);
    expectStoppedAnswering(o);
}

/** A second Orthanc with 30 images of the Philips study, to be killed. */
class PacsKill : public ::testing::Test {
protected:
    void SetUp() override {
        FVR_REQUIRE_ORTHANC();
        m_orthanc = std::make_unique<OrthancServer>(env().dir / "killable", fvr::test::kOurAe,
                                                    env().local().listenPort);
        const fs::path some = env().dir / "killable-input";
        fs::create_directories(some);
        int n = 0;
        for (const auto& f : fs::directory_iterator(fvr::test::sharedData() / fvr::test::kPhilips))
            if (n++ < 30)
                fs::copy_file(f.path(), some / f.path().filename(),
                              fs::copy_options::overwrite_existing);
        ASSERT_EQ(m_orthanc->upload(some), 30) << m_orthanc->log();
    }

    Node node() const {
        Node n = env().node();
        n.port = m_orthanc->dicomPort();
        return n;
    }

    /** Kills Orthanc once 10 images came, retrieves with `n`, and checks the words; then
     *  restarts it and retrieves the 30 images. */
    void killMidTransfer(const Node& n, const char* what) {
        LocalStore store(fvr::test::storeRoot(std::string("kill-") + what));
        Clock::time_point at;
        bool done = false;
        const Outcome o = timed(what, at, [&] {
            retrieve(n, shortTimeout(), philipsStudy(), "", store, [&](const RetrieveProgress& p) {
                if (!done && p.received >= 10) {
                    m_orthanc->kill();
                    at = Clock::now();
                    done = true;
                }
            });
        });
        EXPECT_NE(o.message.find("the connection was lost (the PACS closed it or died)"),
                  std::string::npos)
            << o.message;
        EXPECT_EQ(o.message.find("AE title"), std::string::npos) << o.message;
        EXPECT_EQ(o.message.find("0xffff"), std::string::npos) << o.message;
        EXPECT_LE(o.seconds, kTimeout + 1.0);
        m_orthanc->restart();
        retrieve(n, shortTimeout(), philipsStudy(), "", store);
        const auto entry = store.find(philipsStudy());
        ASSERT_TRUE(entry);
        EXPECT_EQ(entry->instances, 30);
        EXPECT_TRUE(entry->complete);
    }

    std::unique_ptr<OrthancServer> m_orthanc;
};

TEST_F(PacsKill, GetFromAPacsKilledMidTransfer) { killMidTransfer(node(), "C-GET, killed at 10"); }

TEST_F(PacsKill, MoveFromAPacsKilledMidTransfer) {
    killMidTransfer(moveNode(node()), "C-MOVE, killed at 10");
}
