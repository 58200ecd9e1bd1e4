// What the local store says about studies from a real Orthanc: a study Orthanc pushes to our
// listener is complete once all its series are, listed with its patient fields and announced
// (an Incoming event naming the patient); a series retrieve lists its study with the patient,
// date and description (the C-FIND's, the oracle), and a later full retrieve keeps them.
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/pacs/storage_listener.h>

#include <nlohmann/json.hpp>

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
