#pragma once
/** DICOM studies through DCMTK: scan a folder into series, load one series into a Volume with
 *  its patient geometry (LPS), Hounsfield units and every geometry problem reported.
 *
 *  Supported: Explicit/Implicit VR Little Endian, Explicit VR Big Endian, Deflated, RLE, JPEG
 *  (baseline, extended, lossless incl. frames split over several fragments), JPEG-LS (lossless
 *  and near-lossless), JPEG 2000 (lossless and lossy; OpenJPEG, strict: truncated codestreams
 *  are refused; the header's PixelRepresentation decides the sign; irreversible codestreams are
 *  reported as lossy); single-frame series, classic multi-frame and enhanced multi-frame
 *  (shared and per-frame functional groups: PlanePosition, PlaneOrientation, PixelMeasures,
 *  PixelValueTransformation); monochrome, 8/16/32-bit integer (signed or not, any BitsStored and
 *  HighBit) and Float/Double Float Pixel Data. Refused with a DicomError naming the file and the
 *  reason: transfer syntaxes without a decoder (JPEG 2000 multi-component, JPEG XL, HTJ2K),
 *  colour (SamplesPerPixel > 1, PALETTE COLOR), BitsAllocated 1 (segmentations), headers the
 *  pixel data cannot hold (checked before anything is allocated; compressed data may claim at
 *  most 1024 times its size, or 256 MiB).
 *
 *  Values: raw words shifted down by HighBit + 1 - BitsStored, masked to BitsStored,
 *  sign-extended from the top stored bit when PixelRepresentation is 1, then rescaled with the
 *  frame's RescaleSlope/RescaleIntercept, or mapped through the Modality LUT Sequence when there
 *  is one (LUTData[stored - first mapped value], clamped to the table). Units: HounsfieldUnits
 *  for CT with a rescale whose RescaleType is absent or HU (an explicit 'US' on a CT is loaded as
 *  Intensity, with a warning), Intensity otherwise. MONOCHROME1: stored value v -> (min + max
 *  of the BitsStored range) - v before the rescale (with a Modality LUT: its output range is
 *  inverted), so that larger means brighter, with a warning; except Hounsfield units, which are
 *  physical and stay as they are (MONOCHROME1 only tells a viewer to show low values white),
 *  also with a warning. Pixel padding: stored values equal to PixelPaddingValue (or between it
 *  and PixelPaddingRangeLimit) hold no measurement (outside a CT's reconstruction circle, say);
 *  they become air (-1000) for Hounsfield units, else 0, so that they add nothing to a
 *  projection, with a warning that counts them.
 *
 *  Geometry (decided per case; a user never gets a silently distorted volume):
 *  - Order: slices sorted by ImagePositionPatient projected on the normal n = row x column
 *    cosines (ImageOrientationPatient), never by file name or InstanceNumber.
 *    direction[0] = row cosines (index x, along a row), direction[1] = column cosines,
 *    direction[2] = n; origin = the first slice's position (LPS). spacing x/y = PixelSpacing
 *    column/row spacing; z = (last - first) / (N - 1) along n (not SliceThickness).
 *  - Uneven gaps or missing slices (a gap differing from the median by more than 1 % or
 *    0.01 mm): resampled onto a regular grid along n at the median gap (adjusted so that the
 *    first and last slices fall on it) by linear interpolation between the two neighbouring
 *    slices; the warning lists the distinct gaps found and, where a gap is a multiple of the
 *    median, how many slices are missing where. A gap of more than 10 times the median (two
 *    stacks in one series) is refused, as is a grid of more than 16 times the input voxels.
 *  - Gantry tilt / sheared stack (slice positions drifting in plane by more than 5 % of a
 *    pixel): resampled onto an orthogonal grid (rows, columns, n) that covers every slice,
 *    bilinear in plane and linear along n; voxels that no slice covers get the series minimum;
 *    the warning gives the angle of the stack against n (and GantryDetectorTilt).
 *  - Duplicate positions (two slices within 0.01 mm along n): the scan splits the series by
 *    the acquisition attribute that separates them (AcquisitionNumber, temporal position,
 *    StackID, ImageType/FrameType, trigger time, b-value, rescale, a DimensionIndexValues
 *    entry, or the file); when none does, loading refuses with a message naming two of them.
 *  - Image size, pixel spacing, orientation (cosines differing by more than 1e-3) and echo
 *    always split a series at scan time; the loader refuses mixed sizes it is handed.
 *  - Missing ImagePositionPatient in a multi-file series: refused (no guessing from names).
 *    Frames of one multi-frame file without positions: stacked in file order at
 *    SpacingBetweenSlices/SliceThickness (or 1 mm), with a warning. Missing PixelSpacing or
 *    ImageOrientationPatient on a single image: 1 mm / identity, with a warning. */
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <fvr/core/errors.h>
#include <fvr/core/render/preprocess.h> // ProgressFn, CancelToken
#include <fvr/core/volume.h>

namespace fvr::core {

/** A DICOM file or series could not be read or is not usable as a volume. */
struct DicomError : LoadError {
    using LoadError::LoadError;
};

/** The study and patient attributes besides the UIDs, names and date that an export copies from
 *  its source so that it joins the study without contradicting it (empty when absent). */
struct DicomStudyFields {
    std::string studyTime, studyId, studyDescription, accessionNumber, referringPhysicianName;
    std::string patientSex, patientBirthDate;
    std::string manufacturer; ///< of the equipment that made the source images
};

/** One series as found by a scan (a SeriesInstanceUID, split further where the image size,
 *  orientation or acquisition differs). */
struct DicomSeriesInfo {
    std::string key; ///< unique within the scan: the SeriesInstanceUID, or UID#n when split
    std::string seriesUid;
    std::string studyUid;
    std::string patientName, patientId, studyDate, modality, description;
    std::string seriesNumber; ///< SeriesNumber as written (empty when absent)
    DicomStudyFields study;
    std::string transferSyntax; ///< name of the (first file's) transfer syntax
    int imageCount = 0; ///< files (a multi-frame file counts once)
    int frameCount = 0; ///< slices in total
    Dims3 dims{0, 0, 0}; ///< columns, rows, slices (as it would load)
    Vec3 spacing{0, 0, 0}; ///< mm, as it would load (slice spacing from positions)
    std::vector<std::filesystem::path>
        files; ///< sorted along the slice normal where positions allow
    /** Per file (parallel to `files`): the 0-based frames of that file that belong to this series,
     *  when a multi-frame file holds several volumes (e.g. two image types of an enhanced MR
     *  split apart); empty (or an empty entry): all frames of the file. */
    std::vector<std::vector<std::int32_t>> frames;
    std::vector<std::string> warnings; ///< problems visible at scan time
    /** Why loadDicomSeries would refuse this series (colour, mixed sizes, duplicate positions,
     *  ...); empty when it loads. */
    std::string unloadableReason;
    bool loadable() const { return unloadableReason.empty(); }
};

struct DicomScanResult {
    std::vector<DicomSeriesInfo> series;
    std::vector<std::string> skipped; ///< "file: reason" for files that are not usable images
    /** About the folder as a whole, each said once: how many files were skipped because they
     *  are not DICOM ("skipped 2 files that are not DICOM: README.txt, notes.txt") or are DICOM
     *  objects without an image (with their SOP class in words), the first three named.
     *  loadChosenSeries, and so openStudy, adds them to the loaded series' warnings. */
    std::vector<std::string> warnings;
};

/** Recursive scan (reads DICOMDIR when present, else every file), in parallel, headers only
 *  (pixel data stays on disk); progress and cancellation as for preprocessing. Non-DICOM and
 *  broken files are listed in `skipped`; series that cannot be loaded (e.g. colour) are
 *  listed with the reason in `unloadableReason`. `folder` may also be a single file. Throws
 *  DicomError when the folder does not exist or holds no image series. */
DicomScanResult scanDicomFolder(const std::filesystem::path& folder,
                                const ProgressFn& progress = {},
                                const CancelToken* cancel = nullptr);

struct DicomVolume {
    Volume volume; ///< units HU for CT with rescale, origin/direction in LPS
    std::vector<std::string> warnings; ///< uneven spacing, gantry tilt, resampling, ...
};

/** Loads a scanned series: slices sorted by ImagePositionPatient along the slice normal,
 *  spacing from positions, direction from ImageOrientationPatient, rescale to real values,
 *  MONOCHROME1 inverted, multi-frame and enhanced multi-frame supported, compressed transfer
 *  syntaxes decoded (JPEG, JPEG-LS, RLE, deflate). Decodes on all cores. Throws DicomError with
 *  the file and the problem; refuses what cannot be loaded without distorting the geometry. */
DicomVolume loadDicomSeries(const DicomSeriesInfo& series, const ProgressFn& progress = {},
                            const CancelToken* cancel = nullptr);

/**
 * The series a folder opens with when none is named (fvr-render, the workstation and
 * loadDicomFolder alike): the loadable one with most slices; an unloadable one only when nothing
 * is loadable; ties keep scan order. Returns an index into scan.series; throws DicomError when
 * there is none.
 */
std::size_t defaultSeriesIndex(const DicomScanResult& scan);

/**
 * The series `key` names: the series with that key, else the first with that SeriesInstanceUID
 * (a series split at scan time answers to its UID with its first part; `note` then says so).
 * Throws DicomError naming `folder` and listing the keys found.
 */
const DicomSeriesInfo& findSeries(const DicomScanResult& scan, const std::string& key,
                                  const std::filesystem::path& folder, std::string* note = nullptr);

/** Loads the series `key` names from a scan of `folder` (empty: the default series). The
 *  warnings start with which series was loaded and why when there was a choice, then the
 *  loader's and the scan's warnings for it, each once. `chosen` (optional) receives the series. */
DicomVolume loadChosenSeries(const DicomScanResult& scan, const std::string& key,
                             const std::filesystem::path& folder, const ProgressFn& progress = {},
                             const CancelToken* cancel = nullptr,
                             const DicomSeriesInfo** chosen = nullptr);

/** Convenience: scan `folder` and loadChosenSeries(scan, key). */
DicomVolume loadDicomFolder(const std::filesystem::path& folder, const std::string& key = {});

/** Loads one file (single image or multi-frame) as a volume; throws DicomError. A file that
 *  holds several volumes (split as a scan would) loads the first, with a warning. Used by the
 *  fuzz target and for single-file input. */
DicomVolume loadDicomFile(const std::filesystem::path& file);

} // namespace fvr::core
