#pragma once
// Internals shared by the DICOM scanner (dicom_scan.cpp), loader (dicom_load.cpp), header
// reader (dicom_header.cpp) and geometry planner (dicom_geometry.cpp). Not installed.
#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/volume.h>

class DcmFileFormat;
class DcmDataset;

namespace fvr::core::dicom_detail {

namespace fs = std::filesystem;

/** Registers the JPEG, JPEG-LS and RLE decoders and quietens DCMTK's console logging (our
 *  errors carry the details). Thread-safe, idempotent. */
void initDcmtk();

/** "<file>: <detail>" as a DicomError. */
[[noreturn]] void fail(const fs::path& file, const std::string& detail);

/** The file is no DICOM at all (text, another format): a scan counts such files together. */
struct NotDicomError : DicomError {
    using DicomError::DicomError;
};

/** A DICOM object without an image (structure set, report, presentation state...). */
struct NoImageError : DicomError {
    NoImageError(const std::string& message, std::string className)
        : DicomError(message), sopClass(std::move(className)) {}
    std::string sopClass; ///< its SOP class in words ("RT Structure Set Storage"), or the UID
};

/** A SOP class UID in words from DCMTK's dictionary ("RT Structure Set Storage" for
 *  1.2.840.10008.5.1.4.1.1.481.3); empty when the dictionary does not know it. */
std::string sopClassName(const std::string& uid);

/** "RT Structure Set Storage (1.2.840.10008.5.1.4.1.1.481.3)", "SOP class <uid>" when unknown,
 *  "a DICOM object of unknown SOP class" when empty. */
std::string describeSopClass(const std::string& uid);

/** Throws Cancelled when the token was cancelled (no dependency on preprocess.cpp). */
inline void checkCancel(const CancelToken* cancel) {
    if (cancel && cancel->cancelled()) throw Cancelled();
}

/** Geometry and value transform of one frame (a single-frame file has one). */
struct FrameInfo {
    bool hasPosition = false;
    Vec3 position{0, 0, 0}; ///< ImagePositionPatient (LPS, mm)
    bool fileLevelPosition =
        false; ///< classic multi-frame: `position` is the file's, not the frame's
    bool hasOrientation = false;
    std::array<double, 6> orientation{}; ///< ImageOrientationPatient: row cosines, column cosines
    bool hasPixelSpacing = false;
    double rowSpacing = 1.0; ///< PixelSpacing[0]: between rows (along the column direction)
    double colSpacing = 1.0; ///< PixelSpacing[1]: between columns (along the row direction)
    double sliceThickness = 0.0; ///< 0: absent
    double spacingBetweenSlices = 0.0; ///< 0: absent
    bool hasRescale = false;
    double slope = 1.0;
    double intercept = 0.0;
    /** Attributes that tell acquisitions apart; compared as text. */
    std::string echo; ///< EchoNumbers or the MR echo's EffectiveEchoTime
    std::string acquisition; ///< AcquisitionNumber
    std::string temporal; ///< TemporalPositionIdentifier / TemporalPositionIndex
    std::string stack; ///< StackID
    std::string imageType; ///< ImageType / FrameType
    std::string triggerTime; ///< TriggerTime / NominalCardiacTriggerDelayTime
    std::string diffusion; ///< DiffusionBValue
    std::vector<std::int32_t> dimensionIndex; ///< DimensionIndexValues
};

/** Everything the scanner and loader need from a file, read without its pixel values. */
struct DicomHeader {
    fs::path path;
    std::string sopInstanceUid, sopClassUid, studyUid, seriesUid, seriesNumber;
    std::string patientName, patientId, studyDate, modality, description;
    DicomStudyFields study;
    std::string rescaleType;
    int xfer = 0; ///< E_TransferSyntax of the file
    std::string xferUid, xferName;
    bool encapsulated = false;
    bool bigEndian = false;
    bool decodable = true; ///< a decoder for the transfer syntax is registered
    std::int64_t rows = 0, cols = 0, frames = 1;
    int samplesPerPixel = 1, bitsAllocated = 0, bitsStored = 0, highBit = 0,
        pixelRepresentation = 0;
    std::string photometric;
    bool hasPixelData = false; ///< (7FE0,0010)
    bool floatPixelData = false; ///< (7FE0,0008) Float Pixel Data instead
    bool doublePixelData = false; ///< (7FE0,0009) Double Float Pixel Data instead
    std::uint64_t pixelDataLength = 0; ///< native: the value length; encapsulated: sum of fragments
    std::int64_t fragments = 0; ///< encapsulated: number of fragments (offset table excluded)
    bool hasModalityLut = false; ///< a Modality LUT replaces the rescale
    std::string modalityLutProblem; ///< why the LUT cannot be used (empty: usable)
    std::vector<std::uint16_t> modalityLut; ///< LUTData
    std::int64_t lutFirst = 0; ///< first stored value mapped
    int lutBits = 16; ///< bits per LUT entry
    std::string lutType; ///< ModalityLUTType (HU, OD, US...)
    bool enhanced = false; ///< per-frame functional groups present
    std::string gantryTilt; ///< GantryDetectorTilt as written
    /// PixelPaddingValue (0028,0120) and PixelPaddingRangeLimit (0028,0121), in stored-value
    /// units (before inversion and rescale; signed when PixelRepresentation is 1).
    std::optional<std::int64_t> paddingValue, paddingLimit;
    bool lossyDeclared = false; ///< LossyImageCompression (0028,2110) is 01
    std::vector<FrameInfo> frameInfo; ///< one per frame
    std::vector<std::string> problems; ///< malformed geometry attributes (become warnings)
};

/** Reads the header of `path` (pixel values are not loaded: elements above a few KiB stay on
 *  disk). Throws DicomError naming the file for unreadable files and non-images. When `keep`
 *  is given, the parsed file is handed over (its pixel data loads on demand). */
DicomHeader readHeader(const fs::path& path, std::unique_ptr<DcmFileFormat>* keep = nullptr);

/** JPEG 2000 (1.2.840.10008.1.2.4.90/.91): decoded with OpenJPEG, DCMTK has no codec for it. */
bool isJpeg2000(int xfer);
struct Jpeg2000Frames {
    std::vector<std::uint8_t>
        words; ///< little-endian words of BitsAllocated, samples in the low bits
    bool signReinterpreted =
        false; ///< the codestream's signedness differs from PixelRepresentation
    bool irreversible = false; ///< a codestream uses the 9/7 wavelet (lossy)
};
/** Decodes the listed frames (0-based) of a JPEG 2000 file, frame f at f * rows * cols words (the
 *  other frames stay 0). Throws DicomError naming the file (fragments that do not split into the
 *  frames, colour, size or more bits than the header's, a corrupt or truncated codestream). */
Jpeg2000Frames decodeJpeg2000(const DicomHeader& h, DcmDataset& ds, const std::vector<int>& frames);

/** Empty when the header's pixel format can be loaded, else the reason (unsupported
 *  transfer syntax, colour, bit depth...). */
std::string unsupportedReason(const DicomHeader& h);

/** Every frame of one file in file order, as real values (rescale or Modality LUT, as the
 *  loader does; MONOCHROME1 inverted when `invert`; padding set to 0): frame f at
 *  f * rows * cols. For single images and X-ray frames, which no geometry plan reorders.
 *  Counts non-finite float values (set to 0) and changed padding pixels. Throws DicomError. */
std::vector<float> decodeAllFrames(const DicomHeader& h, DcmFileFormat& ff, bool invert,
                                   std::int64_t* nonFinite = nullptr,
                                   std::int64_t* padded = nullptr);

/** The frames taken from one file for a series. */
struct FrameRef {
    int file = 0; ///< index into the series' files
    int frame = 0; ///< 0-based frame within the file
};

/** Where the sorted input slices go and how. */
struct GeometryPlan {
    Dims3 dims{0, 0, 0};
    Vec3 spacing{1, 1, 1};
    Vec3 origin{0, 0, 0};
    glm::dmat3 direction{1.0}; ///< as Volume::direction
    std::vector<int> order; ///< indices into the planner's input, sorted along the normal
    bool resample = false; ///< uneven spacing or sheared stack: interpolate
    std::vector<double> t; ///< sorted slices' distances along the normal (mm), resample only
    std::vector<double> du, dv; ///< sorted slices' in-plane offsets (output pixels), resample only
    double z0 = 0.0; ///< distance along the normal of output slice 0
    std::vector<std::string> warnings;
};

struct PlanSlice {
    const FrameInfo* info = nullptr;
    std::string label; ///< file (and frame) for messages
    bool fromMultiFrame = false;
    std::string gantryTilt; ///< GantryDetectorTilt as written (for the message)
    int file = 0; ///< which file the slice comes from
};

/** Plans the volume for slices of cols x rows pixels. Throws DicomError (naming `source`)
 *  for what cannot be loaded without distortion: duplicate positions, missing positions in a
 *  multi-file series, invalid orientation. */
GeometryPlan planGeometry(const std::vector<PlanSlice>& slices, std::int64_t cols,
                          std::int64_t rows, const std::string& source);

/** Groups headers into series: by SeriesInstanceUID, split by image size, pixel spacing,
 *  orientation and echo, then by an acquisition attribute where that resolves duplicate
 *  positions (see dicom_scan.cpp). Files repeating a SOPInstanceUID go to `skipped`. */
std::vector<DicomSeriesInfo> groupIntoSeries(const std::vector<DicomHeader>& headers,
                                             std::vector<std::string>& skipped);

/** "name" or "name frame k" (1-based) for messages. */
std::string sliceLabel(const DicomHeader& h, std::int64_t frame);

/** Fixed-point text of v. */
std::string fmt(double v, int precision = 3);

/** pool.parallelFor over items 0..count-1 calling fn(i), with exceptions kept out of the pool:
 *  the first one stops the remaining items and is rethrown here once every worker is done.
 *  (ThreadPool::parallelFor's own error path can return while a late worker still picks up a
 *  chunk; this wrapper never takes it.) */
template <class Pool, class Fn>
void runParallel(Pool& pool, std::int64_t count, std::int64_t grain, Fn&& fn) {
    std::mutex mutex;
    std::exception_ptr first;
    std::atomic<bool> failed{false};
    pool.parallelFor(count, grain, [&](std::int64_t b, std::int64_t e) {
        for (std::int64_t i = b; i < e && !failed.load(std::memory_order_relaxed); ++i) {
            try {
                fn(i);
            } catch (...) {
                std::lock_guard lock(mutex);
                if (!first) first = std::current_exception();
                failed.store(true, std::memory_order_relaxed);
            }
        }
    });
    if (first) std::rethrow_exception(first);
}

/** Progress reported from the calling thread only, monotone, mapped into [lo, hi]. */
class Progress {
public:
    Progress(const ProgressFn& fn, const char* stage, double lo, double hi, std::int64_t total)
        : m_fn(fn), m_stage(stage), m_lo(lo), m_hi(hi), m_total(total > 0 ? total : 1),
          m_owner(std::this_thread::get_id()) {
        report(0);
    }
    /** Counts `n` finished items; thread-safe. */
    void step(std::int64_t n = 1) {
        const std::int64_t done = m_done.fetch_add(n) + n;
        if (std::this_thread::get_id() == m_owner) report(done);
    }
    void finish() { report(m_total); }

private:
    void report(std::int64_t done) {
        if (!m_fn) return;
        const double f = m_lo + (m_hi - m_lo) * std::min(1.0, double(done) / double(m_total));
        if (f < m_last) return;
        m_last = f;
        m_fn(f, m_stage);
    }
    const ProgressFn& m_fn;
    const char* m_stage;
    double m_lo, m_hi;
    std::int64_t m_total;
    std::atomic<std::int64_t> m_done{0};
    std::thread::id m_owner;
    double m_last = -1.0;
};

} // namespace fvr::core::dicom_detail
