// The storage listener's trust, against DCMTK's echoscu/storescu and a real Orthanc: whom it
// accepts (allowed peers, the PACS of a running C-MOVE), the address it binds, where what it
// receives goes (the study a C-MOVE asked for, Incoming, refused, quarantined).
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/pacs/storage_listener.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <chrono>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <thread>

#include "pacs_environment.h"
#include "slow_peer.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace fvr::core;
using namespace fvr::core::pacs;
using fvr::test::OrthancServer;
using fvr::test::PacsEnvironment;

namespace {

PacsEnvironment& env() { return PacsEnvironment::get(); }

using fvr::test::storeRoot;

fs::path scratch(const std::string& name) {
    const fs::path dir = env().dir / "listener" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

/** Skips when DCMTK's command-line tools are missing (apt package dcmtk). */
#define FVR_REQUIRE_DCMTK_TOOLS()                                                                  \
    do {                                                                                           \
        if (fvr::test::runCommand("command -v storescu echoscu >/dev/null 2>&1").status != 0)      \
            GTEST_SKIP() << "DCMTK's storescu/echoscu are not installed (apt package dcmtk)";      \
    } while (0)

/** echoscu from `callingAe` to our listener; exit status and its output (stdout and stderr). */
fvr::test::CommandOutput echoscu(const std::string& callingAe, int port) {
    return fvr::test::runCommand("echoscu -ta 30 -aet " + callingAe + " -aec " + fvr::test::kOurAe +
                                 " 127.0.0.1 " + std::to_string(port) + " 2>&1");
}

/** storescu of `files` from `callingAe` to our listener (-v: it prints each response's
 *  status). */
fvr::test::CommandOutput storescu(const std::string& callingAe, int port,
                                  const std::vector<fs::path>& files) {
    std::string cmd = "storescu -v -ta 120 -td 120 -aet " + callingAe + " -aec " +
                      fvr::test::kOurAe + " 127.0.0.1 " + std::to_string(port);
    for (const fs::path& f : files) cmd += " '" + f.string() + "'";
    return fvr::test::runCommand(cmd + " 2>&1");
}

std::string readAll(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/** The TCP sockets listening on `port` as /proc/net/tcp writes their local address
 *  ("0100007F" = 127.0.0.1, "00000000" = every interface). */
std::vector<std::string> listeningAddresses(int port) {
    std::ifstream in("/proc/net/tcp");
    std::vector<std::string> out;
    char portHex[8];
    std::snprintf(portHex, sizeof portHex, "%04X", port);
    std::string line;
    std::getline(in, line); // header
    while (std::getline(in, line)) {
        std::istringstream fields(line);
        std::string sl, local, remote, state;
        fields >> sl >> local >> remote >> state;
        if (state == "0A" && local.substr(local.find(':') + 1) == portHex)
            out.push_back(local.substr(0, local.find(':')));
    }
    return out;
}

/** The events of one kind, their texts joined (for messages). */
std::string eventsOf(const StorageListener& l, StorageListener::Event::Kind kind) {
    std::string out;
    for (const auto& e : l.events())
        if (e.kind == kind) out += e.text + "\n";
    return out;
}

std::string philipsFile(int index = 0) {
    std::vector<fs::path> files;
    for (const auto& f : fs::directory_iterator(fvr::test::sharedData() / fvr::test::kPhilips))
        files.push_back(f.path());
    std::sort(files.begin(), files.end());
    return files.at(static_cast<std::size_t>(index)).string();
}

/** A copy of `src` with a new SOP instance UID (and a new study when `newStudy`): an instance
 *  the PACS does not have. */
fs::path extraInstance(const fs::path& src, const fs::path& out, bool newStudy) {
    DcmFileFormat file;
    EXPECT_TRUE(file.loadFile(src.c_str()).good());
    char uid[100];
    DcmDataset* ds = file.getDataset();
    ds->putAndInsertString(DCM_SOPInstanceUID,
                           dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT));
    if (newStudy) {
        ds->putAndInsertString(DCM_StudyInstanceUID,
                               dcmGenerateUniqueIdentifier(uid, SITE_STUDY_UID_ROOT));
        ds->putAndInsertString(DCM_SeriesInstanceUID,
                               dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT));
    }
    EXPECT_TRUE(file.saveFile(out.c_str(), EXS_LittleEndianExplicit).good());
    return out;
}

LocalAe withPeers(std::vector<Peer> peers) {
    LocalAe local = env().local();
    local.allowedPeers = std::move(peers);
    return local;
}

} // namespace

TEST(PacsListenerTrust, BindsLoopbackUnlessToldOtherwise) {
    FVR_REQUIRE_ORTHANC();
    LocalStore store(storeRoot("bind"));
    {
        StorageListener listener(env().local(), store);
        listener.start();
        EXPECT_EQ(listeningAddresses(env().local().listenPort),
                  std::vector<std::string>{"0100007F"}); // 127.0.0.1 only
    }
    EXPECT_TRUE(listeningAddresses(env().local().listenPort).empty()); // closed when stopped
    LocalAe all = env().local();
    all.listenAddress = "0.0.0.0"; // asked for explicitly
    StorageListener listener(all, store);
    listener.start();
    EXPECT_EQ(listeningAddresses(all.listenPort), std::vector<std::string>{"00000000"});
    listener.stop();
    all.listenAddress = "localhost";
    try {
        StorageListener bad(all, store);
        ADD_FAILURE() << "a listen address that is not an IPv4 address was taken";
    } catch (const PacsError& e) {
        EXPECT_NE(std::string(e.what()).find("\"localhost\" is not an IPv4 address"),
                  std::string::npos)
            << e.what();
    }
}

TEST(PacsListenerTrust, UnknownCallingAeIsRejectedAndNamed) {
    FVR_REQUIRE_ORTHANC();
    FVR_REQUIRE_DCMTK_TOOLS();
    LocalStore store(storeRoot("trust-ae"));
    StorageListener listener(withPeers({{"SENDER", ""}, {"LABHOST", "10.255.255.1"}}), store);
    listener.start();
    const int port = env().local().listenPort;

    const auto attacker = echoscu("ATTACKER", port);
    EXPECT_NE(attacker.status, 0) << attacker.out;
    EXPECT_NE(attacker.out.find("Calling AE Title Not Recognized"), std::string::npos)
        << attacker.out;
    const std::string refused = eventsOf(listener, StorageListener::Event::Kind::Refused);
    EXPECT_NE(refused.find("refused an association from ATTACKER at 127.0.0.1: calling AE "
                           "title not recognised"),
              std::string::npos)
        << refused;
    EXPECT_NE(listener.lastError().find("ATTACKER at 127.0.0.1"), std::string::npos);

    // An allowed AE title from another host than the one it is allowed from.
    EXPECT_NE(echoscu("LABHOST", port).status, 0);
    EXPECT_NE(
        eventsOf(listener, StorageListener::Event::Kind::Refused).find("LABHOST at 127.0.0.1"),
        std::string::npos);

    const auto sender = echoscu("SENDER", port);
    EXPECT_EQ(sender.status, 0) << sender.out;

    // A C-STORE from the stranger stores nothing.
    const auto stored = storescu("ATTACKER", port, {philipsFile()});
    EXPECT_NE(stored.status, 0) << stored.out;
    EXPECT_TRUE(store.studies().empty());
}

namespace {

std::string philipsStudy() { return fvr::test::dicomTag(philipsFile(), "StudyInstanceUID"); }

/** A copy of `src` with the same UIDs and a bright block in its pixels: a tampered slice. */
fs::path tamperedCopy(const fs::path& src, const fs::path& out) {
    DcmFileFormat file;
    EXPECT_TRUE(file.loadFile(src.c_str()).good());
    DcmDataset* ds = file.getDataset();
    const Uint16* pixels = nullptr;
    unsigned long count = 0;
    EXPECT_TRUE(ds->findAndGetUint16Array(DCM_PixelData, pixels, &count).good());
    std::vector<Uint16> changed(pixels, pixels + count);
    for (unsigned long i = 0; i < count / 8; ++i) changed[i] = 4000;
    ds->putAndInsertUint16Array(DCM_PixelData, changed.data(), count);
    EXPECT_TRUE(file.saveFile(out.c_str(), ds->getOriginalXfer()).good());
    return out;
}

/** The Philips study retrieved by C-MOVE into `store` through `listener` (running). */
fs::path moveRetrieve(LocalStore& store, const RetrieveProgressFn& progress = {}) {
    Node node = env().node();
    node.retrieve = RetrieveMethod::Move;
    return retrieve(node, env().local(), philipsStudy(), "", store, progress);
}

} // namespace

TEST(PacsListenerTrust, TamperedResendNeverReplacesAStoredSlice) {
    FVR_REQUIRE_ORTHANC();
    FVR_REQUIRE_DCMTK_TOOLS();
    LocalStore store(storeRoot("tamper"));
    StorageListener listener(withPeers({{"SENDER", "127.0.0.1"}}), store);
    listener.start();
    const fs::path folder = moveRetrieve(store);
    const fs::path dir = scratch("tamper");
    const std::string sop = fvr::test::dicomTag(philipsFile(69), "SOPInstanceUID");
    const std::string series = fvr::test::dicomTag(philipsFile(69), "SeriesInstanceUID");
    const fs::path stored = store.seriesFolder(philipsStudy(), series) / (sop + ".dcm");
    ASSERT_TRUE(fs::exists(stored));
    const std::string before = readAll(stored);
    const fs::path tampered = tamperedCopy(stored, dir / "tampered.dcm");
    ASSERT_NE(readAll(tampered), before);

    // From an allowed peer, unasked: into Incoming, never into the study.
    const auto pushed = storescu("SENDER", env().local().listenPort, {tampered});
    EXPECT_EQ(pushed.status, 0) << pushed.out;
    EXPECT_EQ(readAll(stored), before);
    EXPECT_TRUE(
        fs::exists(store.seriesFolder(philipsStudy(), series, Area::Incoming) / (sop + ".dcm")));

    // As the PACS itself during a C-MOVE of that study (the AE title and address a C-MOVE
    // trusts): the stored file stays, the copy is quarantined, the sender hears a failure.
    {
        Node orthanc = env().node();
        const auto move = listener.expect(orthanc, philipsStudy(), "");
        const auto spoofed =
            storescu(OrthancServer::kAeTitle, env().local().listenPort, {tampered});
        EXPECT_NE(spoofed.out.find("Status: 0x111"), std::string::npos) << spoofed.out;
        EXPECT_NE(move.lastProblem(), "");
        // The very same bytes again are no tampering: success, nothing changes.
        const auto same = storescu(OrthancServer::kAeTitle, env().local().listenPort, {stored});
        EXPECT_EQ(same.status, 0) << same.out;
        EXPECT_EQ(same.out.find("Status: 0x111"), std::string::npos) << same.out;
    }
    EXPECT_EQ(readAll(stored), before);
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 140);
    ASSERT_EQ(store.quarantined().size(), 1u);
    EXPECT_EQ(readAll(store.quarantined()[0]), readAll(tampered));
    const std::string quarantine = eventsOf(listener, StorageListener::Event::Kind::Quarantined);
    EXPECT_NE(quarantine.find("ORTHANC at 127.0.0.1"), std::string::npos) << quarantine;
    EXPECT_NE(quarantine.find(sop), std::string::npos) << quarantine;
    (void)folder;
}

TEST(PacsListenerTrust, NothingButTheMovedStudyEntersItDuringAMove) {
    FVR_REQUIRE_ORTHANC();
    FVR_REQUIRE_DCMTK_TOOLS();
    LocalStore store(storeRoot("inject"));
    const fs::path dir = scratch("inject");
    const fs::path extra = extraInstance(philipsFile(3), dir / "extra.dcm", false);
    const fs::path other = extraInstance(philipsFile(4), dir / "other-study.dcm", true);
    const int port = env().local().listenPort;
    // The listener of the retrieve itself (none runs): it knows SENDER, and ORTHANC for the
    // move only. While the move runs (the first progress report), three others try their luck.
    LocalAe local = withPeers({{"SENDER", ""}});
    StorageListener listener(local, store);
    listener.start();
    std::vector<fvr::test::CommandOutput> tries;
    moveRetrieve(store, [&](const RetrieveProgress&) {
        if (!tries.empty()) return;
        tries.push_back(storescu("ATTACKER", port, {extra})); // not allowed: rejected
        tries.push_back(storescu("SENDER", port, {extra})); // allowed, unasked: Incoming
        tries.push_back(storescu(OrthancServer::kAeTitle, port, {other})); // not what was asked
    });
    ASSERT_EQ(tries.size(), 3u);
    EXPECT_NE(tries[0].out.find("Calling AE Title Not Recognized"), std::string::npos)
        << tries[0].out;
    EXPECT_EQ(tries[1].status, 0) << tries[1].out;
    EXPECT_NE(tries[2].out.find("Status: 0x124"), std::string::npos)
        << tries[2].out; // Not Authorized
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 140); // exactly the PACS's count
    const auto incoming = store.find(philipsStudy(), Area::Incoming);
    ASSERT_TRUE(incoming);
    EXPECT_EQ(incoming->instances, 1);
    EXPECT_FALSE(store.find(fvr::test::dicomTag(other, "StudyInstanceUID"), Area::Incoming));
    EXPECT_NE(eventsOf(listener, StorageListener::Event::Kind::NotAuthorized)
                  .find("ORTHANC at 127.0.0.1 sent instance"),
              std::string::npos);
}

namespace {

/** The pixel data of a DICOM file (its bytes as DCMTK reads them), "" when it has none. */
std::string pixelBytes(const fs::path& file) {
    DcmFileFormat ff;
    if (ff.loadFile(file.c_str()).bad()) return "";
    const Uint8* data = nullptr;
    unsigned long count = 0;
    if (ff.getDataset()->findAndGetUint8Array(DCM_PixelData, data, &count).bad() || !data)
        return "";
    return std::string(reinterpret_cast<const char*>(data), count);
}

/** The shared files of a folder by their SOP Instance UID. */
std::map<std::string, fs::path> bySop(const fs::path& folder) {
    std::map<std::string, fs::path> out;
    for (const auto& f : fs::directory_iterator(folder))
        out[fvr::test::dicomTag(f.path(), "SOPInstanceUID")] = f.path();
    return out;
}

/** Every .dcm file under `folder`, relative to it. */
std::vector<fs::path> dcmFiles(const fs::path& folder) {
    std::vector<fs::path> out;
    for (const auto& f : fs::recursive_directory_iterator(folder))
        if (f.path().extension() == ".dcm") out.push_back(fs::relative(f.path(), folder));
    std::sort(out.begin(), out.end());
    return out;
}

} // namespace

// 8 C-MOVEs of the same 140-image CT into one store at once, while 4 peers push the 93-image
// head to the same listener: each study complete, each file bit-equal to a retrieve done
// alone (and its pixels to the shared data), the index readable, nothing half-written left.
TEST(PacsListenerLoad, EightMovesAndFourSendersShareOneStore) {
    FVR_REQUIRE_ORTHANC();
    FVR_REQUIRE_DCMTK_TOOLS();
    LocalStore reference(storeRoot("load-reference"));
    const fs::path refFolder = moveRetrieve(reference);
    LocalStore store(storeRoot("load"));
    StorageListener listener(
        withPeers({{"SENDER1", ""}, {"SENDER2", ""}, {"SENDER3", ""}, {"SENDER4", ""}}), store);
    listener.start();
    std::vector<fs::path> slicer;
    for (const auto& f : fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer))
        slicer.push_back(f.path());

    const auto t0 = std::chrono::steady_clock::now();
    std::vector<std::string> errors(8);
    std::vector<fvr::test::CommandOutput> sent(4);
    std::vector<std::thread> threads;
    for (int i = 0; i < 8; ++i)
        threads.emplace_back([&, i] {
            try {
                moveRetrieve(store);
            } catch (const std::exception& e) {
                errors[std::size_t(i)] = e.what();
            }
        });
    for (int i = 0; i < 4; ++i)
        threads.emplace_back([&, i] {
            sent[std::size_t(i)] =
                storescu("SENDER" + std::to_string(i + 1), env().local().listenPort, slicer);
        });
    for (auto& t : threads) t.join();
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("[ load     ] 8 C-MOVEs x 140 + 4 senders x 93 into one store: %.1f s\n", seconds);
    for (const std::string& e : errors) EXPECT_EQ(e, "");
    for (const auto& s : sent) EXPECT_EQ(s.status, 0) << s.out;

    const auto studies = store.studies(); // the index reads back
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 140);
    const std::string slicerStudy = fvr::test::dicomTag(slicer[0], "StudyInstanceUID");
    const auto incoming = store.find(slicerStudy, Area::Incoming);
    ASSERT_TRUE(incoming);
    EXPECT_EQ(incoming->instances, 93);
    EXPECT_TRUE(store.quarantined().empty());
    const fs::path folder = store.studyFolder(philipsStudy());
    ASSERT_EQ(dcmFiles(folder), dcmFiles(refFolder));
    const auto philipsSources = bySop(fvr::test::sharedData() / fvr::test::kPhilips);
    for (const fs::path& rel : dcmFiles(folder)) {
        EXPECT_EQ(readAll(folder / rel), readAll(refFolder / rel)) << rel;
        EXPECT_EQ(pixelBytes(folder / rel), pixelBytes(philipsSources.at(rel.stem().string())))
            << rel;
    }
    const auto slicerSources = bySop(fvr::test::sharedData() / fvr::test::kSlicer);
    for (const fs::path& rel : dcmFiles(incoming->folder))
        EXPECT_EQ(pixelBytes(incoming->folder / rel),
                  pixelBytes(slicerSources.at(rel.stem().string())))
            << rel;
    for (const auto& f : fs::recursive_directory_iterator(store.root()))
        EXPECT_NE(f.path().extension(), ".part") << f.path();
    EXPECT_EQ(listener.lastError(), "");
}

// With no listener running, concurrent C-MOVEs share the one the first of them starts (it
// stays until the last ends): each ends complete.
TEST(PacsListenerLoad, ConcurrentMovesShareTheListenerTheyStart) {
    FVR_REQUIRE_ORTHANC();
    LocalStore store(storeRoot("load-own"));
    ASSERT_EQ(StorageListener::runningOn(env().local().listenPort), nullptr);
    std::vector<std::string> errors(4);
    std::vector<std::thread> threads;
    for (int i = 0; i < 4; ++i)
        threads.emplace_back([&, i] {
            try {
                moveRetrieve(store);
            } catch (const std::exception& e) {
                errors[std::size_t(i)] = e.what();
            }
        });
    for (auto& t : threads) t.join();
    for (const std::string& e : errors) EXPECT_EQ(e, "");
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 140);
    EXPECT_EQ(StorageListener::runningOn(env().local().listenPort), nullptr); // stopped at the end
}

// The listener a C-MOVE starts for itself (fvr-render --retrieve move's) allows the node it
// retrieves from, while the move runs, and no one else.
TEST(PacsListenerTrust, TheListenerOfAMoveAllowsOnlyItsNode) {
    FVR_REQUIRE_ORTHANC();
    FVR_REQUIRE_DCMTK_TOOLS();
    LocalStore store(storeRoot("move-own"));
    ASSERT_EQ(StorageListener::runningOn(env().local().listenPort), nullptr);
    const int port = env().local().listenPort;
    std::vector<fvr::test::CommandOutput> tries;
    std::string refused;
    moveRetrieve(store, [&](const RetrieveProgress&) {
        if (!tries.empty()) return;
        tries.push_back(echoscu("ATTACKER", port));
        tries.push_back(echoscu(OrthancServer::kAeTitle, port)); // the node, as its move runs
        if (StorageListener* l = StorageListener::runningOn(port))
            refused = eventsOf(*l, StorageListener::Event::Kind::Refused);
    });
    ASSERT_EQ(tries.size(), 2u);
    EXPECT_NE(tries[0].status, 0) << tries[0].out;
    EXPECT_EQ(tries[1].status, 0) << tries[1].out;
    EXPECT_NE(refused.find("ATTACKER at 127.0.0.1"), std::string::npos) << refused;
    EXPECT_NE(refused.find("allowed peers: none"), std::string::npos) << refused;
    // After the move, the listener it started is gone (the node's trust after a move, on a
    // listener that stays: TheWorkstationsListenerTrustsTheNodeOnlyWhileItsMoveRuns).
    EXPECT_EQ(StorageListener::runningOn(port), nullptr);
}

// The workstation's listener keeps running after a C-MOVE through it: the PACS it trusted for
// the move (ORTHANC at 127.0.0.1) is a stranger again once the move has ended, for echo and
// for store, and what it then sends stays out of the store.
TEST(PacsListenerTrust, TheWorkstationsListenerTrustsTheNodeOnlyWhileItsMoveRuns) {
    FVR_REQUIRE_ORTHANC();
    FVR_REQUIRE_DCMTK_TOOLS();
    LocalStore store(storeRoot("move-then-stranger"));
    const fs::path dir = scratch("move-then-stranger");
    const fs::path extra = extraInstance(philipsFile(5), dir / "extra.dcm", false);
    const int port = env().local().listenPort;
    StorageListener listener(env().local(), store); // no allowed peers
    listener.start();
    std::vector<fvr::test::CommandOutput> during;
    moveRetrieve(store, [&](const RetrieveProgress&) {
        if (during.empty()) during.push_back(echoscu(OrthancServer::kAeTitle, port));
    });
    ASSERT_EQ(during.size(), 1u);
    EXPECT_EQ(during[0].status, 0) << during[0].out; // trusted while its move ran
    ASSERT_EQ(StorageListener::runningOn(port), &listener); // the same listener, still running
    ASSERT_TRUE(listener.running());

    const auto echo = echoscu(OrthancServer::kAeTitle, port);
    EXPECT_NE(echo.status, 0) << echo.out;
    EXPECT_NE(echo.out.find("Calling AE Title Not Recognized"), std::string::npos) << echo.out;
    const auto stored = storescu(OrthancServer::kAeTitle, port, {extra});
    EXPECT_NE(stored.status, 0) << stored.out;
    EXPECT_NE(stored.out.find("Calling AE Title Not Recognized"), std::string::npos) << stored.out;
    const std::string refused = eventsOf(listener, StorageListener::Event::Kind::Refused);
    EXPECT_NE(refused.find("refused an association from ORTHANC at 127.0.0.1"), std::string::npos)
        << refused;
    EXPECT_NE(refused.find("expected for a C-MOVE: none"), std::string::npos) << refused;
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 140); // the extra instance did not get in
    EXPECT_FALSE(store.find(philipsStudy(), Area::Incoming));
}

// The listener takes one association at a time. A peer that only reaches the port (no AE title
// checked yet) sends the head of an A-ASSOCIATE-RQ and then one byte of it a second, each well
// within the timeout: the whole request must arrive within the timeout of the connection, so
// the listener drops it then (not when the peer stops), and serves the next peer.
TEST(PacsListenerTrust, ADrippedAssociationRequestIsDroppedAtTheTimeout) {
    FVR_REQUIRE_ORTHANC();
    FVR_REQUIRE_DCMTK_TOOLS();
    constexpr int kTimeout = 3; // s
    LocalStore store(storeRoot("drip"));
    LocalAe local = withPeers({{"SENDER", ""}});
    local.timeoutSeconds = kTimeout;
    StorageListener listener(local, store);
    listener.start();
    // A-ASSOCIATE-RQ (type 1) with 200 bytes to follow, which come one a second.
    const double droppedAfter =
        fvr::test::dripUntilDropped(local.listenPort, {0x01, 0x00, 0x00, 0x00, 0x00, 0xc8});
    std::printf("[ timing   ] dripped association request dropped after %.2f s (timeout %d s)\n",
                droppedAfter, kTimeout);
    ASSERT_GE(droppedAfter, 0) << "the listener still held the dripping peer after 30 s";
    EXPECT_LE(droppedAfter, kTimeout + 1.0);
    const auto echo = echoscu("SENDER", local.listenPort);
    EXPECT_EQ(echo.status, 0) << echo.out;
    EXPECT_TRUE(listener.running());
}
