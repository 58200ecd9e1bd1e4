#pragma once
/** DICOM studies through DCMTK: scan a folder into series, load one series into a Volume with
 *  its patient geometry (LPS), Hounsfield units and every geometry problem reported. */
#include <filesystem>
#include <string>
#include <vector>

#include <fvr/core/errors.h>
#include <fvr/core/preprocess.h> // ProgressFn, CancelToken
#include <fvr/core/volume.h>

namespace fvr::core {

/** A DICOM file or series could not be read or is not usable as a volume. */
struct DicomError : LoadError {
    using LoadError::LoadError;
};

/** One series as found by a scan (a SeriesInstanceUID, split further where the image size,
 *  orientation or acquisition differs). */
struct DicomSeriesInfo {
    std::string key;            ///< unique within the scan: the SeriesInstanceUID, or UID#n when split
    std::string seriesUid;
    std::string studyUid;
    std::string patientName, patientId, studyDate, modality, description;
    std::string transferSyntax; ///< name of the (first file's) transfer syntax
    int imageCount = 0;         ///< files (a multi-frame file counts once)
    int frameCount = 0;         ///< slices in total
    Dims3 dims{0, 0, 0};        ///< columns, rows, slices (as it would load)
    Vec3 spacing{0, 0, 0};      ///< mm; slice spacing estimated from positions
    std::vector<std::filesystem::path> files;
    std::vector<std::string> warnings; ///< problems visible at scan time
};

struct DicomScanResult {
    std::vector<DicomSeriesInfo> series;
    std::vector<std::string> skipped; ///< "file: reason" for files that are not usable images
};

/** Recursive scan (reads DICOMDIR when present, else every file), in parallel; progress and
 *  cancellation as for preprocessing. Non-DICOM and broken files are listed in `skipped`.
 *  Throws DicomError when the folder does not exist or holds no image series. */
DicomScanResult scanDicomFolder(const std::filesystem::path& folder, const ProgressFn& progress = {},
                                const CancelToken* cancel = nullptr);

struct DicomVolume {
    Volume volume;                     ///< units HU for CT with rescale, origin/direction in LPS
    std::vector<std::string> warnings; ///< uneven spacing, gantry tilt, resampling, ...
};

/** Loads a scanned series: slices sorted by ImagePositionPatient along the slice normal,
 *  spacing from positions, direction from ImageOrientationPatient, rescale to real values,
 *  MONOCHROME1 inverted, multi-frame and enhanced multi-frame supported, compressed transfer
 *  syntaxes decoded (JPEG, JPEG-LS, RLE, deflate). Decodes on all cores. Throws DicomError with
 *  the file and the problem; refuses what cannot be loaded without distorting the geometry. */
DicomVolume loadDicomSeries(const DicomSeriesInfo& series, const ProgressFn& progress = {},
                            const CancelToken* cancel = nullptr);

/** Convenience: scan `folder` and load the series whose key or SeriesInstanceUID is `key`
 *  (empty: the only series, or the one with most slices when there are several). */
DicomVolume loadDicomFolder(const std::filesystem::path& folder, const std::string& key = {});

/** Loads one file (single image or multi-frame) as a volume; throws DicomError. Used by the
 *  fuzz target and for single-file input. */
DicomVolume loadDicomFile(const std::filesystem::path& file);

} // namespace fvr::core
