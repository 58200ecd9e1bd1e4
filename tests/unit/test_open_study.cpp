// The one rule for opening a path (io/open_study.h): what a path names, the default series, the
// Hounsfield-units guess, and openStudy following it on real data.
#include <filesystem>
#include <fstream>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/io/open_study.h>

#include "test_support.h"

namespace {
namespace fs = std::filesystem;
using namespace fvr::core;
using fvr::test::sharedData;
using fvr::test::tmpDir;

fs::path touch(const fs::path& p, const std::string& bytes = "x") {
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
}

DicomSeriesInfo series(const std::string& key, int slices, const std::string& why = {}) {
    DicomSeriesInfo s;
    s.key = key;
    s.seriesUid = key.substr(0, key.find('#'));
    s.frameCount = slices;
    s.unloadableReason = why;
    return s;
}

TEST(OpenStudy, ClassifiesPathsByTheRule) {
    const fs::path dir = tmpDir() / "open_rule";
    fs::remove_all(dir);
    touch(dir / "series" / "a.dcm");
    EXPECT_EQ(classifyInput((dir / "series").string()).kind, InputKind::DicomFolder);
    const InputSource dicomdir = classifyInput(touch(dir / "cd" / "DICOMDIR").string());
    EXPECT_EQ(dicomdir.kind, InputKind::DicomFolder);
    EXPECT_EQ(dicomdir.path, dir / "cd");
    EXPECT_EQ(classifyInput(touch(dir / "v.mhd").string()).kind, InputKind::VolumeFile);
    EXPECT_EQ(classifyInput(touch(dir / "v.MHA").string()).kind, InputKind::VolumeFile);
    EXPECT_EQ(classifyInput(touch(dir / "v.nii.gz").string()).kind, InputKind::VolumeFile);
    EXPECT_EQ(classifyInput(touch(dir / "v.nii").string()).kind, InputKind::VolumeFile);
    EXPECT_EQ(classifyInput((dir / "series" / "a.dcm").string()).kind, InputKind::DicomFile);
    EXPECT_EQ(classifyInput(touch(dir / "IM0001").string()).kind, InputKind::DicomFile);
    EXPECT_EQ(classifyInput(touch(dir / "scan.IMA", std::string(128, '\0') + "DICM").string()).kind,
              InputKind::DicomFile);
    // Other names are volume files: loadVolume names the formats it reads.
    const InputSource nrrd = classifyInput(touch(dir / "v.nrrd").string());
    EXPECT_EQ(nrrd.kind, InputKind::VolumeFile);
    try {
        openStudy(nrrd);
        ADD_FAILURE() << "a .nrrd file must not open";
    } catch (const LoadError& e) {
        EXPECT_NE(std::string(e.what()).find("unknown volume format"), std::string::npos)
            << e.what();
    }
    // A DICOM file named like a volume file is still DICOM (its preamble decides).
    EXPECT_EQ(classifyInput(touch(dir / "odd.nii", std::string(128, '\0') + "DICM").string()).kind,
              InputKind::DicomFile);
    try {
        classifyInput((dir / "missing.nii").string());
        ADD_FAILURE() << "a missing path must throw";
    } catch (const LoadError& e) {
        EXPECT_NE(std::string(e.what()).find("missing.nii: no such file or folder"),
                  std::string::npos);
    }
}

TEST(OpenStudy, ParsesThePhantomSpec) {
    EXPECT_EQ(classifyInput("phantom:shepp-logan").kind, InputKind::Phantom);
    EXPECT_EQ(classifyInput("phantom:shepp-logan").phantomSize, 128);
    EXPECT_EQ(classifyInput("phantom:shepp-logan:64").phantomSize, 64);
    EXPECT_THROW(classifyInput("phantom:cube"), SettingsError);
    EXPECT_THROW(classifyInput("phantom:shepp-logan:64x"), SettingsError);
    EXPECT_THROW(openStudy(classifyInput("phantom:shepp-logan:4")), SettingsError); // 8..1024
}

TEST(OpenStudy, DefaultSeriesPrefersLoadableThenMostSlices) {
    DicomScanResult scan;
    scan.series = {series("a", 30), series("b", 200, "colour images"), series("c", 40),
                   series("d", 40)};
    EXPECT_EQ(defaultSeriesIndex(scan), 2u); // b has most slices but cannot load; c before d
    scan.series = {series("a", 3, "mixed image sizes"), series("b", 5, "colour images")};
    EXPECT_EQ(defaultSeriesIndex(scan), 1u); // nothing loadable: most slices
    EXPECT_THROW(defaultSeriesIndex(DicomScanResult{}), DicomError);
}

TEST(OpenStudy, FindsSeriesByKeyThenByUid) {
    DicomScanResult scan;
    scan.series = {series("1.2", 10), series("1.3#1", 6), series("1.3#2", 6)};
    std::string note;
    EXPECT_EQ(findSeries(scan, "1.3#2", "f", &note).key, "1.3#2");
    EXPECT_TRUE(note.empty());
    EXPECT_EQ(findSeries(scan, "1.3", "f", &note).key, "1.3#1");
    EXPECT_EQ(note, "series 1.3 was split; loaded its first part 1.3#1");
    try {
        findSeries(scan, "9.9", "folder");
        ADD_FAILURE() << "an unknown key must throw";
    } catch (const DicomError& e) {
        EXPECT_EQ(std::string(e.what()), "folder: no series '9.9' (found: 1.2, 1.3#1, 1.3#2)");
    }
}

Volume ramp(float lo, float hi, ValueUnits units = ValueUnits::Unknown) {
    Volume v;
    v.dims = {4, 1, 1};
    v.voxels = {lo, 0.0f, 0.5f * hi, hi};
    v.units = units;
    return v;
}

TEST(OpenStudy, GuessesHounsfieldUnitsFromTheRange) {
    Volume ct = ramp(-1024.0f, 1500.0f);
    const auto w = guessHounsfieldUnits(ct);
    EXPECT_EQ(ct.units, ValueUnits::HounsfieldUnits);
    ASSERT_TRUE(w.has_value());
    EXPECT_NE(w->find("look like Hounsfield units"), std::string::npos) << *w;
    Volume padded = ramp(-3024.0f, 3000.0f); // scanners that pad outside the field of view
    EXPECT_TRUE(guessHounsfieldUnits(padded).has_value());
    Volume mr = ramp(0.0f, 900.0f), uint8 = ramp(0.0f, 255.0f), deep = ramp(-4000.0f, 500.0f);
    Volume soft = ramp(-1000.0f, 150.0f); // no tissue or bone above 200
    for (Volume* v : {&mr, &uint8, &deep, &soft}) {
        EXPECT_FALSE(guessHounsfieldUnits(*v).has_value());
        EXPECT_EQ(v->units, ValueUnits::Unknown);
    }
    Volume stated = ramp(-1000.0f, 2000.0f, ValueUnits::Intensity);
    EXPECT_FALSE(guessHounsfieldUnits(stated).has_value());
    EXPECT_EQ(stated.units, ValueUnits::Intensity);
}

TEST(OpenStudy, VolumeFileWithoutUnitsOpensAsHounsfield) {
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.nii.gz");
    for (const char* name : {"example_ct.nii.gz", "example_ct.mhd"}) {
        const auto path = sharedData() / "volumes/body_ct_hu_3mm" / name;
        const OpenedStudy s = openStudy(classifyInput(path.string()));
        EXPECT_EQ(s.volume.dims, (Dims3{122, 101, 112})) << name;
        EXPECT_EQ(s.volume.units, ValueUnits::HounsfieldUnits) << name;
        EXPECT_FALSE(s.series.has_value());
        // The NIfTI file has an sform; the MetaImage header no TransformMatrix: assumed, said so.
        const bool stated = std::string(name) == "example_ct.nii.gz";
        EXPECT_EQ(s.volume.orientationStated, stated) << name;
        int said = 0;
        for (const auto& w : s.warnings)
            said += w.find("states no orientation") != std::string::npos;
        EXPECT_EQ(said, stated ? 0 : 1) << name;
    }
    FVR_REQUIRE_DATA("volumes/bonsai_256");
    for (const auto& e : fs::directory_iterator(sharedData() / "volumes/bonsai_256")) {
        const OpenedStudy s = openStudy(classifyInput(e.path().string()));
        EXPECT_EQ(s.volume.units, ValueUnits::Unknown) << "uint8 data is not CT: " << e.path();
    }
}

TEST(OpenStudy, SingleDicomFileAndFolderOpen) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93/CTHead1.dcm");
    const auto dir = sharedData() / "dicom/ct_head_slicer_64x64x93";
    const OpenedStudy one = openStudy(classifyInput((dir / "CTHead1.dcm").string()));
    EXPECT_EQ(one.volume.dims, (Dims3{64, 64, 1}));
    // RescaleType 'US': stated units (intensity), so no Hounsfield guess despite the range.
    EXPECT_EQ(one.volume.units, ValueUnits::Intensity);
    const OpenedStudy all = openStudy(classifyInput(dir.string()));
    EXPECT_EQ(all.volume.dims, (Dims3{64, 64, 93}));
    EXPECT_EQ(all.volume.units, ValueUnits::Intensity);
    ASSERT_TRUE(all.series.has_value());
    EXPECT_EQ(all.series->frameCount, 93);
}

TEST(OpenStudy, MultiSeriesFolderOpensTheDefaultSeries) {
    FVR_REQUIRE_DATA("dicom_edge/enhanced_multiframe_mr");
    const auto dir = sharedData() / "dicom_edge/enhanced_multiframe_mr";
    const DicomScanResult scan = scanDicomFolder(dir);
    ASSERT_EQ(scan.series.size(), 6u);
    const std::size_t d = defaultSeriesIndex(scan);
    EXPECT_EQ(scan.series[d].frameCount, 32); // the Philips series; Siemens ones have 6 slices
    int moreOrEqual = 0;
    for (const auto& s : scan.series) moreOrEqual += s.loadable() && s.frameCount >= 32;
    EXPECT_EQ(moreOrEqual, 2); // two Philips parts of 32: the first in scan order wins
    for (std::size_t i = 0; i < d; ++i) EXPECT_LT(scan.series[i].frameCount, 32);
    const OpenedStudy s = openStudy(classifyInput(dir.string()));
    ASSERT_TRUE(s.series.has_value());
    EXPECT_EQ(s.series->key, scan.series[d].key);
}

TEST(OpenStudy, TextFilesGetMessagesAUserCanActOn) {
    const fs::path dir = tmpDir() / "open_text";
    fs::remove_all(dir);
    const std::string text = "This folder holds a CT head.\nSee the notes.\n";
    // Named like DICOM or NIfTI, the text is refused with the file and what is wrong with it.
    const auto errorOf = [&](const std::string& name) {
        touch(dir / name, text);
        try {
            openStudy(classifyInput((dir / name).string()));
        } catch (const LoadError& e) {
            return std::string(e.what());
        }
        return std::string("(opened)");
    };
    std::string m = errorOf("readme.dcm");
    EXPECT_NE(m.find((dir / "readme.dcm").string() + ": not a DICOM file (no DICM preamble"),
              std::string::npos)
        << m;
    m = errorOf("notes.nii.gz");
    EXPECT_NE(m.find((dir / "notes.nii.gz").string() + ": not gzip-compressed data"),
              std::string::npos)
        << m;
    m = errorOf("notes.nii");
    EXPECT_NE(m.find((dir / "notes.nii").string() + ": not a NIfTI file"), std::string::npos) << m;
    // Beside the slices of a series, text files are skipped and said once in the warnings.
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93/CTHead1.dcm");
    const fs::path series = dir / "series";
    for (const char* f : {"CTHead1.dcm", "CTHead2.dcm"}) {
        fs::create_directories(series);
        fs::copy_file(sharedData() / "dicom/ct_head_slicer_64x64x93" / f, series / f);
    }
    touch(series / "README.txt", text);
    const OpenedStudy s = openStudy(classifyInput(series.string()));
    EXPECT_EQ(s.volume.dims, (Dims3{64, 64, 2}));
    int mentions = 0;
    for (const auto& w : s.warnings)
        mentions += w.find("skipped 1 file that is not DICOM: README.txt") != std::string::npos;
    EXPECT_EQ(mentions, 1);
}

} // namespace

// Voxels that are not finite (a NaN-masked NIfTI, a broken file) are said and replaced by the
// lowest finite value: one NaN voxel used to spread through the 3D transform into about a third
// of every projection.
TEST(OpenStudy, NonFiniteVoxelsAreSaidAndReplaced) {
    const fs::path dir = tmpDir() / "nonfinite";
    fs::create_directories(dir);
    std::vector<float> voxels(8 * 8 * 8, 100.0f);
    voxels[3] = -50.0f;
    voxels[100] = std::numeric_limits<float>::quiet_NaN();
    voxels[200] = std::numeric_limits<float>::infinity();
    std::ofstream(dir / "v.raw", std::ios::binary)
        .write(reinterpret_cast<const char*>(voxels.data()), std::streamsize(voxels.size() * 4));
    std::ofstream(dir / "v.mhd") << "ObjectType = Image\nNDims = 3\nDimSize = 8 8 8\n"
                                    "ElementType = MET_FLOAT\nElementSpacing = 1 1 1\n"
                                    "ElementDataFile = v.raw\n";
    const OpenedStudy s = openStudy(classifyInput((dir / "v.mhd").string()));
    bool said = false;
    for (const auto& w : s.warnings) said |= w.find("2 of 512 voxels are not finite") == 0;
    EXPECT_TRUE(said);
    EXPECT_EQ(s.volume.voxels[100], -50.0f); // the lowest finite value
    EXPECT_EQ(s.volume.voxels[200], -50.0f);
    EXPECT_EQ(s.volume.voxels[0], 100.0f); // the others untouched
    Volume allNan;
    allNan.dims = {2, 2, 2};
    allNan.voxels.assign(8, std::numeric_limits<float>::quiet_NaN());
    EXPECT_TRUE(replaceNonFiniteVoxels(allNan));
    EXPECT_EQ(allNan.voxels[7], 0.0f);
    Volume fine;
    fine.dims = {1, 1, 2};
    fine.voxels = {1.0f, 2.0f};
    EXPECT_FALSE(replaceNonFiniteVoxels(fine));
}
