// The local study store without a PACS: its index (partial and complete studies, a bad or
// old index), strict UIDs, no silent overwrite (quarantine), and the Incoming area.
#include <fstream>
#include <map>
#include <regex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <fvr/core/io/atomic_file.h>

#include <gtest/gtest.h>

#include "pacs_local_test_support.h"

using namespace fvr::test::pacs_local;
using fvr::core::temporaryPathFor;

TEST(PacsLocalStore, IndexListsPartialThenCompleteAndSurvivesANewObject) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-unit";
    fs::remove_all(root);
    {
        LocalStore store(root);
        EXPECT_TRUE(store.studies().empty());
        store.beginRetrieve(study("1.2.3"), "");
        const SeriesRecord series{"1.2.3.1", "CT", "head", 1, 2};
        const fs::path a = store.storeInstance(study("1.2.3"), series, "1.2.3.1.1", "DICM-a").path;
        EXPECT_EQ(a, root / "1.2.3" / "1.2.3.1" / "1.2.3.1.1.dcm");
        auto entry = store.find("1.2.3");
        ASSERT_TRUE(entry);
        EXPECT_FALSE(entry->complete); // a retrieve runs: partial
        EXPECT_EQ(entry->instances, 1);
        store.storeInstance(study("1.2.3"), series, "1.2.3.1.2", "DICM-b");
        store.finishRetrieve("1.2.3", "", true);
        EXPECT_EQ(store.instancesStored(), 2);
    }
    LocalStore again(root); // the index on disk, read by a new object
    const auto entries = again.studies();
    ASSERT_EQ(entries.size(), 1u);
    EXPECT_TRUE(entries[0].complete);
    EXPECT_EQ(entries[0].instances, 2);
    EXPECT_EQ(entries[0].study.patientName, "DOE^JANE");
    ASSERT_EQ(entries[0].series.size(), 1u);
    EXPECT_TRUE(entries[0].series[0].complete);
    EXPECT_EQ(entries[0].series[0].modality, "CT");
    again.remove("1.2.3");
    EXPECT_TRUE(again.studies().empty());
    EXPECT_FALSE(fs::exists(root / "1.2.3"));
}

TEST(PacsLocalStore, ANameThatIsNotUtf8IsIndexedNotFatal) {
    // A Latin-1 patient name (0xFC: u-umlaut) in a file that declares no character set: the
    // index is written with U+FFFD for the bad byte, and the store goes on (a fuzzer found the
    // dump throwing here, which ended the process).
    const fs::path root = fvr::test::tmpDir() / "pacs-store-latin1";
    fs::remove_all(root);
    {
        LocalStore store(root);
        StudyRecord s = study("1.2.5");
        s.patientName = "M\xFCller^Hans";
        EXPECT_NO_THROW(store.storeInstance(s, {"1.2.5.1", "CT", "", 1, 1}, "1.2.5.1.1", "x"));
    }
    const auto entries = LocalStore(root).studies();
    ASSERT_EQ(entries.size(), 1u);
    EXPECT_EQ(entries[0].study.patientName, "M\xEF\xBF\xBDller^Hans"); // U+FFFD in UTF-8
}

TEST(PacsLocalStore, AFailedRetrieveStaysPartialEvenWhenTheListenerSeesARelease) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-partial";
    fs::remove_all(root);
    LocalStore store(root);
    store.beginRetrieve(study("9.8"), "");
    store.storeInstance(study("9.8"), {"9.8.1", "MR", "", 1, 1}, "9.8.1.1", "x");
    store.finishRetrieve("9.8", "", false); // cancelled
    store.markReceived("9.8", {"9.8.1"}); // a late sub-association ends normally
    const auto entry = store.find("9.8");
    ASSERT_TRUE(entry);
    EXPECT_FALSE(entry->complete);
    EXPECT_FALSE(entry->series[0].complete);
}

TEST(PacsLocalStore, BadIndexAndBadUidsAreNamed) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-bad";
    fs::remove_all(root);
    fs::create_directories(root);
    std::ofstream(root / "index.json") << "{ not json";
    LocalStore store(root);
    const std::string msg = errorOf([&] { store.studies(); });
    EXPECT_NE(msg.find((root / "index.json").string() + " cannot be read"), std::string::npos)
        << msg;
    EXPECT_NE(errorOf([&] { store.studyFolder("../etc"); }).find("cannot name a file"),
              std::string::npos);
}

// An index edited by hand: valid JSON of the wrong shape is named like unreadable JSON (it
// was a bare json type_error without the file's name).
TEST(PacsLocalStore, AnIndexOfTheWrongShapeIsNamed) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-shape";
    for (const char* text :
         {"", "{\"studies\": {\"1.2.3\": {\"patientName\": \"DOE^J", "[1, 2]", "{\"studies\": 5}",
          "{\"studies\": {\"1.2.3\": 5}}", "{\"studies\": {\"1.2.3\": {\"patientName\": 5}}}",
          "{\"studies\": {\"1.2.3\": {\"complete\": \"yes\"}}}",
          "{\"studies\": {\"1.2.3\": {\"series\": {\"1.2.4\": []}}}}",
          "{\"studies\": {\"1.2.3\": {\"series\": {\"1.2.4\": {\"modality\": 1}}}}}"}) {
        fs::remove_all(root);
        fs::create_directories(root);
        std::ofstream(root / "index.json") << text;
        LocalStore store(root);
        const std::string msg = errorOf([&] { store.studies(); });
        EXPECT_NE(msg.find((root / "index.json").string() + " cannot be read"), std::string::npos)
            << text << " -> " << msg;
    }
}

// The UID rule of PS3.5 9.1, nothing looser: the old rule took letters, '-' and '_', so a peer
// could name a study "index.json.part" (the store's temporary index) and break the store.
TEST(PacsLocalStore, UidsAreDicomUidsOnly) {
    for (const char* good : {"1", "1.2.3", "1.2.840.10008.5.1.4.1.1.2", "0.0", "1.02.003",
                             "1.2.826.0.1.3680043.2.1125.1.21134519937893837128465612345678901"})
        EXPECT_TRUE(isValidUid(good)) << good << ": " << uidProblem(good);
    const std::string long65 = "1." + std::string(63, '2');
    ASSERT_EQ(long65.size(), 65u);
    const std::pair<std::string, std::string> bad[] = {
        {"", "it is empty"},
        {long65, "it has 65 characters, at most 64"},
        {"index.json.part", "it contains \"i\", not a digit or a dot"},
        {"1.2.3a", "it contains \"a\""},
        {"1.2-3", "it contains \"-\""},
        {"1.2/3", "it contains \"/\""},
        {std::string("1.2\0.3", 6), "it contains \"\\x00\""},
        {"1.2\n", "it contains \"\\x0a\""},
        {".1.2", "it begins with a dot"},
        {"1.2.", "it ends with a dot"},
        {"1..2", "it has an empty component"},
        {".", "it begins with a dot"},
        {"..", "it begins with a dot"}};
    for (const auto& [uid, why] : bad) {
        EXPECT_FALSE(isValidUid(uid)) << uid;
        EXPECT_NE(uidProblem(uid).find(why), std::string::npos) << uid << " -> " << uidProblem(uid);
    }
    // The store's own names lie where no UID can reach.
    const fs::path root = "/store";
    for (const fs::path& own :
         {fs::path("index.json"), fs::path(".index.lock"), fs::path("incoming"),
          fs::path("quarantine"), temporaryPathFor(root / "index.json").filename(),
          temporaryPathFor(root / "1.2.3.dcm").filename(), temporaryPathFor(root / "1").filename(),
          fs::path("20260101T000000-1.2.3-1.dcm"), fs::path("1.2.3.dcm")})
        EXPECT_FALSE(isValidUid(own.string())) << own;
}

// A peer chooses the UIDs it sends: a study UID of "index.json.part" would make a folder of
// that name, and every later index write would fail ("Is a directory"). Each name of the
// store's own, and every other UID that is not one, is refused naming it, and the store goes on.
TEST(PacsLocalStore, AnInstanceNamedLikeTheStoresOwnFilesIsRefusedAndTheStoreGoesOn) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-own-names";
    fs::remove_all(root);
    LocalStore store(root);
    ASSERT_EQ(
        detail::storeDataset(store, *makeDataset("1.2.3", "1.2.3.1", "1.2.3.1.1")).outcome.result,
        StoreResult::Stored);
    const std::string long65 = "1." + std::string(63, '2');
    int n = 0;
    for (const std::string bad : {"index.json.part", "index.json", ".index.lock", "incoming",
                                  "quarantine", "1.2.3a", long65.c_str(), "1..2", "..", "."}) {
        for (int position = 0; position < 3; ++position, ++n) {
            const auto ds =
                makeDataset(position == 0 ? bad : "1.2.3", position == 1 ? bad : "1.2.3.1",
                            position == 2 ? bad : "1.2.3.1.9");
            const Area area = n % 2 ? Area::Incoming : Area::Studies;
            const std::string msg = errorOf([&] { detail::storeDataset(store, *ds, area); });
            const char* what[] = {"study", "series", "SOP instance"};
            EXPECT_NE(msg.find(std::string("the ") + what[position] + " UID \"" + bad +
                               "\" cannot name a file in the local store: "),
                      std::string::npos)
                << bad << " -> " << msg;
        }
        EXPECT_NE(errorOf([&] { store.studyFolder(bad); }).find("\"" + bad + "\""),
                  std::string::npos);
        EXPECT_NE(errorOf([&] { store.remove(bad); }).find("cannot name a file"),
                  std::string::npos);
        EXPECT_NE(errorOf([&] { store.beginRetrieve(study(bad), ""); }).find("cannot name a file"),
                  std::string::npos);
    }
    // Nothing of theirs was made; the index and later stores still work.
    EXPECT_EQ(filesUnder(root), (std::vector<std::string>{
                                    ".index.lock", "1.2.3/1.2.3.1/1.2.3.1.1.dcm", "index.json"}));
    EXPECT_TRUE(fs::is_regular_file(root / "index.json"));
    store.beginRetrieve(study("1.2.4"), "");
    EXPECT_EQ(
        store.storeInstance(study("1.2.4"), {"1.2.4.1", "CT", "", 1, 1}, "1.2.4.1.1", "x").result,
        StoreResult::Stored);
    store.finishRetrieve("1.2.4", "", true);
    const auto entries = LocalStore(root).studies();
    ASSERT_EQ(entries.size(), 2u);
    EXPECT_TRUE(LocalStore(root).find("1.2.4")->complete);
    EXPECT_EQ(LocalStore(root).find("1.2.3")->instances, 1);
}

// Tampering: a peer re-sends a slice of a complete study with the same UIDs and a bright block.
// The stored bytes stay (never silently overwritten), the new ones go to quarantine with a
// message, and the same bytes again change nothing.
TEST(PacsLocalStore, DifferentBytesUnderAStoredUidGoToQuarantine) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-tamper";
    fs::remove_all(root);
    LocalStore store(root);
    const std::vector<Source> two = syntheticStudy("1.2.5", 1);
    const Source& a = two[0];
    // The last bytes of the file are pixels: another dataset under the same UIDs.
    const std::string head = a.bytes.substr(0, a.bytes.size() - 8);
    const std::string tampered = head + "tampered";
    ASSERT_NE(tampered, a.bytes);
    const StoreOutcome first = store.storeInstance(a.study, a.series, a.sop, a.bytes);
    EXPECT_EQ(first.result, StoreResult::Stored);
    EXPECT_EQ(first.path, root / "1.2.5" / a.series.seriesUid / (a.sop + ".dcm"));
    EXPECT_TRUE(first.message.empty());
    store.finishRetrieve("1.2.5", "", true); // the study is complete

    const StoreOutcome again = store.storeInstance(a.study, a.series, a.sop, tampered);
    EXPECT_EQ(again.result, StoreResult::Quarantined);
    EXPECT_EQ(readBytes(first.path), a.bytes); // untouched: equal to the source
    EXPECT_EQ(again.path.parent_path(), store.quarantineFolder());
    EXPECT_TRUE(std::regex_match(again.path.filename().string(),
                                 std::regex("[0-9]{8}T[0-9]{6}-" + a.sop + "-1\\.dcm")))
        << again.path;
    EXPECT_EQ(readBytes(again.path), tampered);
    for (const std::string& part :
         {"SOP instance " + a.sop, std::string("study 1.2.5"), again.path.string(),
          first.path.string() + " is kept unchanged"})
        EXPECT_NE(again.message.find(part), std::string::npos) << again.message;
    EXPECT_EQ(store.quarantined(), std::vector<fs::path>{again.path});

    // The same bytes as stored: nothing written, nothing new.
    const auto before = filesUnder(root);
    const StoreOutcome same = store.storeInstance(a.study, a.series, a.sop, a.bytes);
    EXPECT_EQ(same.result, StoreResult::Identical);
    EXPECT_EQ(same.path, first.path);
    EXPECT_EQ(filesUnder(root), before);
    // The same tampered bytes again: quarantined, no second copy; other bytes: a second file.
    const StoreOutcome repeated = store.storeInstance(a.study, a.series, a.sop, tampered);
    EXPECT_EQ(repeated.result, StoreResult::Quarantined);
    EXPECT_EQ(repeated.path, again.path);
    EXPECT_NE(repeated.message.find("the same bytes were quarantined before"), std::string::npos)
        << repeated.message;
    EXPECT_EQ(filesUnder(root), before);
    const StoreOutcome third = store.storeInstance(a.study, a.series, a.sop, head + "tamperd2");
    EXPECT_EQ(third.result, StoreResult::Quarantined);
    EXPECT_NE(third.path, again.path);
    EXPECT_EQ(readBytes(third.path), head + "tamperd2");
    EXPECT_EQ(readBytes(again.path), tampered);
    EXPECT_EQ(store.quarantined().size(), 2u);
    // The study stays as it was: complete, one instance (quarantine files are not its own).
    EXPECT_TRUE(store.find("1.2.5")->complete);
    EXPECT_EQ(store.find("1.2.5")->instances, 1);
    EXPECT_EQ(readBytes(first.path), a.bytes);
}

// The tamper case through what the listener and C-GET call, on a real slice when the shared
// data is there: a bright block in I70's pixels is quarantined, the stored slice kept.
TEST(PacsLocalStore, AReceivedSliceWithABrightBlockIsQuarantined) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-tamper-dataset";
    fs::remove_all(root);
    LocalStore store(root);
    const fs::path slice = fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93/CTHead70.dcm";
    DcmFileFormat file;
    std::unique_ptr<DcmDataset> synthetic;
    DcmDataset* ds = nullptr;
    if (fs::exists(slice)) {
        ASSERT_TRUE(file.loadFile(slice.c_str()).good());
        ds = file.getDataset();
        ASSERT_TRUE(ds->loadAllDataIntoMemory().good());
    } else { // without the shared data: a synthetic one
        synthetic = makeDataset("1.2.6", "1.2.6.1", "1.2.6.1.70");
        ds = synthetic.get();
    }
    const auto stored = detail::storeDataset(store, *ds);
    ASSERT_EQ(stored.outcome.result, StoreResult::Stored);
    const std::string original = readBytes(stored.outcome.path);
    EXPECT_EQ(detail::storeDataset(store, *ds).outcome.result, StoreResult::Identical);

    const Uint16* pixels = nullptr;
    unsigned long count = 0;
    ASSERT_TRUE(ds->findAndGetUint16Array(DCM_PixelData, pixels, &count).good());
    std::vector<Uint16> bright(pixels, pixels + count);
    for (unsigned long i = 0; i < std::min<unsigned long>(count, 8); ++i) bright[i] = 4000;
    ds->putAndInsertUint16Array(DCM_PixelData, bright.data(), count);
    const auto tampered = detail::storeDataset(store, *ds);
    EXPECT_EQ(tampered.outcome.result, StoreResult::Quarantined);
    EXPECT_EQ(readBytes(stored.outcome.path), original);
    EXPECT_NE(readBytes(tampered.outcome.path), original);
    EXPECT_NE(tampered.outcome.message.find(stored.sopInstanceUid), std::string::npos);
    EXPECT_NE(tampered.outcome.message.find(stored.studyUid), std::string::npos);
}

// Unsolicited stores go to an Incoming area that never mixes into a study of the Studies area,
// even under the same UIDs.
TEST(PacsLocalStore, IncomingInstancesStayApartFromStudies) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-incoming";
    fs::remove_all(root);
    LocalStore store(root);
    const SeriesRecord series{"1.2.3.1", "CT", "head", 1, 1};
    const auto asked = store.storeInstance(study("1.2.3"), series, "1.2.3.1.1", "asked");
    const auto unasked =
        store.storeInstance(study("1.2.3"), series, "1.2.3.1.1", "unasked", Area::Incoming);
    EXPECT_EQ(asked.result, StoreResult::Stored);
    EXPECT_EQ(unasked.result, StoreResult::Stored); // not a tamper: another area
    EXPECT_EQ(asked.path, root / "1.2.3/1.2.3.1/1.2.3.1.1.dcm");
    EXPECT_EQ(unasked.path, root / "incoming/1.2.3/1.2.3.1/1.2.3.1.1.dcm");
    EXPECT_EQ(readBytes(asked.path), "asked");
    EXPECT_EQ(readBytes(unasked.path), "unasked");
    EXPECT_EQ(store.seriesFolder("1.2.3", "1.2.3.1", Area::Incoming), unasked.path.parent_path());

    const auto entries = LocalStore(root).studies();
    ASSERT_EQ(entries.size(), 2u);
    std::map<Area, LocalStore::Entry> byArea;
    for (const auto& e : entries) byArea[e.area] = e;
    ASSERT_EQ(byArea.size(), 2u);
    EXPECT_EQ(byArea[Area::Studies].folder, root / "1.2.3");
    EXPECT_EQ(byArea[Area::Incoming].folder, root / "incoming/1.2.3");
    for (const auto& [area, e] : byArea) {
        EXPECT_EQ(e.study.studyUid, "1.2.3");
        EXPECT_EQ(e.instances, 1);
        ASSERT_EQ(e.series.size(), 1u);
        EXPECT_EQ(e.series[0].instances, 1);
    }
    ASSERT_TRUE(store.find("1.2.3", Area::Incoming));
    EXPECT_EQ(store.find("1.2.3", Area::Incoming)->area, Area::Incoming);
    EXPECT_EQ(store.find("1.2.3")->area, Area::Studies);

    // The listener's rule applies per area: the incoming series is complete, the other not.
    store.markReceived("1.2.3", {"1.2.3.1"}, Area::Incoming);
    EXPECT_TRUE(store.find("1.2.3", Area::Incoming)->series[0].complete);
    EXPECT_FALSE(store.find("1.2.3")->series[0].complete);
    store.remove("1.2.3", Area::Incoming);
    EXPECT_FALSE(store.find("1.2.3", Area::Incoming));
    EXPECT_FALSE(fs::exists(root / "incoming/1.2.3"));
    EXPECT_EQ(readBytes(asked.path), "asked");
    EXPECT_TRUE(store.find("1.2.3"));
}

// An index written before the Incoming area (version 1, no "incoming") is read as it is, and
// kept when the store next writes.
TEST(PacsLocalStore, AnIndexOfVersion1IsRead) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-v1";
    fs::remove_all(root);
    fs::create_directories(root / "1.2.3/1.2.3.1");
    std::ofstream(root / "1.2.3/1.2.3.1/1.2.3.1.1.dcm") << "x";
    std::ofstream(root / "index.json")
        << R"({"version": 1, "studies": {"1.2.3": {"patientName": "DOE^J", "complete": true,
             "updated": "2024-01-01T00:00:00Z", "series": {"1.2.3.1": {"modality": "CT",
             "description": "", "complete": true}}}}})";
    LocalStore store(root);
    auto entry = store.find("1.2.3");
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 1);
    EXPECT_EQ(entry->area, Area::Studies);
    store.storeInstance(study("1.2.4"), {"1.2.4.1", "MR", "", 1, 1}, "1.2.4.1.1", "y",
                        Area::Incoming);
    const nlohmann::json index = nlohmann::json::parse(readBytes(root / "index.json"));
    EXPECT_EQ(index.at("version"), 2);
    EXPECT_TRUE(index.at("studies").at("1.2.3").at("complete").get<bool>());
    EXPECT_TRUE(index.at("incoming").contains("1.2.4"));
    EXPECT_EQ(store.studies().size(), 2u);
}

TEST(PacsLocalStore, ASeriesRetrieveFillsTheStudysFieldsFromItsInstances) {
    // A series retrieve begins the entry with the UIDs alone; its first instance gives the
    // patient, date and description (and the series its modality and description).
    const fs::path root = fvr::test::tmpDir() / "pacs-store-series-fields";
    fs::remove_all(root);
    LocalStore store(root);
    store.beginRetrieve(StudyRecord{"4.5"}, "4.5.1");
    StudyRecord full = study("4.5");
    full.studyDate = "20240102";
    full.description = "CHEST";
    store.storeInstance(full, {"4.5.1", "CT", "lung", 1, 1}, "4.5.1.1", "x");
    store.finishRetrieve("4.5", "4.5.1", true);
    auto entry = store.find("4.5");
    ASSERT_TRUE(entry);
    EXPECT_EQ(entry->study.patientName, "DOE^JANE");
    EXPECT_EQ(entry->study.studyDate, "20240102");
    EXPECT_EQ(entry->study.description, "CHEST");
    ASSERT_EQ(entry->series.size(), 1u);
    EXPECT_EQ(entry->series[0].modality, "CT");
    EXPECT_EQ(entry->series[0].description, "lung");
    // A nameless entry (as an older version left it) is filled by a later full retrieve.
    store.beginRetrieve(StudyRecord{"4.6"}, "4.6.1");
    store.storeInstance(StudyRecord{"4.6"}, {"4.6.1", "", "", 1, 1}, "4.6.1.1", "x");
    store.finishRetrieve("4.6", "4.6.1", true);
    EXPECT_EQ(store.find("4.6")->study.patientName, "");
    store.beginRetrieve(StudyRecord{"4.6"}, "");
    StudyRecord named = study("4.6");
    store.storeInstance(named, {"4.6.1", "MR", "t1", 1, 1}, "4.6.1.1", "x"); // identical
    store.finishRetrieve("4.6", "", true);
    entry = store.find("4.6");
    ASSERT_TRUE(entry);
    EXPECT_EQ(entry->study.patientName, "DOE^JANE");
    EXPECT_EQ(entry->series.at(0).modality, "MR");
    EXPECT_TRUE(entry->complete);
}

TEST(PacsLocalStore, AReceivedStudyIsCompleteWhenAllItsSeriesAre) {
    // What a peer pushed (Incoming) and sent whole: its series complete, so is the study; a
    // study with a series still partial is not.
    const fs::path root = fvr::test::tmpDir() / "pacs-store-pushed";
    fs::remove_all(root);
    LocalStore store(root);
    for (const char* s : {"7.1.1", "7.1.2"})
        store.storeInstance(study("7.1"), {s, "CT", "", 1, 1}, std::string(s) + ".1", "x",
                            Area::Incoming);
    store.markReceived("7.1", {"7.1.1"}, Area::Incoming);
    EXPECT_FALSE(store.find("7.1", Area::Incoming)->complete); // 7.1.2 not yet
    store.markReceived("7.1", {"7.1.2"}, Area::Incoming);
    const auto entry = store.find("7.1", Area::Incoming);
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->study.patientName, "DOE^JANE");
}

TEST(PacsLocalStore, AStudyWithASeriesLeftPartialIsPartial) {
    // A complete study; one of its series retrieved again (a refresh) and cancelled: that series
    // is partial, and so is the study, until a retrieve completes the series.
    const fs::path root = fvr::test::tmpDir() / "pacs-store-series-partial";
    fs::remove_all(root);
    LocalStore store(root);
    store.beginRetrieve(study("8.1"), "");
    for (const char* s : {"8.1.1", "8.1.2"})
        store.storeInstance(study("8.1"), {s, "CT", "", 1, 1}, std::string(s) + ".1", "x");
    store.finishRetrieve("8.1", "", true);
    ASSERT_TRUE(store.find("8.1")->complete);
    store.beginRetrieve(study("8.1"), "8.1.2");
    store.finishRetrieve("8.1", "8.1.2", false); // cancelled
    auto entry = store.find("8.1");
    ASSERT_TRUE(entry);
    EXPECT_FALSE(entry->complete);
    ASSERT_EQ(entry->series.size(), 2u);
    EXPECT_TRUE(entry->series[0].complete);
    EXPECT_FALSE(entry->series[1].complete);
    store.beginRetrieve(study("8.1"), "8.1.2");
    store.finishRetrieve("8.1", "8.1.2", true);
    EXPECT_TRUE(store.find("8.1")->complete);
}

// The user's Delete: refused while a retrieve runs on the study (saying so), then the study's
// entry and files go; its source node (for Resume) is kept in the index until then.
TEST(PacsLocalStore, DeleteStudyRefusesARunningRetrieveThenRemovesEntryAndFiles) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-delete";
    fs::remove_all(root);
    LocalStore store(root);
    store.beginRetrieve(study("1.2.7"), "");
    const SeriesRecord series{"1.2.7.1", "CT", "head", 1, 1};
    const fs::path file = store.storeInstance(study("1.2.7"), series, "1.2.7.1.1", "DICM-a").path;
    store.setSource("1.2.7", "Main PACS");
    EXPECT_NE(errorOf([&] { store.deleteStudy("1.2.7"); }).find("is being retrieved"),
              std::string::npos);
    EXPECT_TRUE(fs::exists(file)); // nothing removed
    store.finishRetrieve("1.2.7", "", false);
    EXPECT_EQ(LocalStore(root).find("1.2.7")->source, "Main PACS"); // read back from disk
    store.deleteStudy("1.2.7");
    EXPECT_FALSE(store.find("1.2.7"));
    EXPECT_FALSE(fs::exists(root / "1.2.7"));
    EXPECT_NE(errorOf([&] { store.deleteStudy("1.2.7"); }).find("is not in the local store"),
              std::string::npos);
}
