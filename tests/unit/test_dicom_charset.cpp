// Character sets end to end without a PACS: files in Latin-1, UTF-8, ISO 2022 Japanese and Greek
// are read with their names in UTF-8 (scan, received instance into the local store's index), a
// file whose bytes its set does not explain gets U+FFFD and a warning naming the element, and
// an export from them declares ISO_IR 192 and holds the UTF-8 bytes.
#include <fvr/core/dicom/dicom.h>
#include <fvr/core/dicom/dicom_export.h>

#include <gtest/gtest.h>

#include "charset_cases.h"
#include "dicom/dicom_charset.h"
#include "pacs_local_test_support.h"

using namespace fvr::test::pacs_local;
using fvr::test::CharsetCase;
using fvr::test::charsetCases;

namespace {

fs::path slicer() { return fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93"; }

fs::path caseDir(const std::string& name) {
    const fs::path dir = fvr::test::tmpDir() / ("charset-" + std::to_string(::getpid())) / name;
    fs::remove_all(dir);
    return dir;
}

std::string allWarnings(const fvr::core::DicomSeriesInfo& s) {
    std::string all;
    for (const auto& w : s.warnings) all += w + "\n";
    return all;
}

/** A file's element as its raw bytes ("" when absent). */
std::string rawTag(const fs::path& file, const DcmTagKey& tag) {
    DcmFileFormat ff;
    OFString value;
    if (ff.loadFile(file.c_str()).good()) ff.getDataset()->findAndGetOFStringArray(tag, value);
    return std::string(value.c_str(), value.length());
}

} // namespace

TEST(DicomCharset, ScanGivesNamesInUtf8) {
    if (!fs::exists(slicer())) GTEST_SKIP() << "shared data not found: " << slicer();
    for (const CharsetCase& c : charsetCases()) {
        const fs::path dir = caseDir("scan-" + c.label);
        fvr::test::writeCharsetStudy(c, slicer(), dir, 3);
        const auto scan = fvr::core::scanDicomFolder(dir);
        ASSERT_EQ(scan.series.size(), 1u) << c.label;
        const auto& s = scan.series[0];
        EXPECT_EQ(s.patientName, c.utf8) << c.label;
        if (!c.description.empty()) EXPECT_EQ(s.study.studyDescription, c.descriptionUtf8);
        EXPECT_EQ(allWarnings(s).find("U+FFFD"), std::string::npos) << allWarnings(s);
    }
}

TEST(DicomCharset, BytesNoSetExplainsGetReplacementAndAWarning) {
    if (!fs::exists(slicer())) GTEST_SKIP() << "shared data not found: " << slicer();
    // Latin-1 bytes with no SpecificCharacterSet, and bytes that are not ISO 2022 (0xFC) under
    // the Japanese set: each bad byte becomes U+FFFD, and the warning names the element.
    const std::vector<CharsetCase> bad{
        {"undeclared", "", "M\xFCller^Hans", "M\xEF\xBF\xBDller^Hans", "", ""},
        {"notjis", "\\ISO 2022 IR 87", "M\xFCller", "M\xEF\xBF\xBDller", "", ""}};
    for (const CharsetCase& c : bad) {
        const fs::path dir = caseDir("bad-" + c.label);
        fvr::test::writeCharsetStudy(c, slicer(), dir, 1);
        const auto scan = fvr::core::scanDicomFolder(dir);
        ASSERT_EQ(scan.series.size(), 1u);
        EXPECT_EQ(scan.series[0].patientName, c.utf8) << c.label;
        const std::string w = allWarnings(scan.series[0]);
        EXPECT_NE(w.find("PatientName (0010,0010)"), std::string::npos) << w;
        EXPECT_NE(w.find("U+FFFD"), std::string::npos) << w;
    }
}

TEST(DicomCharset, ValidUtf8ReplacesEachBadByte) {
    using fvr::core::dicom_detail::validUtf8;
    bool replaced = true;
    EXPECT_EQ(validUtf8("M\xC3\xBCller", &replaced), "M\xC3\xBCller");
    EXPECT_FALSE(replaced);
    EXPECT_EQ(validUtf8("\xFC\xC3", &replaced), "\xEF\xBF\xBD\xEF\xBF\xBD");
    EXPECT_TRUE(replaced);
    EXPECT_EQ(validUtf8("\xC0\xAF"), "\xEF\xBF\xBD\xEF\xBF\xBD"); // overlong '/'
    EXPECT_EQ(validUtf8("\xED\xA0\x80"), "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD"); // a surrogate
}

TEST(DicomCharset, AReceivedInstanceIsIndexedInUtf8AndKeptAsItCame) {
    if (!fs::exists(slicer())) GTEST_SKIP() << "shared data not found: " << slicer();
    const fs::path root = caseDir("store");
    LocalStore store(root);
    for (const CharsetCase& c : charsetCases()) {
        const fs::path dir = caseDir("recv-" + c.label);
        const auto uids = fvr::test::writeCharsetStudy(c, slicer(), dir, 1);
        DcmFileFormat file;
        ASSERT_TRUE(file.loadFile((dir / "cs_0.dcm").c_str()).good());
        const auto stored = detail::storeDataset(store, *file.getDataset());
        const auto entry = store.find(uids.studyUid);
        ASSERT_TRUE(entry) << c.label;
        EXPECT_EQ(entry->study.patientName, c.utf8) << c.label;
        if (!c.description.empty()) EXPECT_EQ(entry->study.description, c.descriptionUtf8);
        // The file keeps the bytes and the set it came with.
        EXPECT_EQ(rawTag(stored.outcome.path, DCM_PatientName), c.raw) << c.label;
        EXPECT_EQ(rawTag(stored.outcome.path, DCM_SpecificCharacterSet), c.charset) << c.label;
    }
}

TEST(DicomCharset, AnExportDeclaresUtf8) {
    if (!fs::exists(slicer())) GTEST_SKIP() << "shared data not found: " << slicer();
    for (const CharsetCase& c : charsetCases()) {
        const fs::path dir = caseDir("export-" + c.label);
        fvr::test::writeCharsetStudy(c, slicer(), dir / "in", 2);
        const auto scan = fvr::core::scanDicomFolder(dir / "in");
        ASSERT_EQ(scan.series.size(), 1u);
        fvr::core::ProjectionImage img;
        img.width = img.height = 8;
        img.pixelSize = 1.0;
        img.pixels.assign(64, 1.0f);
        const fs::path out = dir / "sc.dcm";
        fvr::core::writeDicomProjection(out, img, fvr::core::exportInfoFor(scan.series[0]));
        EXPECT_EQ(rawTag(out, DCM_SpecificCharacterSet), "ISO_IR 192") << c.label;
        EXPECT_EQ(rawTag(out, DCM_PatientName), c.utf8) << c.label;
        if (!c.description.empty())
            EXPECT_EQ(rawTag(out, DCM_StudyDescription), c.descriptionUtf8) << c.label;
        // Read back: the same name.
        EXPECT_EQ(fvr::core::scanDicomFolder(out).series.at(0).patientName, c.utf8) << c.label;
    }
}

TEST(DicomCharset, AReceivedNameNoSetExplainsIsIndexedWithReplacementAndSaid) {
    if (!fs::exists(slicer())) GTEST_SKIP() << "shared data not found: " << slicer();
    const CharsetCase undeclared{"undeclared", "", "M\xFCller^Hans", "M\xEF\xBF\xBDller^Hans",
                                 "",           ""};
    const fs::path dir = caseDir("recv-undeclared");
    const auto uids = fvr::test::writeCharsetStudy(undeclared, slicer(), dir, 1);
    LocalStore store(caseDir("store-undeclared"));
    DcmFileFormat file;
    ASSERT_TRUE(file.loadFile((dir / "cs_0.dcm").c_str()).good());
    const auto stored = detail::storeDataset(store, *file.getDataset());
    EXPECT_EQ(store.find(uids.studyUid)->study.patientName, undeclared.utf8);
    const auto problems = store.takeTextProblems();
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_NE(problems[0].find("SOP instance " + stored.sopInstanceUid), std::string::npos)
        << problems[0];
    EXPECT_NE(problems[0].find("PatientName (0010,0010)"), std::string::npos) << problems[0];
    EXPECT_NE(problems[0].find("U+FFFD"), std::string::npos) << problems[0];
    EXPECT_TRUE(store.takeTextProblems().empty()); // said once
}
