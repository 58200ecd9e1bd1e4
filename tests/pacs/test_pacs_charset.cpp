// Patients named in Latin-1, UTF-8, ISO 2022 Japanese and Greek against a real Orthanc: each is
// found (C-FIND shows the name in UTF-8), retrieved (C-GET and C-MOVE: the index holds the name
// in UTF-8, the files the bytes Orthanc sent), opened (the study's name), exported (ISO_IR 192,
// dciodvfy without errors) and sent back (Orthanc reads the name we meant). The studies are
// written by the test and removed from Orthanc after it (the other tests count studies).
#include <fvr/core/dicom/dicom.h>
#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>

#include <nlohmann/json.hpp>

#include <sstream>

#include "charset_cases.h"
#include "pacs_environment.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace fvr::core;
using namespace fvr::core::pacs;
using fvr::test::CharsetCase;
using fvr::test::PacsEnvironment;

namespace {

PacsEnvironment& env() { return PacsEnvironment::get(); }

/** Removes the studies from Orthanc however the test ends. */
struct RemoveFromOrthanc {
    std::vector<std::string> studyUids;
    ~RemoveFromOrthanc() {
        for (const std::string& uid : studyUids)
            if (const std::string id = env().orthanc().lookup(uid); !id.empty())
                env().orthanc().remove("/studies/" + id);
    }
};

/** dciodvfy's error lines on `path` (none when it is not installed). */
std::vector<std::string> dciodvfyErrors(const fs::path& path) {
    const auto r = fvr::test::runCommand("dciodvfy -new '" + path.string() + "' 2>&1");
    std::vector<std::string> out;
    std::istringstream in(r.out);
    for (std::string line; std::getline(in, line);)
        if (line.rfind("Error", 0) == 0) out.push_back(line);
    return out;
}

/** Sets Orthanc's DefaultEncoding (the set its C-FIND answers are in); puts the one it had
 *  back however the test ends. */
struct OrthancEncoding {
    std::string before = env().orthanc().get("/tools/default-encoding").body;
    ~OrthancEncoding() { env().orthanc().put("/tools/default-encoding", before); }
    void set(const std::string& encoding) const {
        const auto r = env().orthanc().put("/tools/default-encoding", encoding);
        ASSERT_EQ(r.status, 200) << encoding << ": " << r.body;
    }
};

/** The case's study: found by its patient ID, its name in UTF-8 (Orthanc answers in the case's
 *  own character set). */
void expectFound(const CharsetCase& c, const std::string& studyUid) {
    OrthancEncoding encoding;
    encoding.set(c.orthancEncoding);
    StudyQuery q;
    q.patientId = "CS-" + c.label;
    const auto found = findStudies(env().node(), env().local(), q);
    ASSERT_EQ(found.size(), 1u) << c.label;
    EXPECT_EQ(found[0].studyUid, studyUid);
    EXPECT_EQ(found[0].patientName, c.utf8) << c.label;
    if (!c.description.empty()) EXPECT_EQ(found[0].description, c.descriptionUtf8) << c.label;
}

/** Retrieved by `node`'s method into `store`: complete, the index's name in UTF-8, the study
 *  opens with that name. Returns the scanned series. */
DicomSeriesInfo expectRetrievedAndOpened(const CharsetCase& c, const Node& node,
                                         const std::string& studyUid, LocalStore& store) {
    fs::path folder;
    EXPECT_NO_THROW(folder = retrieve(node, env().local(), studyUid, "", store)) << c.label;
    const auto entry = store.find(studyUid);
    EXPECT_TRUE(entry && entry->complete) << c.label;
    if (entry) EXPECT_EQ(entry->study.patientName, c.utf8) << c.label;
    if (entry && !c.description.empty())
        EXPECT_EQ(entry->study.description, c.descriptionUtf8) << c.label;
    const auto scan = scanDicomFolder(store.studyFolder(studyUid));
    EXPECT_EQ(scan.series.size(), 1u) << c.label;
    if (scan.series.empty()) return {};
    EXPECT_EQ(scan.series[0].patientName, c.utf8) << c.label;
    return scan.series[0];
}

/** An export from the opened series declares ISO_IR 192, passes dciodvfy, and Orthanc reads
 *  the name we meant once it is sent. */
void expectExportedAndSent(const CharsetCase& c, const DicomSeriesInfo& series) {
    ProjectionImage img;
    img.width = img.height = 16;
    img.pixelSize = 1.0;
    img.pixels.assign(16 * 16, 2.0f);
    const fs::path file = env().dir / ("charset-" + c.label + "-sc.dcm");
    writeDicomProjection(file, img, exportInfoFor(series));
    EXPECT_EQ(fvr::test::dicomTag(file, "SpecificCharacterSet"), "ISO_IR 192") << c.label;
    const auto errors = dciodvfyErrors(file);
    EXPECT_TRUE(errors.empty()) << c.label << ": " << ::testing::PrintToString(errors);
    ASSERT_NO_THROW(sendFiles(env().node(), env().local(), {file})) << c.label;
    const std::string id = env().orthanc().lookup(fvr::test::dicomTag(file, "SOPInstanceUID"));
    ASSERT_FALSE(id.empty()) << c.label;
    const auto tags =
        nlohmann::json::parse(env().orthanc().get("/instances/" + id + "/tags?simplify").body);
    EXPECT_EQ(tags.value("PatientName", ""), c.utf8) << c.label;
    EXPECT_EQ(tags.value("StudyInstanceUID", ""), series.studyUid) << c.label;
}

} // namespace

TEST(PacsCharset, EachSetIsFoundRetrievedOpenedExportedAndSent) {
    FVR_REQUIRE_ORTHANC();
    RemoveFromOrthanc cleanup;
    const fs::path slicer = fvr::test::sharedData() / fvr::test::kSlicer;
    LocalStore getStore(fvr::test::storeRoot("charset-get"));
    LocalStore moveStore(fvr::test::storeRoot("charset-move"));
    Node moveNode = env().node();
    moveNode.retrieve = RetrieveMethod::Move;
    for (const CharsetCase& c : fvr::test::charsetCases()) {
        const fs::path dir = env().dir / ("charset-" + c.label);
        fs::remove_all(dir);
        const auto uids = fvr::test::writeCharsetStudy(c, slicer, dir, 3);
        cleanup.studyUids.push_back(uids.studyUid);
        ASSERT_EQ(env().orthanc().upload(dir), 3) << c.label << "\n" << env().orthanc().log();
        expectFound(c, uids.studyUid);
        const DicomSeriesInfo series =
            expectRetrievedAndOpened(c, env().node(), uids.studyUid, getStore);
        expectRetrievedAndOpened(c, moveNode, uids.studyUid, moveStore);
        // The received files are what Orthanc sent: the name's own bytes under its set.
        if (!series.files.empty()) {
            EXPECT_EQ(fvr::test::dicomTag(series.files[0], "SpecificCharacterSet"), c.charset);
            EXPECT_EQ(fvr::test::dicomTag(series.files[0], "PatientName"), c.raw) << c.label;
            expectExportedAndSent(c, series);
        }
    }
}
