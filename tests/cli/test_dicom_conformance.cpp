// Every kind of DICOM object fvr-render writes, from a real CT study: the Secondary Capture of a
// parallel view (one, a sweep, Beer-Lambert), the X-Ray Angiographic image of a cone-beam view
// and the multi-frame XA of a run, and the RT Image of a treatment beam. Each passes dciodvfy
// (dicom3tools) with no error (its warnings are printed), keeps the source study's fields
// (compared with the source file itself), says its PatientOrientation and is a series of its own.
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include "charset_cases.h"
#include "cli_support.h"
#include "dicom_tag.h"
#include "test_support.h"

namespace {

using fvr::test::dicomTag;

namespace fs = std::filesystem;

const char* kStudy = "dicom/ct_phantom_philips_512x512x140";

std::string tmp(const std::string& name) {
    return (fvr::test::tmpDir() / ("conformance_" + std::to_string(getpid()) + "_" + name))
        .string();
}

std::string source() { return (fvr::test::sharedData() / kStudy).string(); }

bool present(const std::string& path, const DcmTagKey& key) {
    DcmFileFormat ff;
    return ff.loadFile(path.c_str()).good() && ff.getDataset()->tagExists(key);
}

/** The lines of dciodvfy's output on `path` that start with `kind` ("Error", "Warning"). */
std::vector<std::string> dciodvfyLines(const std::string& path, const std::string& kind) {
    const auto r = fvr::test::runCommand("dciodvfy -new '" + path + "' 2>&1");
    std::vector<std::string> out;
    std::istringstream in(r.out);
    for (std::string line; std::getline(in, line);)
        if (line.rfind(kind, 0) == 0) out.push_back(line);
    return out;
}

/** One object of each kind fvr-render writes (file, what it is). */
std::vector<std::pair<std::string, std::string>> writeEachKind() {
    const std::string in = source() + " ";
    const std::vector<std::pair<std::string, std::string>> runs = {
        {"sc.dcm", "--size 48"},
        {"sweep.dcm", "--size 32 --sweep 3"},
        {"sc_film.dcm", "--size 48 --beer-lambert"},
        {"xa.dcm", "--geometry cone --detector-size 48x40 --primary-angle 30"},
        {"xa_run.dcm", "--geometry cone --detector-size 32x32 --sweep 3"},
        {"rt.dcm", "--geometry cone --beam 90,0,0 --detector-size 48x40 --pitch 2"},
    };
    std::vector<std::pair<std::string, std::string>> files;
    for (const auto& [name, args] : runs) {
        const auto r = fvr::test::runFvrRender(in + args + " --out " + tmp(name));
        EXPECT_EQ(r.status, 0) << args << ": " << r.output;
        if (name == "sweep.dcm")
            for (const char* n : {"sweep_0000.dcm", "sweep_0001.dcm", "sweep_0002.dcm"})
                files.emplace_back(tmp(n), args);
        else
            files.emplace_back(tmp(name), args);
    }
    return files;
}

TEST(DicomConformance, EveryKindWePassesDciodvfyWithoutErrors) {
    FVR_REQUIRE_DATA(kStudy);
    if (fvr::test::runCommand("command -v dciodvfy").status != 0)
        GTEST_SKIP() << "dciodvfy (Debian package dicom3tools) is not installed";
    for (const auto& [path, args] : writeEachKind()) {
        ASSERT_TRUE(fs::exists(path)) << args;
        const auto errors = dciodvfyLines(path, "Error");
        EXPECT_TRUE(errors.empty()) << args << ":\n" << ::testing::PrintToString(errors);
        // The warnings that remain, for the record (see the report: the source's own names,
        // an unknown Laterality, the private geometry tags, a run's zero angle increments).
        for (const std::string& w : dciodvfyLines(path, "Warning"))
            std::cout << fs::path(path).filename().string() << ": " << w << "\n";
    }
}

TEST(DicomConformance, EveryKindKeepsTheSourceStudysFields) {
    FVR_REQUIRE_DATA(kStudy);
    // The oracle: the source study's own first file.
    const std::string first = (fvr::test::sharedData() / kStudy / "I10").string();
    ASSERT_TRUE(fs::exists(first));
    const std::vector<DcmTagKey> keys = {DCM_StudyInstanceUID,
                                         DCM_StudyDate,
                                         DCM_StudyTime,
                                         DCM_StudyID,
                                         DCM_StudyDescription,
                                         DCM_AccessionNumber,
                                         DCM_PatientName,
                                         DCM_PatientID,
                                         DCM_PatientSex,
                                         DCM_PatientBirthDate,
                                         DCM_ReferringPhysicianName};
    ASSERT_NE(dicomTag(first, DCM_StudyTime), ""); // the data has them: the test compares values
    ASSERT_NE(dicomTag(first, DCM_StudyID), "");
    ASSERT_NE(dicomTag(first, DCM_PatientSex), "");
    for (const auto& [path, args] : writeEachKind()) {
        for (const DcmTagKey& k : keys) {
            EXPECT_EQ(dicomTag(path, k), dicomTag(first, k))
                << args << ": " << DcmTag(k).getTagName();
            EXPECT_TRUE(present(path, k)) << args << ": " << DcmTag(k).getTagName();
        }
        EXPECT_TRUE(present(path, DCM_PatientOrientation)) << args;
        EXPECT_NE(dicomTag(path, DCM_PatientOrientation), "") << args;
    }
    // A Secondary Capture keeps the maker of the images it shows; this program made the capture.
    EXPECT_EQ(dicomTag(tmp("sc.dcm"), DCM_Manufacturer), dicomTag(first, DCM_Manufacturer));
    EXPECT_EQ(dicomTag(tmp("sc.dcm"), DCM_SecondaryCaptureDeviceManufacturer), "FVR Workstation");
}

TEST(DicomConformance, AnApViewSaysLeftAndFeet) {
    FVR_REQUIRE_DATA(kStudy);
    // The default view is AP: the patient's left on the image's right (rows run towards L),
    // the feet at the bottom (columns run towards F). LEFT looks from the patient's left side,
    // head up: the face is on the image's left, so the rows run towards posterior (P).
    const std::string ap = tmp("ap.dcm"), left = tmp("left.dcm");
    ASSERT_EQ(fvr::test::runFvrRender(source() + " --size 32 --out " + ap).status, 0);
    const auto r = fvr::test::runFvrRender(source() + " --size 32 --view LEFT --out " + left);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(dicomTag(ap, DCM_PatientOrientation), "L\\F");
    EXPECT_EQ(dicomTag(left, DCM_PatientOrientation), "P\\F");
}

TEST(DicomConformance, EachExportIsANewSeriesAndASweepNumbersItsInstances) {
    FVR_REQUIRE_DATA(kStudy);
    const std::string a = tmp("series_a.dcm"), b = tmp("series_b.dcm");
    ASSERT_EQ(fvr::test::runFvrRender(source() + " --size 32 --out " + a).status, 0);
    ASSERT_EQ(fvr::test::runFvrRender(source() + " --size 32 --out " + b).status, 0);
    EXPECT_NE(dicomTag(a, DCM_SeriesInstanceUID), dicomTag(b, DCM_SeriesInstanceUID));
    EXPECT_NE(dicomTag(a, DCM_SeriesNumber), dicomTag(b, DCM_SeriesNumber));
    EXPECT_EQ(dicomTag(a, DCM_InstanceNumber), "1");
    const std::string s = tmp("numbered.dcm");
    ASSERT_EQ(fvr::test::runFvrRender(source() + " --size 32 --sweep 3 --out " + s).status, 0);
    const std::string uid = dicomTag(tmp("numbered_0000.dcm"), DCM_SeriesInstanceUID);
    for (int i = 0; i < 3; ++i) {
        const std::string f = tmp("numbered_000" + std::to_string(i) + ".dcm");
        EXPECT_EQ(dicomTag(f, DCM_SeriesInstanceUID), uid) << f;
        EXPECT_EQ(dicomTag(f, DCM_InstanceNumber), std::to_string(i + 1)) << f;
    }
}

TEST(DicomConformance, SourcesInEachCharacterSetGiveUtf8) {
    // Latin-1, UTF-8, ISO 2022 Japanese and Greek names: fvr-render --info says them in UTF-8, and
    // the export declares ISO_IR 192, holds the UTF-8 bytes and passes dciodvfy.
    const fs::path slicer = fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93";
    if (!fs::exists(slicer)) GTEST_SKIP() << "shared data not found: " << slicer;
    const bool dciodvfy = fvr::test::runCommand("command -v dciodvfy").status == 0;
    for (const fvr::test::CharsetCase& c : fvr::test::charsetCases()) {
        const std::string in = tmp("charset_" + c.label);
        fs::remove_all(in);
        fvr::test::writeCharsetStudy(c, slicer, in, 4);
        const auto info = fvr::test::runFvrRender(in + " --info");
        ASSERT_EQ(info.status, 0) << c.label << ": " << info.output;
        EXPECT_NE(info.output.find("\"patient_name\": \"" + c.utf8 + "\""), std::string::npos)
            << c.label << ": " << info.output;
        const std::string out = tmp("charset_" + c.label + ".dcm");
        const auto r = fvr::test::runFvrRender(in + " --size 32 --out " + out);
        ASSERT_EQ(r.status, 0) << c.label << ": " << r.output;
        EXPECT_EQ(dicomTag(out, DCM_SpecificCharacterSet), "ISO_IR 192") << c.label;
        EXPECT_EQ(dicomTag(out, DCM_PatientName), c.utf8) << c.label;
        if (!c.description.empty())
            EXPECT_EQ(dicomTag(out, DCM_StudyDescription), c.descriptionUtf8) << c.label;
        if (dciodvfy) {
            const auto errors = dciodvfyLines(out, "Error");
            EXPECT_TRUE(errors.empty()) << c.label << ":\n" << ::testing::PrintToString(errors);
        }
    }
}

} // namespace
