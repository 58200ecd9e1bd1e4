// The cine's exports without the workstation: the MP4 writer (decoded back with FFmpeg itself),
// the multi-frame Secondary Capture (read back with DCMTK, checked with dciodvfy) and the DICOM
// tag rows of the tag browser (against DCMTK's own lookup of the same file).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <fvr/core/dicom/multiframe_export.h>
#include <fvr/core/errors.h>
#include <fvr/core/io/movie_writer.h>

#include "support/movie_decode.h"
#include "test_support.h"

using namespace fvr::core;
namespace fs = std::filesystem;

namespace {

/** Frame k of a test movie: a gradient with a bright disc moving along x. */
std::vector<std::uint8_t> testFrame(int W, int H, int k) {
    std::vector<std::uint8_t> f(std::size_t(W) * H);
    const double cx = 8 + 4.0 * k, cy = H / 2.0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const bool disc = (x - cx) * (x - cx) + (y - cy) * (y - cy) < 36.0;
            f[std::size_t(y) * W + x] = std::uint8_t(disc ? 240 : 20 + 2 * x + y);
        }
    return f;
}

std::vector<ProjectionImage> testFrames(int n, int W, int H) {
    std::vector<ProjectionImage> frames(n);
    for (int k = 0; k < n; ++k) {
        ProjectionImage& p = frames[k];
        p.width = W;
        p.height = H;
        p.pixelSize = 0.5;
        p.view = ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1});
        p.pixels.resize(std::size_t(W) * H);
        for (int i = 0; i < W * H; ++i)
            p.pixels[i] = float(-3.0 + 0.01 * i + 5.0 * std::sin(0.3 * k + 0.02 * i));
    }
    return frames;
}

std::string tag(DcmDataset* ds, const DcmTagKey& key) {
    OFString v;
    ds->findAndGetOFStringArray(key, v);
    return v.c_str();
}

} // namespace

TEST(MovieWriter, DecodesToTheFramesSizeAndRate) {
    const int W = 64, H = 48, n = 12;
    const fs::path path = fvr::test::tmpDir() / "cine_test.mp4";
    fs::remove(path);
    MovieWriter movie(path, W, H, 10.0);
    for (int k = 0; k < n; ++k) movie.addFrame(testFrame(W, H, k).data());
    movie.finish();
    const auto d = fvr::test::decodeMovie(path.string());
    ASSERT_EQ(d.error, "");
    EXPECT_EQ(d.codec, "h264");
    EXPECT_EQ(d.width, W);
    EXPECT_EQ(d.height, H);
    EXPECT_NEAR(d.fps, 10.0, 1e-6);
    ASSERT_EQ(int(d.frames.size()), n);
    for (int k = 0; k < n; ++k) {
        // Each decoded frame is its own source frame, not a neighbour (the disc moves).
        const double same = fvr::test::correlation(d.frames[k], testFrame(W, H, k));
        EXPECT_GT(same, 0.99) << "frame " << k;
        if (k > 0) {
            EXPECT_GT(same, fvr::test::correlation(d.frames[k], testFrame(W, H, k - 1)));
        }
    }
}

TEST(MovieWriter, OddSizesArePaddedByOne) {
    const fs::path path = fvr::test::tmpDir() / "cine_odd.mp4";
    MovieWriter movie(path, 33, 31, 5.0);
    for (int k = 0; k < 3; ++k) movie.addFrame(testFrame(33, 31, k).data());
    movie.finish();
    const auto d = fvr::test::decodeMovie(path.string());
    EXPECT_EQ(d.width, 34);
    EXPECT_EQ(d.height, 32);
    EXPECT_EQ(d.frames.size(), 3u);
}

TEST(MovieWriter, BadInputNamesTheFileAndLeavesNothing) {
    const fs::path path = fvr::test::tmpDir() / "cine_bad.mp4";
    fs::remove(path);
    try {
        MovieWriter(path, 64, 64, 0.0);
        FAIL() << "a zero frame rate was accepted";
    } catch (const WriteError& e) {
        EXPECT_NE(std::string(e.what()).find("cine_bad.mp4"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("frame rate"), std::string::npos) << e.what();
    }
    EXPECT_THROW(MovieWriter("/nonexistent-folder/x.mp4", 64, 64, 10.0), WriteError);
    {
        MovieWriter cancelled(path, 16, 16, 10.0);
        cancelled.addFrame(testFrame(16, 16, 0).data());
    } // no finish(): cancelled
    EXPECT_FALSE(fs::exists(path));
    const auto parent = path.parent_path();
    for (const auto& e : fs::directory_iterator(parent))
        EXPECT_EQ(e.path().filename().string().find(".cine_bad.mp4"), std::string::npos)
            << "temporary left: " << e.path();
}

TEST(MultiframeDicom, ReadsBackFramesFrameTimeAndValues) {
    const int W = 20, H = 16, n = 5;
    const auto frames = testFrames(n, W, H);
    DicomExportInfo info;
    info.patientName = "Doe^Jane";
    info.patientId = "ID42";
    info.studyDate = "20240102";
    info.study.studyId = "S7";
    info.study.patientSex = "F";
    info.window = DisplayWindowValues{1.0, 4.0, false};
    const fs::path path = fvr::test::tmpDir() / "cine_mf.dcm";
    writeDicomMultiframe(path, frames, {40.0, 72.0, "patient S-I"}, info);
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile(path.c_str()).good());
    DcmDataset* ds = ff.getDataset();
    EXPECT_EQ(tag(ds, DCM_SOPClassUID), UID_MultiframeGrayscaleWordSecondaryCaptureImageStorage);
    EXPECT_EQ(tag(ds, DCM_NumberOfFrames), "5");
    EXPECT_EQ(tag(ds, DCM_FrameTime), "40");
    EXPECT_EQ(tag(ds, DCM_FrameIncrementPointer), "(0018,1063)"); // FrameTime
    EXPECT_EQ(tag(ds, DCM_PatientName), "Doe^Jane");
    EXPECT_EQ(tag(ds, DCM_StudyDate), "20240102");
    EXPECT_EQ(tag(ds, DCM_StudyID), "S7");
    EXPECT_EQ(tag(ds, DCM_PatientSex), "F");
    EXPECT_EQ(tag(ds, DCM_WindowCenter), "1");
    EXPECT_EQ(tag(ds, DCM_WindowWidth), "4");
    // The stored values map back to the frames' values through the one rescale.
    double slope = 0, intercept = 0;
    ds->findAndGetFloat64(DCM_RescaleSlope, slope);
    ds->findAndGetFloat64(DCM_RescaleIntercept, intercept);
    const Uint16* px = nullptr;
    unsigned long count = 0;
    ASSERT_TRUE(ds->findAndGetUint16Array(DCM_PixelData, px, &count).good());
    ASSERT_EQ(count, std::size_t(W) * H * n);
    for (int k = 0; k < n; ++k)
        for (int i = 0; i < W * H; ++i)
            ASSERT_NEAR(intercept + slope * px[k * W * H + i], frames[k].pixels[i], slope)
                << "frame " << k << " pixel " << i;
}

TEST(MultiframeDicom, PassesDciodvfyWithoutErrors) {
    if (fvr::test::runCommand("command -v dciodvfy").status != 0)
        GTEST_SKIP() << "dciodvfy (Debian package dicom3tools) is not installed";
    const fs::path path = fvr::test::tmpDir() / "cine_mf_vfy.dcm";
    for (bool inverted : {false, true}) {
        DicomExportInfo info;
        info.window = DisplayWindowValues{0.0, 2.0, inverted};
        writeDicomMultiframe(path, testFrames(3, 16, 16), {66.7, 5.0, "patient S-I"}, info);
        const auto r = fvr::test::runCommand("dciodvfy -new '" + path.string() + "' 2>&1");
        std::istringstream in(r.out);
        for (std::string line; std::getline(in, line);) {
            EXPECT_NE(line.rfind("Error", 0), 0u) << "inverted " << inverted << ": " << line;
            if (line.rfind("Warning", 0) == 0) std::cout << "dciodvfy: " << line << "\n";
        }
    }
}

TEST(MultiframeDicom, MixedFrameSizesNameTheFrame) {
    auto frames = testFrames(3, 8, 8);
    frames[2] = testFrames(1, 6, 8)[0];
    try {
        writeDicomMultiframe(fvr::test::tmpDir() / "cine_mixed.dcm", frames, {});
        FAIL() << "mixed sizes were written";
    } catch (const WriteError& e) {
        EXPECT_NE(std::string(e.what()).find("frame 3 is 6 x 8"), std::string::npos) << e.what();
    }
}

TEST(DicomTags, ListsTheRealCtsHeaderAsDcmtkReadsIt) {
    const char* rel = "dicom/ct_phantom_philips_512x512x140/I10";
    FVR_REQUIRE_DATA(rel);
    const fs::path file = fvr::test::sharedData() / rel;
    const auto rows = readDicomTags(file);
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile(file.c_str()).good());
    const std::string name = tag(ff.getDataset(), DCM_PatientName);
    ASSERT_FALSE(name.empty());
    bool found = false, meta = false;
    for (const auto& r : rows) {
        if (r.keyword == "PatientName") {
            found = true;
            EXPECT_EQ(r.tag, "(0010,0010)");
            EXPECT_EQ(r.vr, "PN");
            EXPECT_EQ(r.value, name);
        }
        meta |= r.keyword == "TransferSyntaxUID";
        if (r.keyword == "PixelData") {
            EXPECT_EQ(r.value.front(), '<') << r.value;
        }
    }
    EXPECT_TRUE(found);
    EXPECT_TRUE(meta);
}

TEST(DicomTags, NotDicomNamesTheFile) {
    const fs::path f = fvr::test::tmpDir() / "not_dicom.txt";
    std::ofstream(f) << "hello";
    try {
        readDicomTags(f);
        FAIL();
    } catch (const LoadError& e) {
        EXPECT_NE(std::string(e.what()).find("not_dicom.txt"), std::string::npos) << e.what();
    }
}

TEST(DicomTags, ValuesAreUtf8FromTheFilesCharacterSet) {
    // The oracle: the name's Latin-1 bytes written by hand, read back as UTF-8.
    const fs::path f = fvr::test::tmpDir() / "latin1_tags.dcm";
    DcmFileFormat ff;
    DcmDataset* ds = ff.getDataset();
    ds->putAndInsertString(DCM_SOPClassUID, UID_SecondaryCaptureImageStorage);
    ds->putAndInsertString(DCM_SOPInstanceUID, "1.2.3.4");
    ds->putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 100");
    ds->putAndInsertString(DCM_PatientName, "M\xFCller^J\xF6rg");
    ASSERT_TRUE(ff.saveFile(f.c_str(), EXS_LittleEndianExplicit).good());
    for (const auto& r : readDicomTags(f))
        if (r.keyword == "PatientName") {
            EXPECT_EQ(r.value, "M\xC3\xBCller^J\xC3\xB6rg");
            return;
        }
    FAIL() << "no PatientName row";
}
