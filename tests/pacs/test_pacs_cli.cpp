// fvr-render and the PACS: a dicom:// INPUT renders as the same folder does, --query prints
// JSON, --send stores the views on Orthanc.
#include <algorithm>
#include <fstream>
#include <iterator>

#include <nlohmann/json.hpp>

#include <fvr/core/dicom/dicom.h>

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
