// Shared by the PACS tests that need no PACS (test_pacs_peers.cpp, test_pacs_local.cpp,
// test_pacs_local_writers.cpp): the PacsError message of a call, and synthetic and real DICOM
// instances to store.
#pragma once

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>

#include "pacs/pacs_internal.h" // detail::storeDataset: what the listener and C-GET call
#include "test_support.h"

namespace fvr::test::pacs_local {

namespace fs = std::filesystem;
using namespace fvr::core::pacs;

/** The PacsError message that `f` throws, or empty when it throws none. */
inline std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const PacsError& e) {
        return e.what();
    }
    return "";
}

inline StudyRecord study(const std::string& uid) {
    StudyRecord s;
    s.studyUid = uid;
    s.patientName = "DOE^JANE";
    return s;
}

inline std::string readBytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/** A small CT instance (4 x 4 pixels of `fill`) with the given UIDs. */
inline std::unique_ptr<DcmDataset> makeDataset(const std::string& studyUid,
                                               const std::string& seriesUid,
                                               const std::string& sopUid, Uint16 fill = 100) {
    auto ds = std::make_unique<DcmDataset>();
    ds->putAndInsertString(DCM_SOPClassUID, UID_CTImageStorage);
    ds->putAndInsertString(DCM_SOPInstanceUID, sopUid.c_str());
    ds->putAndInsertString(DCM_StudyInstanceUID, studyUid.c_str());
    ds->putAndInsertString(DCM_SeriesInstanceUID, seriesUid.c_str());
    ds->putAndInsertString(DCM_PatientName, "DOE^JANE");
    ds->putAndInsertString(DCM_Modality, "CT");
    ds->putAndInsertUint16(DCM_Rows, 4);
    ds->putAndInsertUint16(DCM_Columns, 4);
    ds->putAndInsertUint16(DCM_BitsAllocated, 16);
    ds->putAndInsertUint16(DCM_BitsStored, 16);
    ds->putAndInsertUint16(DCM_HighBit, 15);
    ds->putAndInsertUint16(DCM_PixelRepresentation, 0);
    ds->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    ds->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2");
    const std::vector<Uint16> pixels(16, fill);
    ds->putAndInsertUint16Array(DCM_PixelData, pixels.data(), pixels.size());
    return ds;
}

/** Every regular file under `root` (recursively), as paths relative to it. */
inline std::vector<std::string> filesUnder(const fs::path& root) {
    std::vector<std::string> files;
    for (const auto& f : fs::recursive_directory_iterator(root))
        if (f.is_regular_file()) files.push_back(fs::relative(f.path(), root).string());
    std::sort(files.begin(), files.end());
    return files;
}

/** An instance to store: its records and its bytes (a DICOM file). */
struct Source {
    StudyRecord study;
    SeriesRecord series;
    std::string sop, bytes;
};

/** `n` synthetic instances of one study in two series. */
inline std::vector<Source> syntheticStudy(const std::string& studyUid, int n) {
    std::vector<Source> out;
    const fs::path tmp = fvr::test::tmpDir() / ("synthetic-" + studyUid + ".dcm");
    for (int i = 0; i < n; ++i) {
        const std::string series = studyUid + "." + std::to_string(1 + i % 2);
        const std::string sop = series + "." + std::to_string(i + 1);
        const auto ds = makeDataset(studyUid, series, sop, Uint16(i));
        DcmFileFormat file(ds.get());
        EXPECT_TRUE(file.saveFile(tmp.c_str(), EXS_LittleEndianExplicit).good());
        out.push_back({study(studyUid), SeriesRecord{series, "CT", "", 0, 0}, sop, readBytes(tmp)});
    }
    fs::remove(tmp);
    return out;
}

/** The 93 slices of the shared head CT as they are on disk, or none without the shared data. */
inline std::vector<Source> headCt() {
    std::vector<Source> out;
    const fs::path dir = fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93";
    if (!fs::is_directory(dir)) return out;
    for (const auto& f : fs::directory_iterator(dir)) {
        DcmFileFormat file;
        if (file.loadFile(f.path().c_str()).bad()) continue;
        DcmDataset& ds = *file.getDataset();
        OFString sop;
        ds.findAndGetOFString(DCM_SOPInstanceUID, sop);
        out.push_back({detail::studyRecordFrom(ds), detail::seriesRecordFrom(ds), sop.c_str(),
                       readBytes(f.path())});
    }
    return out;
}

} // namespace fvr::test::pacs_local
