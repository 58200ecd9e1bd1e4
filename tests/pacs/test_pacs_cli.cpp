// fvr-render and the PACS: a dicom:// INPUT renders as the same folder does, --query prints
// JSON, --send stores the views on Orthanc.
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/pacs/local_store.h>

#include "pacs_environment.h"
#include "test_support.h"

namespace fs = std::filesystem;
using fvr::test::PacsEnvironment;

namespace {

PacsEnvironment& env() { return PacsEnvironment::get(); }

std::string nodeUrl(int port = 0) {
    return "dicom://ORTHANC@127.0.0.1:" + std::to_string(port ? port : env().orthanc().dicomPort());
}

std::string slicerTag(const char* tag) {
    return fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer), tag);
}

std::string readAll(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/** fvr-render with `args`; stdout returned, stderr in `err`. */
fvr::test::CommandOutput render(const std::string& args, const fs::path& err) {
    return fvr::test::runCommand(std::string(FVR_RENDER_EXE) + " " + args + " --ae-title " +
                                 fvr::test::kOurAe + " 2>" + err.string());
}

} // namespace

TEST(PacsCli, DicomInputRendersAsTheFolderAndThenOpensFromTheStore) {
    FVR_REQUIRE_ORTHANC();
    const fs::path dir = env().dir / "cli-render";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string common = " --backend cpu --size 128 --view AP";
    const auto local = render((fvr::test::sharedData() / fvr::test::kSlicer).string() + common +
                                  " --out " + (dir / "local.npy").string(),
                              dir / "local.err");
    ASSERT_EQ(local.status, 0) << readAll(dir / "local.err");
    const std::string url = nodeUrl() + "/" + slicerTag("StudyInstanceUID");
    const std::string store = " --store " + (dir / "store").string();
    auto r =
        render(url + common + store + " --out " + (dir / "pacs.npy").string(), dir / "pacs.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "pacs.err");
    EXPECT_NE(readAll(dir / "pacs.err").find("retrieved study"), std::string::npos);
    EXPECT_EQ(readAll(dir / "local.npy"), readAll(dir / "pacs.npy"));
    // Complete in the store: the same study opens with the PACS unreachable.
    const std::string closed =
        nodeUrl(fvr::test::freeLoopbackPort()) + "/" + slicerTag("StudyInstanceUID");
    r = render(closed + common + store + " --out " + (dir / "again.npy").string(),
               dir / "again.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "again.err");
    EXPECT_EQ(readAll(dir / "local.npy"), readAll(dir / "again.npy"));
}

TEST(PacsCli, MoveOfASeries) {
    FVR_REQUIRE_ORTHANC();
    const fs::path dir = env().dir / "cli-move";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string url =
        nodeUrl() + "/" + slicerTag("StudyInstanceUID") + "/" + slicerTag("SeriesInstanceUID");
    const auto r =
        render(url + " --retrieve move --listen-port " + std::to_string(env().local().listenPort) +
                   " --store " + (dir / "store").string() + " --info",
               dir / "err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "err");
    const auto info = nlohmann::json::parse(r.out); // the retrieved folder's series
    ASSERT_EQ(info["series"].size(), 1u) << r.out;
    EXPECT_EQ(info["series"][0]["dims"], nlohmann::json({64, 64, 93})) << r.out;
    EXPECT_NE(readAll(dir / "err").find("(C-MOVE, 93 images in "), std::string::npos)
        << readAll(dir / "err");
}

TEST(PacsCli, ListenAddressMustBeAnIpv4Address) {
    FVR_REQUIRE_ORTHANC();
    const fs::path err = env().dir / "listen-address.err";
    const std::string url = nodeUrl() + "/" + slicerTag("StudyInstanceUID");
    const auto r = render(url + " --retrieve move --listen-address 10.0.0.300 --info", err);
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(readAll(err).find("the listen address \"10.0.0.300\" is not an IPv4 address"),
              std::string::npos)
        << readAll(err);
}

TEST(PacsCli, QueryPrintsTheMatchingStudiesAsJson) {
    FVR_REQUIRE_ORTHANC();
    const fs::path err = env().dir / "query.err";
    auto r = render(nodeUrl() + " --query PatientName=HE* --query-series", err);
    ASSERT_EQ(r.status, 0) << readAll(err);
    auto j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j.size(), 1u) << r.out;
    EXPECT_EQ(j[0]["patientName"], "HEAD");
    EXPECT_EQ(j[0]["numberOfInstances"], 140);
    ASSERT_EQ(j[0]["series"].size(), 1u);
    EXPECT_EQ(j[0]["series"][0]["modality"], "CT");
    EXPECT_EQ(j[0]["url"], nodeUrl() + "/" + j[0]["studyUid"].get<std::string>());
    r = render(nodeUrl() + " --query StudyDate=-20100101,Modality=CT", err);
    ASSERT_EQ(r.status, 0) << readAll(err);
    j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j.size(), 1u) << r.out; // the Slicer head (2009); the 1999 study is MR
    EXPECT_EQ(j[0]["studyUid"], slicerTag("StudyInstanceUID"));
    r = render(nodeUrl() + " --query StudyDate=2015", err);
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(readAll(err).find("--query: 'StudyDate=2015': expected"), std::string::npos);
}

TEST(PacsCli, SendStoresEveryViewOnThePacs) {
    FVR_REQUIRE_ORTHANC();
    const fs::path dir = env().dir / "cli-send";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const auto r = render("phantom:shepp-logan:64 --backend cpu --size 128 --sweep 2 --out " +
                              (dir / "view.dcm").string() + " --send " + nodeUrl(),
                          dir / "err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "err");
    EXPECT_NE(readAll(dir / "err").find("sent 2 views to ORTHANC@127.0.0.1:"), std::string::npos);
    for (const char* name : {"view_0000.dcm", "view_0001.dcm"}) {
        const fs::path file = dir / name;
        const std::string sop = fvr::test::dicomTag(file, "SOPInstanceUID");
        const auto ids = nlohmann::json::parse(env().orthanc().post("/tools/lookup", sop).body);
        ASSERT_EQ(ids.size(), 1u) << name;
        const std::string id = ids[0]["ID"];
        const auto tags =
            nlohmann::json::parse(env().orthanc().get("/instances/" + id + "/tags?simplify").body);
        EXPECT_EQ(tags["SOPInstanceUID"], sop);
        EXPECT_EQ(tags["SOPClassUID"], fvr::test::dicomTag(file, "SOPClassUID"));
        const fs::path back = dir / (std::string("back_") + name);
        std::ofstream(back, std::ios::binary)
            << env().orthanc().get("/instances/" + id + "/file").body;
        EXPECT_TRUE(fvr::core::loadDicomFile(file).volume.voxels ==
                    fvr::core::loadDicomFile(back).volume.voxels);
    }
}

TEST(PacsCli, SendStoresConeBeamViewsAsXraysThatCarryTheirCArm) {
    FVR_REQUIRE_ORTHANC();
    const fs::path dir = env().dir / "cli-send-cone";
    fs::remove_all(dir);
    fs::create_directories(dir);
    // A .dcm orbit: its one multi-frame XA, sent as written (the same bytes come back).
    const fs::path run = dir / "run.dcm";
    auto r = render("phantom:chest:32 --geometry cone --detector-size 32x24 --orbit 0:60:3 --out " +
                        run.string() + " --send " + nodeUrl(),
                    dir / "err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "err");
    EXPECT_NE(readAll(dir / "err").find("sent 1 file to ORTHANC@127.0.0.1:"), std::string::npos)
        << readAll(dir / "err");
    EXPECT_NE(readAll(dir / "err").find("(X-Ray Angiographic, C-STORE)"), std::string::npos);
    const auto instance = [&](const fs::path& file) {
        const std::string sop = fvr::test::dicomTag(file, "SOPInstanceUID");
        const auto ids = nlohmann::json::parse(env().orthanc().post("/tools/lookup", sop).body);
        return ids.size() == 1 ? std::string(ids[0]["ID"]) : std::string();
    };
    const std::string id = instance(run);
    ASSERT_FALSE(id.empty());
    EXPECT_EQ(env().orthanc().get("/instances/" + id + "/file").body, readAll(run));
    const auto tags =
        nlohmann::json::parse(env().orthanc().get("/instances/" + id + "/tags?simplify").body);
    EXPECT_EQ(tags["Modality"], "XA");
    EXPECT_EQ(tags["NumberOfFrames"], "3");
    EXPECT_EQ(tags["PositionerPrimaryAngleIncrement"], "0\\30\\60");
    // A .npy output: each view sent as its own XA, at its own primary angle.
    r = render("phantom:chest:32 --geometry cone --detector-size 32x24 --sweep 2 "
               "--primary-angle 20 --out " +
                   (dir / "views.npy").string() + " --send " + nodeUrl(),
               dir / "err2");
    ASSERT_EQ(r.status, 0) << readAll(dir / "err2");
    EXPECT_NE(readAll(dir / "err2").find("sent 2 files to ORTHANC@127.0.0.1:"), std::string::npos)
        << readAll(dir / "err2");
    // On the PACS: XA instances at the sweep's primary angles, 20 and 200 degrees.
    const auto xa = nlohmann::json::parse(
        env()
            .orthanc()
            .post("/tools/find", R"({"Level": "Instance", "Query": {"Modality": "XA"}})")
            .body);
    std::vector<std::string> angles;
    for (const auto& xid : xa) {
        const auto t = nlohmann::json::parse(
            env().orthanc().get("/instances/" + std::string(xid) + "/tags?simplify").body);
        if (!t.contains("NumberOfFrames")) angles.push_back(t["PositionerPrimaryAngle"]);
    }
    EXPECT_NE(std::find(angles.begin(), angles.end(), "20"), angles.end());
    EXPECT_NE(std::find(angles.begin(), angles.end(), "200"), angles.end());
}

TEST(PacsCli, SendStoresTreatmentBeamsAsRtImages) {
    FVR_REQUIRE_ORTHANC();
    const fs::path dir = env().dir / "cli-send-beam";
    fs::remove_all(dir);
    fs::create_directories(dir);
    // A .dcm output of one beam: its RT Image, sent as written (the same bytes come back).
    const fs::path dcm = dir / "beam.dcm";
    auto r =
        render("phantom:chest:32 --geometry cone --detector-size 32x24 --beam 45,10,15 --out " +
                   dcm.string() + " --send " + nodeUrl(),
               dir / "err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "err");
    EXPECT_NE(readAll(dir / "err").find("sent 1 file to ORTHANC@127.0.0.1:"), std::string::npos)
        << readAll(dir / "err");
    EXPECT_NE(readAll(dir / "err").find("(RT Image, C-STORE)"), std::string::npos)
        << readAll(dir / "err");
    const std::string sop = fvr::test::dicomTag(dcm, "SOPInstanceUID");
    const auto ids = nlohmann::json::parse(env().orthanc().post("/tools/lookup", sop).body);
    ASSERT_EQ(ids.size(), 1u);
    const std::string id = ids[0]["ID"];
    EXPECT_EQ(env().orthanc().get("/instances/" + id + "/file").body, readAll(dcm));
    const auto tags =
        nlohmann::json::parse(env().orthanc().get("/instances/" + id + "/tags?simplify").body);
    EXPECT_EQ(tags["Modality"], "RTIMAGE");
    EXPECT_EQ(tags["GantryAngle"], "45");
    EXPECT_EQ(tags["PatientSupportAngle"], "10");
    EXPECT_EQ(tags["BeamLimitingDeviceAngle"], "15");
    // A .npy output: the beam sent as its own RT Image.
    r = render("phantom:chest:32 --geometry cone --detector-size 32x24 --beam 270,0,0 --out " +
                   (dir / "beam.npy").string() + " --send " + nodeUrl(),
               dir / "err2");
    ASSERT_EQ(r.status, 0) << readAll(dir / "err2");
    EXPECT_NE(readAll(dir / "err2").find("sent 1 file to ORTHANC@127.0.0.1:"), std::string::npos)
        << readAll(dir / "err2");
    const auto rt = nlohmann::json::parse(
        env()
            .orthanc()
            .post("/tools/find",
                  R"({"Level": "Instance", "Query": {"Modality": "RTIMAGE"}, "Expand": true})")
            .body);
    std::vector<std::string> gantry;
    for (const auto& inst : rt) {
        const auto t = nlohmann::json::parse(
            env().orthanc().get("/instances/" + std::string(inst["ID"]) + "/tags?simplify").body);
        gantry.push_back(t["GantryAngle"]);
    }
    EXPECT_NE(std::find(gantry.begin(), gantry.end(), "270"), gantry.end());
}

namespace {

/** How many instances Orthanc holds of a study (its REST API): the oracle of "N of M". */
int orthancStudyInstances(const std::string& studyUid) {
    const std::string id = env().orthanc().lookup(studyUid);
    if (id.empty()) return -1;
    return int(
        nlohmann::json::parse(env().orthanc().get("/studies/" + id + "/instances").body).size());
}

/** Deletes every `step`-th file of `folder` (sorted by name), as an interrupted retrieve leaves
 *  a study; returns the names deleted. */
std::set<std::string> deleteEvery(const fs::path& folder, int step) {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(folder)) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    std::set<std::string> gone;
    for (std::size_t i = 0; i < files.size(); i += step) {
        fs::remove(files[i]);
        gone.insert(files[i].filename().string());
    }
    return gone;
}

std::set<std::string> fileNames(const fs::path& folder) {
    std::set<std::string> out;
    for (const auto& e : fs::directory_iterator(folder)) out.insert(e.path().filename().string());
    return out;
}

/** Lists the study (and `seriesUid`, when not empty) partial, as a retrieve that did not finish
 *  leaves them (the store's own API). */
void markPartial(const fs::path& root, const std::string& studyUid, const std::string& seriesUid) {
    fvr::core::pacs::LocalStore store(root);
    store.beginRetrieve(fvr::core::pacs::StudyRecord{studyUid}, seriesUid);
    store.finishRetrieve(studyUid, seriesUid, false);
}

} // namespace

TEST(PacsCli, APartialStudyFetchesOnlyTheMissingImages) {
    FVR_REQUIRE_ORTHANC();
    const fs::path dir = env().dir / "cli-partial";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string study = slicerTag("StudyInstanceUID"),
                      series = slicerTag("SeriesInstanceUID");
    const int total = orthancStudyInstances(study);
    ASSERT_EQ(total, 93);
    const std::string common =
        " --backend cpu --size 128 --view AP --store " + (dir / "store").string() + " --out ";
    auto r = render((fvr::test::sharedData() / fvr::test::kSlicer).string() + common +
                        (dir / "local.npy").string(),
                    dir / "local.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "local.err");
    r = render(nodeUrl() + "/" + study + common + (dir / "full.npy").string(), dir / "full.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "full.err");
    ASSERT_NE(readAll(dir / "full.err").find("(C-GET, 93 images in "), std::string::npos)
        << readAll(dir / "full.err");
    const fs::path seriesDir = dir / "store" / study / series;
    const std::set<std::string> all = fileNames(seriesDir);
    ASSERT_EQ(all.size(), 93u);

    // The study partial, 14 of its files gone: only those 14 are retrieved, by C-GET.
    std::set<std::string> gone = deleteEvery(seriesDir, 7);
    ASSERT_EQ(gone.size(), 14u);
    markPartial(dir / "store", study, "");
    ASSERT_FALSE(fvr::core::pacs::LocalStore(dir / "store").find(study)->complete);
    const int sentBefore = env().orthanc().imagesSentByGet(); // Orthanc's own count
    r = render(nodeUrl() + "/" + study + common + (dir / "resumed.npy").string(),
               dir / "resumed.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "resumed.err");
    EXPECT_EQ(env().orthanc().imagesSentByGet() - sentBefore, 14);
    const std::string said = readAll(dir / "resumed.err");
    const std::size_t at = said.rfind("retrieved");
    if (at != std::string::npos) // the summary line, for the timings
        std::printf("[ resume   ] %s\n", said.substr(at, said.find('\n', at) - at).c_str());
    EXPECT_NE(said.find("retrieved study " + study + " from ORTHANC@127.0.0.1:"), std::string::npos)
        << said;
    EXPECT_NE(said.find("(C-GET, 14 of 93 images fetched, 79 already local, in "),
              std::string::npos)
        << said;
    EXPECT_EQ(fileNames(seriesDir), all); // the deleted ones back, nothing else
    EXPECT_TRUE(fvr::core::pacs::LocalStore(dir / "store").find(study)->complete);
    EXPECT_EQ(readAll(dir / "local.npy"), readAll(dir / "resumed.npy"));

    // A partial series, named in the URL: its 10 missing images, by C-MOVE.
    gone = deleteEvery(seriesDir, 10);
    ASSERT_EQ(gone.size(), 10u);
    markPartial(dir / "store", study, ""); // a series partial: its study too
    markPartial(dir / "store", study, series);
    r = render(nodeUrl() + "/" + study + "/" + series + " --retrieve move --listen-port " +
                   std::to_string(env().local().listenPort) + common +
                   (dir / "series.npy").string(),
               dir / "series.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "series.err");
    EXPECT_NE(readAll(dir / "series.err")
                  .find("retrieved series " + series +
                        " from ORTHANC@127.0.0.1:" + std::to_string(env().orthanc().dicomPort()) +
                        " (C-MOVE, 10 of 93 images fetched, 83 already local, in "),
              std::string::npos)
        << readAll(dir / "series.err");
    EXPECT_EQ(fileNames(seriesDir), all);
    EXPECT_EQ(readAll(dir / "local.npy"), readAll(dir / "series.npy"));
}

TEST(PacsCli, RefreshRetrievesACompleteStudyAgain) {
    FVR_REQUIRE_ORTHANC();
    const fs::path dir = env().dir / "cli-refresh";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string study = slicerTag("StudyInstanceUID");
    const std::string store = " --store " + (dir / "store").string() + " --info";
    auto r = render(nodeUrl() + "/" + study + store, dir / "first.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "first.err");
    const fs::path folder = dir / "store" / study;
    // Complete: nothing retrieved (Orthanc sends nothing), and the stderr says where it was.
    const int sentBefore = env().orthanc().imagesSentByGet();
    r = render(nodeUrl() + "/" + study + store, dir / "again.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "again.err");
    EXPECT_EQ(env().orthanc().imagesSentByGet(), sentBefore);
    EXPECT_NE(readAll(dir / "again.err")
                  .find("study " + study + " is complete in the local store (" + folder.string() +
                        "): nothing retrieved"),
              std::string::npos)
        << readAll(dir / "again.err");
    EXPECT_EQ(readAll(dir / "again.err").find("retrieved study"), std::string::npos);
    // --refresh: all 93 from the PACS again (Orthanc holds 93), so it needs the PACS.
    r = render(nodeUrl() + "/" + study + store + " --refresh", dir / "refresh.err");
    ASSERT_EQ(r.status, 0) << readAll(dir / "refresh.err");
    EXPECT_EQ(env().orthanc().imagesSentByGet() - sentBefore, 93);
    EXPECT_NE(readAll(dir / "refresh.err").find("(C-GET, 93 images in "), std::string::npos)
        << readAll(dir / "refresh.err");
    EXPECT_EQ(orthancStudyInstances(study), 93);
    const auto info = nlohmann::json::parse(r.out);
    ASSERT_EQ(info["series"].size(), 1u) << r.out;
    EXPECT_EQ(info["series"][0]["dims"], nlohmann::json({64, 64, 93})) << r.out;
    r = render(nodeUrl(fvr::test::freeLoopbackPort()) + "/" + study + store + " --refresh",
               dir / "closed.err");
    EXPECT_EQ(r.status, 1) << readAll(dir / "closed.err");
    // Not for a folder, nor with --query.
    r = render((fvr::test::sharedData() / fvr::test::kSlicer).string() + " --info --refresh",
               dir / "folder.err");
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(readAll(dir / "folder.err").find("--refresh: INPUT must be a study"),
              std::string::npos)
        << readAll(dir / "folder.err");
}
