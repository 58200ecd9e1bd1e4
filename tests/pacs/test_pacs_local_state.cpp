// What the local store says about studies from a real Orthanc: a study Orthanc pushes to our
// listener is complete once all its series are, listed with its patient fields and announced
// (an Incoming event naming the patient); a series retrieve lists its study with the patient,
// date and description (the C-FIND's, the oracle), and a later full retrieve keeps them. Resume
// of a partial study takes only the missing instances (every instance Orthanc sends is counted
// by the store), and a complete study is taken from the store with Orthanc frozen.
#include <fvr/core/errors.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/pacs/storage_listener.h>

#include <nlohmann/json.hpp>

#include <sys/stat.h>

#include <cstdint>
#include <cstdio>
#include <map>
#include <mutex>

#include "pacs_environment.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace fvr::core::pacs;
using fvr::test::OrthancServer;
using fvr::test::PacsEnvironment;

namespace {

PacsEnvironment& env() { return PacsEnvironment::get(); }

std::string slicerStudy() {
    return fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer), "StudyInstanceUID");
}

/** The Slicer study as Orthanc's C-FIND describes it. */
StudyRecord slicerRecord() {
    StudyQuery q;
    q.patientId = fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer), "PatientID");
    for (const StudyRecord& r : findStudies(env().node(), env().local(), q))
        if (r.studyUid == slicerStudy()) return r;
    return {};
}

void expectFields(const StudyRecord& got, const StudyRecord& want) {
    EXPECT_FALSE(want.patientName.empty());
    EXPECT_EQ(got.patientName, want.patientName);
    EXPECT_EQ(got.patientId, want.patientId);
    EXPECT_EQ(got.studyDate, want.studyDate);
    EXPECT_EQ(got.description, want.description);
}

} // namespace

TEST(PacsLocalState, AStudyOrthancPushesIsCompleteListedAndAnnounced) {
    FVR_REQUIRE_ORTHANC();
    const StudyRecord want = slicerRecord();
    LocalStore store(fvr::test::storeRoot("pushed"));
    LocalAe local = env().local();
    local.allowedPeers = {{OrthancServer::kAeTitle, "127.0.0.1"}}; // it may push to us
    std::mutex mutex;
    std::vector<StorageListener::Event> events;
    StorageListener listener(local, store, [&](const StorageListener::Event& e) {
        std::lock_guard lock(mutex);
        events.push_back(e);
    });
    listener.start();
    const std::string id = env().orthanc().lookup(slicerStudy());
    ASSERT_FALSE(id.empty());
    const auto sent = env().orthanc().post("/modalities/fvr/store", id);
    ASSERT_EQ(sent.status, 200) << sent.body << env().orthanc().log();
    listener.stop();
    const auto entry = store.find(slicerStudy(), Area::Incoming);
    ASSERT_TRUE(entry);
    EXPECT_EQ(entry->instances, 93);
    ASSERT_EQ(entry->series.size(), 1u);
    EXPECT_TRUE(entry->series[0].complete);
    EXPECT_TRUE(entry->complete); // its only series is: it opens without "Resume retrieve"
    expectFields(entry->study, want);
    std::lock_guard lock(mutex);
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(events[0].kind, StorageListener::Event::Kind::Incoming);
    EXPECT_NE(events[0].text.find("93 of " + want.patientName + ", " + want.studyDate),
              std::string::npos)
        << events[0].text;
    EXPECT_NE(events[0].text.find("(complete)"), std::string::npos) << events[0].text;
}

TEST(PacsLocalState, ASeriesRetrieveListsItsStudysPatientDateAndDescription) {
    FVR_REQUIRE_ORTHANC();
    const StudyRecord want = slicerRecord();
    const auto series = findSeries(env().node(), env().local(), slicerStudy());
    ASSERT_EQ(series.size(), 1u);
    LocalStore store(fvr::test::storeRoot("series-fields"));
    retrieve(env().node(), env().local(), slicerStudy(), series[0].seriesUid, store);
    auto entry = store.find(slicerStudy());
    ASSERT_TRUE(entry);
    expectFields(entry->study, want);
    ASSERT_EQ(entry->series.size(), 1u);
    EXPECT_EQ(entry->series[0].modality, series[0].modality);
    EXPECT_EQ(entry->series[0].description, series[0].description);
    EXPECT_TRUE(entry->series[0].complete);
    retrieve(env().node(), env().local(), slicerStudy(), "", store); // the whole study
    entry = store.find(slicerStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    expectFields(entry->study, want);
}

namespace {

std::string philipsStudy() {
    return fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kPhilips), "StudyInstanceUID");
}

/** Each file under `folder` with its inode and modification time: what "untouched" compares. */
std::map<fs::path, std::pair<ino_t, std::int64_t>> fileStamps(const fs::path& folder) {
    std::map<fs::path, std::pair<ino_t, std::int64_t>> out;
    for (const auto& e : fs::recursive_directory_iterator(folder)) {
        struct stat st {};
        if (e.is_regular_file() && ::stat(e.path().c_str(), &st) == 0)
            out[e.path()] = {st.st_ino,
                             std::int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec};
    }
    return out;
}

} // namespace

TEST(PacsLocalState, ResumeFetchesOnlyTheMissingAndACompleteStudyNeedsNoNetwork) {
    FVR_REQUIRE_ORTHANC();
    Node move = env().node();
    move.retrieve = RetrieveMethod::Move;
    for (const Node& node : {env().node(), move}) {
        const char* how = node.retrieve == RetrieveMethod::Move ? "C-MOVE" : "C-GET";
        const fs::path root = fvr::test::storeRoot(std::string("resume-") + how);
        int kept = 0;
        {
            // A retrieve cancelled once 14 of the 140 images came: partial.
            LocalStore store(root);
            fvr::core::CancelToken token;
            EXPECT_THROW(retrieve(
                             node, env().local(), philipsStudy(), "", store,
                             [&](const RetrieveProgress& p) {
                                 if (p.received >= 14) token.cancel();
                             },
                             &token),
                         fvr::core::Cancelled)
                << how;
            const auto entry = store.find(philipsStudy());
            ASSERT_TRUE(entry);
            ASSERT_FALSE(entry->complete);
            kept = entry->instances;
        }
        ASSERT_GE(kept, 14) << how;
        ASSERT_LT(kept, 140) << how;
        const auto before = fileStamps(root / philipsStudy());
        // Resume: a new store object counts every instance the PACS sends (stored or not).
        LocalStore store(root);
        const RetrieveSummary resumed =
            retrieveMissing(node, env().local(), philipsStudy(), "", store);
        std::printf("[ resume   ] %s: %d kept, %d fetched, %d instances sent by Orthanc\n", how,
                    resumed.present, resumed.fetched, store.instancesStored());
        EXPECT_FALSE(resumed.fromStore);
        EXPECT_EQ(resumed.present, kept) << how;
        EXPECT_EQ(resumed.fetched, 140 - kept) << how;
        EXPECT_EQ(store.instancesStored(), 140 - kept) << how; // nothing sent twice
        const auto entry = store.find(philipsStudy());
        ASSERT_TRUE(entry);
        EXPECT_TRUE(entry->complete) << how;
        EXPECT_EQ(entry->instances, 140) << how;
        const auto after = fileStamps(root / philipsStudy());
        for (const auto& [path, stamp] : before) {
            ASSERT_TRUE(after.count(path)) << path;
            EXPECT_EQ(after.at(path), stamp) << path; // the kept files untouched
        }
        // Complete now: a retrieve takes it from the store, with the PACS frozen.
        env().orthanc().stop();
        RetrieveSummary again;
        EXPECT_NO_THROW(again = retrieveMissing(node, env().local(), philipsStudy(), "", store));
        env().orthanc().cont();
        EXPECT_TRUE(again.fromStore) << how;
        EXPECT_EQ(again.fetched, 0) << how;
        EXPECT_EQ(again.folder, store.studyFolder(philipsStudy()));
        EXPECT_EQ(store.instancesStored(), 140 - kept) << how;
    }
}
