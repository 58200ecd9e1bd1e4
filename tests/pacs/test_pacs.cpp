// DIMSE against a real Orthanc: echo and its failures, C-FIND, C-GET and C-MOVE into the local
// store (the volume equal to loading the same folder), cancel, C-STORE, the storage listener.
#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/errors.h>
#include <fvr/core/io/open_study.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/pacs/storage_listener.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>

#include "pacs_environment.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace fvr::core;
using namespace fvr::core::pacs;
using fvr::test::OrthancServer;
using fvr::test::PacsEnvironment;

namespace {

PacsEnvironment& env() { return PacsEnvironment::get(); }

using fvr::test::storeRoot;

std::string philipsStudy() {
    return fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kPhilips), "StudyInstanceUID");
}
std::string philipsSeries() {
    return fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kPhilips),
        "SeriesInstanceUID");
}

/** What a call threw, "" when it did not throw PacsError. */
template <class F>
std::string pacsError(F&& f) {
    try {
        f();
    } catch (const PacsError& e) {
        return e.what();
    }
    return "";
}

/** The retrieved folder opens to the very volume the shared folder gives. */
void expectSameVolume(const fs::path& retrieved) {
    const OpenedStudy a = openStudy(classifyInput(retrieved.string()));
    const OpenedStudy b =
        openStudy(classifyInput((fvr::test::sharedData() / fvr::test::kPhilips).string()));
    ASSERT_EQ(a.volume.dims, b.volume.dims);
    EXPECT_EQ(a.volume.dims, (Dims3{512, 512, 140}));
    for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(a.volume.spacing[i], b.volume.spacing[i]);
        EXPECT_EQ(a.volume.origin[i], b.volume.origin[i]);
    }
    EXPECT_EQ(a.volume.units, b.volume.units);
    EXPECT_TRUE(a.volume.voxels == b.volume.voxels) << "voxel values differ";
}

} // namespace

TEST(PacsEcho, AnswersOurAe) {
    FVR_REQUIRE_ORTHANC();
    EXPECT_NO_THROW(echo(env().node(), env().local()));
}

TEST(PacsEcho, WrongCalledAeSaysSo) {
    FVR_REQUIRE_ORTHANC();
    Node node = env().node();
    node.calledAe = "NOTORTHANC";
    const std::string msg = pacsError([&] { echo(node, env().local()); });
    EXPECT_NE(msg.find("NOTORTHANC@127.0.0.1:"), std::string::npos) << msg;
    EXPECT_NE(msg.find("called AE title not recognised"), std::string::npos) << msg;
}

TEST(PacsEcho, UnknownCallingAeSaysSo) {
    FVR_REQUIRE_ORTHANC();
    LocalAe local = env().local();
    local.aeTitle = "STRANGER";
    const std::string msg = pacsError([&] { echo(env().node(), local); });
    EXPECT_NE(msg.find("calling AE title not recognised"), std::string::npos) << msg;
}

TEST(PacsEcho, ClosedPortSaysConnectionRefused) {
    FVR_REQUIRE_ORTHANC();
    Node node = env().node();
    node.port = fvr::test::freeLoopbackPort(); // nothing listens there
    const std::string msg = pacsError([&] { echo(node, env().local()); });
    EXPECT_NE(msg.find("connection refused (nothing listens at 127.0.0.1:" +
                       std::to_string(node.port) + ")"),
              std::string::npos)
        << msg;
}

TEST(PacsFind, StudiesByNameWildcardAndDateRange) {
    FVR_REQUIRE_ORTHANC();
    StudyQuery q;
    q.patientName = "HE*"; // the Philips phantom is HEAD, born of no one, 2015-02-06
    auto found = findStudies(env().node(), env().local(), q);
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].studyUid, philipsStudy());
    EXPECT_EQ(found[0].patientId, "PLASTIC");
    EXPECT_EQ(found[0].studyDate, "20150206");
    EXPECT_EQ(found[0].numberOfInstances, 140);
    q = {};
    q.dateFrom = "20150101";
    q.dateTo = "20151231";
    found = findStudies(env().node(), env().local(), q);
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].studyUid, philipsStudy());
    q.dateTo = "20150205"; // the day before: no match
    EXPECT_TRUE(findStudies(env().node(), env().local(), q).empty());
    q = {};
    q.dateTo = "20100101"; // open start: the Slicer head (2009) and the Latin-1 study (1999)
    EXPECT_EQ(findStudies(env().node(), env().local(), q).size(), 2u);
    EXPECT_EQ(findStudies(env().node(), env().local(), {}).size(), 3u);
}

TEST(PacsFind, ModalityAccessionAndLatin1ToUtf8) {
    FVR_REQUIRE_ORTHANC();
    StudyQuery q;
    q.modality = "MR";
    auto found = findStudies(env().node(), env().local(), q);
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].studyUid, env().latin1StudyUid);
    EXPECT_EQ(found[0].patientName, env().latin1NameUtf8); // ISO_IR 100 in, UTF-8 out
    q = {};
    q.accessionNumber = "ACC-L1";
    ASSERT_EQ(findStudies(env().node(), env().local(), q).size(), 1u);
    q = {};
    q.patientId = "PLAST?C";
    ASSERT_EQ(findStudies(env().node(), env().local(), q).size(), 1u);
    q = {};
    q.dateFrom = "2015-01-01";
    EXPECT_NE(pacsError([&] {
                  findStudies(env().node(), env().local(), q);
              }).find("is not a date YYYYMMDD"),
              std::string::npos);
}

TEST(PacsFind, SeriesOfAStudy) {
    FVR_REQUIRE_ORTHANC();
    const auto series = findSeries(env().node(), env().local(), philipsStudy());
    ASSERT_EQ(series.size(), 1u);
    EXPECT_EQ(series[0].seriesUid, philipsSeries());
    EXPECT_EQ(series[0].modality, "CT");
    EXPECT_EQ(series[0].numberOfInstances, 140);
}

TEST(PacsRetrieve, GetGivesTheSameVolumeAsTheFolder) {
    FVR_REQUIRE_ORTHANC();
    LocalStore store(storeRoot("get"));
    std::vector<RetrieveProgress> seen;
    const fs::path folder = retrieve(env().node(), env().local(), philipsStudy(), "", store,
                                     [&](const RetrieveProgress& p) { seen.push_back(p); });
    EXPECT_EQ(folder, store.studyFolder(philipsStudy()));
    ASSERT_FALSE(seen.empty());
    EXPECT_EQ(seen.back().received, 140);
    EXPECT_EQ(seen.back().expected, 140);
    EXPECT_EQ(seen.back().failed, 0);
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 140);
    EXPECT_EQ(entry->study.patientName, "HEAD");
    ASSERT_EQ(entry->series.size(), 1u);
    EXPECT_TRUE(entry->series[0].complete);
    expectSameVolume(folder);
}

TEST(PacsRetrieve, MoveGivesTheSameVolumeAsTheFolder) {
    FVR_REQUIRE_ORTHANC();
    LocalStore store(storeRoot("move"));
    Node node = env().node();
    node.retrieve = RetrieveMethod::Move;
    RetrieveProgress last;
    const fs::path folder = retrieve(node, env().local(), philipsStudy(), philipsSeries(), store,
                                     [&](const RetrieveProgress& p) { last = p; });
    EXPECT_EQ(folder, store.seriesFolder(philipsStudy(), philipsSeries()));
    EXPECT_EQ(last.received, 140);
    EXPECT_EQ(last.expected, 140);
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_FALSE(entry->complete); // a series was asked for, not the study
    ASSERT_EQ(entry->series.size(), 1u);
    EXPECT_TRUE(entry->series[0].complete);
    EXPECT_EQ(entry->series[0].instances, 140);
    expectSameVolume(folder);
}

/** Retrieves the Philips study with `node`'s method, cancelled at 10 images: the study stays
 *  partial with nothing half-written (whatever the PACS still sends to our listener after the
 *  C-CANCEL), and a second retrieve completes it. */
static void cancelThenComplete(const Node& node, const std::string& storeName) {
    LocalStore store(storeRoot(storeName));
    CancelToken cancel;
    auto cancelAtTen = [&](const RetrieveProgress& p) {
        if (p.received >= 10) cancel.cancel();
    };
    EXPECT_THROW(retrieve(node, env().local(), philipsStudy(), "", store, cancelAtTen, &cancel),
                 Cancelled);
    auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_FALSE(entry->complete);
    for (const auto& s : entry->series) EXPECT_FALSE(s.complete);
    EXPECT_GE(entry->instances, 10);
    if (node.retrieve == RetrieveMethod::Get) { // it stopped
        EXPECT_LT(entry->instances, 140);
    }
    for (const auto& f : fs::recursive_directory_iterator(entry->folder))
        EXPECT_NE(f.path().extension(), ".part") << f.path(); // nothing half-written
    retrieve(node, env().local(), philipsStudy(), "", store);
    entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 140);
}

TEST(PacsRetrieve, CancelLeavesAPartialStudyThatASecondRetrieveCompletes) {
    FVR_REQUIRE_ORTHANC();
    cancelThenComplete(env().node(), "cancel");
}

TEST(PacsRetrieve, CancelledMoveStaysPartialWhateverArrivesAfter) {
    FVR_REQUIRE_ORTHANC();
    Node node = env().node();
    node.retrieve = RetrieveMethod::Move;
    cancelThenComplete(node, "cancel-move");
}

// A retrieve that brings other bytes than the store holds under a SOP Instance UID (here: a
// stored file changed on disk after a first C-GET) keeps the stored file, puts the received one
// in quarantine, and ends with an error that says so; the study stays partial.
TEST(PacsRetrieve, GetOfInstancesThatDifferFromTheStoredOnesQuarantinesThem) {
    FVR_REQUIRE_ORTHANC();
    LocalStore store(storeRoot("get-differs"));
    retrieve(env().node(), env().local(), philipsStudy(), philipsSeries(), store);
    const fs::path folder = store.seriesFolder(philipsStudy(), philipsSeries());
    const fs::path changed = *fs::directory_iterator(folder);
    std::string original;
    {
        std::ifstream in(changed, std::ios::binary);
        original.assign(std::istreambuf_iterator<char>(in), {});
    }
    std::ofstream(changed, std::ios::binary | std::ios::app) << "changed";
    const std::string msg = pacsError(
        [&] { retrieve(env().node(), env().local(), philipsStudy(), philipsSeries(), store); });
    EXPECT_NE(msg.find("1 instance(s) differed from the stored copies"), std::string::npos) << msg;
    EXPECT_NE(msg.find(store.quarantineFolder().string()), std::string::npos) << msg;
    const auto entry = store.find(philipsStudy());
    ASSERT_TRUE(entry);
    ASSERT_EQ(entry->series.size(), 1u);
    EXPECT_FALSE(entry->series[0].complete);
    EXPECT_EQ(entry->series[0].instances, 140);
    std::ifstream in(changed, std::ios::binary);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), original + "changed");
    const auto kept = store.quarantined();
    ASSERT_EQ(kept.size(), 1u);
    std::ifstream q(kept[0], std::ios::binary);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(q), {}), original);
}

TEST(PacsRetrieve, UnknownStudySaysSo) {
    FVR_REQUIRE_ORTHANC();
    LocalStore store(storeRoot("unknown"));
    const std::string msg =
        pacsError([&] { retrieve(env().node(), env().local(), "1.2.3.4.5.6.7", "", store); });
    EXPECT_NE(msg.find("has no instances of study 1.2.3.4.5.6.7"), std::string::npos) << msg;
    EXPECT_FALSE(store.find("1.2.3.4.5.6.7"));
}

TEST(PacsSend, AProjectionReadBackFromOrthanc) {
    FVR_REQUIRE_ORTHANC();
    ProjectionImage img;
    img.width = img.height = 48;
    img.pixelSize = 0.5;
    img.pixels.resize(48 * 48);
    for (int i = 0; i < 48 * 48; ++i) img.pixels[i] = float(std::sin(0.05 * i) * 100.0);
    const fs::path file = env().dir / "sent.dcm";
    writeDicomProjection(file, img, {"SEND^TEST", "SEND1", "", "FVR send test", "mm"});
    sendFiles(env().node(), env().local(), {file});
    const std::string sop = fvr::test::dicomTag(file, "SOPInstanceUID");
    const auto lookup = env().orthanc().post("/tools/lookup", sop);
    ASSERT_EQ(lookup.status, 200) << lookup.body;
    const auto ids = nlohmann::json::parse(lookup.body);
    ASSERT_EQ(ids.size(), 1u) << lookup.body;
    const std::string id = ids[0]["ID"];
    const auto tags =
        nlohmann::json::parse(env().orthanc().get("/instances/" + id + "/tags?simplify").body);
    EXPECT_EQ(tags["SOPInstanceUID"], sop);
    EXPECT_EQ(tags["StudyInstanceUID"], fvr::test::dicomTag(file, "StudyInstanceUID"));
    EXPECT_EQ(tags["SeriesInstanceUID"], fvr::test::dicomTag(file, "SeriesInstanceUID"));
    EXPECT_EQ(tags["PatientName"], "SEND^TEST");
    const auto back = env().orthanc().get("/instances/" + id + "/file");
    ASSERT_EQ(back.status, 200);
    const fs::path backFile = env().dir / "sent-back.dcm";
    std::ofstream(backFile, std::ios::binary) << back.body;
    const auto a = loadDicomFile(file), b = loadDicomFile(backFile);
    EXPECT_EQ(b.volume.dims, (Dims3{48, 48, 1}));
    EXPECT_TRUE(a.volume.voxels == b.volume.voxels) << "pixel data differ";
}

TEST(PacsSend, ANonDicomFileIsNamed) {
    FVR_REQUIRE_ORTHANC();
    const fs::path file = env().dir / "not-dicom.txt";
    std::ofstream(file) << "hello";
    const std::string msg = pacsError([&] { sendFiles(env().node(), env().local(), {file}); });
    EXPECT_NE(msg.find(file.string() + ": cannot be sent"), std::string::npos) << msg;
}

TEST(PacsListener, ReceivesAStudyOrthancSends) {
    FVR_REQUIRE_ORTHANC();
    LocalStore store(storeRoot("listener"));
    LocalAe local = env().local();
    local.allowedPeers = {{OrthancServer::kAeTitle, "127.0.0.1"}}; // it may push to us
    StorageListener listener(local, store);
    listener.start();
    ASSERT_TRUE(listener.running());
    EXPECT_EQ(StorageListener::runningOn(env().local().listenPort), &listener);
    const std::string slicerStudy = fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer), "StudyInstanceUID");
    const auto lookup =
        nlohmann::json::parse(env().orthanc().post("/tools/lookup", slicerStudy).body);
    ASSERT_EQ(lookup.size(), 1u);
    const auto sent =
        env().orthanc().post("/modalities/fvr/store", lookup[0]["ID"].get<std::string>());
    ASSERT_EQ(sent.status, 200) << sent.body << env().orthanc().log();
    listener.stop();
    EXPECT_FALSE(listener.running());
    EXPECT_EQ(listener.lastError(), "");
    EXPECT_FALSE(store.find(slicerStudy)); // sent unasked: not a study of the Studies area
    const auto entry = store.find(slicerStudy, Area::Incoming);
    ASSERT_TRUE(entry);
    EXPECT_EQ(entry->instances, 93);
    ASSERT_EQ(entry->series.size(), 1u);
    EXPECT_TRUE(entry->series[0].complete); // Orthanc released the association normally
    EXPECT_EQ(entry->study.patientName, "Austrialian");
    const OpenedStudy a = openStudy(classifyInput(entry->folder.string()));
    EXPECT_EQ(a.volume.dims, (Dims3{64, 64, 93}));
}

TEST(PacsListener, RejectsAnotherCalledAe) {
    FVR_REQUIRE_ORTHANC();
    LocalStore store(storeRoot("listener-ae"));
    LocalAe local = env().local();
    local.allowedPeers = {{local.aeTitle, ""}}; // our echo() calls as FVRTEST
    StorageListener listener(local, store);
    listener.start();
    Node us{"us", "SOMEONEELSE", "127.0.0.1", env().local().listenPort};
    const std::string msg = pacsError([&] { echo(us, env().local()); });
    EXPECT_NE(msg.find("called AE title not recognised"), std::string::npos) << msg;
    us.calledAe = env().local().aeTitle;
    EXPECT_NO_THROW(echo(us, env().local()));
    StorageListener second(env().local(), store);
    EXPECT_NE(pacsError([&] { second.start(); }).find("cannot listen on port"), std::string::npos);
}
