// Loading a DICOM series into a Volume: headers (parallel), geometry plan, pixel decoding and
// conversion to real values (parallel, one DcmFileFormat per file and thread), and resampling of
// uneven or sheared stacks onto a regular orthogonal grid.
//
// Pixel values are read as raw words: shifted down by HighBit + 1 - BitsStored (native and RLE
// data; JPEG and JPEG-LS decoders return the samples in the low bits), masked to BitsStored,
// sign-extended from bit BitsStored - 1 when PixelRepresentation is 1, inverted for MONOCHROME1
// (except Hounsfield units, see dicom.h), then rescaled (RescaleSlope/Intercept per frame).
#include "dicom_internal.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcpixel.h>
#include <dcmtk/dcmdata/dcxfer.h>

#include <fvr/core/memory_budget.h>
#include <fvr/core/thread_pool.h>

namespace fvr::core {

using namespace dicom_detail;

namespace {

struct PixelFormat {
    int shift = 0;
    std::uint32_t mask = 0xffffffffu;
    bool isSigned = false;
    std::uint32_t signBit = 0;
    bool invert = false;
    std::int64_t invertSum = 0; ///< min + max of the stored range
};

PixelFormat pixelFormat(const DicomHeader& h, bool invert) {
    PixelFormat pf;
    // JPEG and JPEG-LS decode to samples in the low bits; RLE and native data keep the words.
    const bool lowBits = h.encapsulated && h.xfer != EXS_RLELossless;
    pf.shift = lowBits ? 0 : h.highBit + 1 - h.bitsStored;
    pf.mask = h.bitsStored >= 32 ? 0xffffffffu : ((1u << h.bitsStored) - 1u);
    pf.isSigned = h.pixelRepresentation == 1;
    pf.signBit = 1u << (h.bitsStored - 1);
    pf.invert = invert;
    pf.invertSum = pf.isSigned ? -1 : static_cast<std::int64_t>(pf.mask);
    return pf;
}

inline std::int64_t storedValue(std::uint32_t word, const PixelFormat& pf) {
    const std::uint32_t w = (word >> pf.shift) & pf.mask;
    std::int64_t v = (pf.isSigned && (w & pf.signBit)) ? std::int64_t(w) - std::int64_t(pf.mask) - 1
                                                       : std::int64_t(w);
    return pf.invert ? pf.invertSum - v : v;
}

/** Pixel padding (PixelPaddingValue, up to PixelPaddingRangeLimit when given) marks pixels that
 *  hold no measurement (outside a CT's reconstruction circle, say). They are matched on stored
 *  values before inversion and written as `fill`: air (-1000) for Hounsfield units, else 0 (no
 *  signal), so that they add nothing to a projection. */
struct Padding {
    bool on = false;
    std::int64_t lo = 0, hi = 0;
    float fill = 0.0f;
    Padding(const DicomHeader& h, bool hu) : fill(hu ? -1000.0f : 0.0f) {
        if (!h.paddingValue) return;
        on = true;
        lo = hi = *h.paddingValue;
        if (h.paddingLimit) {
            lo = std::min(lo, *h.paddingLimit);
            hi = std::max(hi, *h.paddingLimit);
        }
    }
    bool operator()(std::int64_t stored) const { return on && stored >= lo && stored <= hi; }
};

struct DecodeCounts {
    std::int64_t nonFinite = 0; ///< non-finite float pixels replaced by 0
    std::int64_t padded = 0; ///< padding pixels whose value changed to the fill
    bool j2kSignReinterpreted = false;
    bool j2kLossyUndeclared = false; ///< 9/7 wavelet without LossyImageCompression 01
};

/** The pixel words of a file that DCMTK decodes (native data, or compressed data decompressed to
 *  native), checked against the size the header declares. */
const void* nativePixelData(const DicomHeader& h, DcmDataset& ds) {
    const fs::path& path = h.path;
    const std::uint64_t frameVox = std::uint64_t(h.rows) * std::uint64_t(h.cols);
    const std::uint64_t bytesPer = h.floatPixelData    ? 4
                                   : h.doublePixelData ? 8
                                                       : std::uint64_t(h.bitsAllocated / 8);
    // rows, cols <= 65535 and frames <= 16384: no overflow.
    const std::uint64_t need = frameVox * std::uint64_t(h.frames) * bytesPer;
    const std::string dims = std::to_string(h.cols) + " x " + std::to_string(h.rows) + " x " +
                             std::to_string(h.frames) + " frames x " + std::to_string(bytesPer) +
                             " bytes";
    if (h.encapsulated) {
        // Sizes against the compressed data were checked by readHeader.
        const OFCondition c = ds.chooseRepresentation(EXS_LittleEndianExplicit, nullptr);
        if (c.bad() || !ds.canWriteXfer(EXS_LittleEndianExplicit))
            fail(path, "cannot decode the " + h.xferName + " pixel data: " +
                           (c.bad() ? std::string(c.text()) : std::string("no decoder")));
    }

    const DcmTagKey tag = h.floatPixelData    ? DCM_FloatPixelData
                          : h.doublePixelData ? DCM_DoubleFloatPixelData
                                              : DCM_PixelData;
    DcmElement* pe = nullptr;
    if (ds.findAndGetElement(tag, pe).bad() || !pe) fail(path, "Pixel Data (7FE0,0010) missing");
    const std::uint64_t have = pe->getLength();
    if (have < need)
        fail(path, "Pixel Data (7FE0,0010): expected " + dims + " = " + std::to_string(need) +
                       " bytes, found " + std::to_string(have) +
                       " (truncated file or wrong header)");

    const void* raw = nullptr;
    OFCondition c = EC_Normal;
    if (h.floatPixelData) {
        Float32* p = nullptr;
        c = pe->getFloat32Array(p);
        raw = p;
    } else if (h.doublePixelData) {
        Float64* p = nullptr;
        c = pe->getFloat64Array(p);
        raw = p;
    } else if (h.bitsAllocated == 8) {
        Uint8* p = nullptr;
        c = pe->getUint8Array(p);
        raw = p;
    } else {
        Uint16* p = nullptr; // 32-bit words: two 16-bit halves in little endian order
        c = pe->getUint16Array(p);
        raw = p;
    }
    if (c.bad() || !raw)
        fail(path, "Pixel Data (7FE0,0010) could not be read: " +
                       std::string(c.bad() ? c.text() : "no value") + " (truncated file?)");
    return raw;
}

/** Converts the frames of one file from stored to real values, counting into `counts`: float
 *  data rescaled (non-finite values become 0); 8 and 16-bit words through a table of every word's
 *  value (the Modality LUT, or the rescale: rebuilt when a frame's rescale differs); 32-bit words
 *  one by one. Padding becomes the fill. */
class FrameConverter {
public:
    FrameConverter(const DicomHeader& h, const void* raw, bool invert, bool hu,
                   DecodeCounts& counts)
        : m_h(h), m_raw(raw), m_frameVox(std::uint64_t(h.rows) * std::uint64_t(h.cols)),
          m_pf(pixelFormat(h, invert)), m_uninverted(m_pf), m_padding(h, hu), m_counts(counts) {
        m_uninverted.invert = false;
    }

    /** Frame `frame` (0-based) of the file into `dst` (rows x cols values). */
    void convert(int frame, float* dst) {
        const FrameInfo& fi = m_h.frameInfo[static_cast<std::size_t>(frame)];
        const double slope = fi.hasRescale ? fi.slope : 1.0;
        const double intercept = fi.hasRescale ? fi.intercept : 0.0;
        const std::uint64_t first = std::uint64_t(frame) * m_frameVox;
        if (m_h.floatPixelData || m_h.doublePixelData) {
            convertFloats(first, slope, intercept, dst);
        } else if (m_h.bitsAllocated <= 16) {
            updateTable(slope, intercept);
            if (m_h.bitsAllocated == 8)
                convertThroughTable(static_cast<const Uint8*>(m_raw) + first, dst);
            else
                convertThroughTable(static_cast<const Uint16*>(m_raw) + first, dst);
        } else {
            convertWords32(first, slope, intercept, dst);
        }
    }

private:
    void convertFloats(std::uint64_t first, double slope, double intercept, float* dst) {
        std::int64_t& nonFinite = m_counts.nonFinite;
        for (std::uint64_t i = 0; i < m_frameVox; ++i) {
            const double v = m_h.floatPixelData
                                 ? double(static_cast<const Float32*>(m_raw)[first + i])
                                 : static_cast<const Float64*>(m_raw)[first + i];
            double out = v * slope + intercept;
            if (!std::isfinite(out)) {
                out = 0.0;
                ++nonFinite;
            }
            dst[i] = static_cast<float>(out);
        }
    }

    /** The value of word `w` (`value`), or the fill when it is padding; notes which it changed. */
    float padWord(std::size_t w, float value) {
        const bool pad = m_padding(storedValue(std::uint32_t(w), m_uninverted));
        m_padChanged[w] = pad && value != m_padding.fill;
        return pad ? m_padding.fill : value;
    }

    /** The table for 8 and 16-bit words: built once for a Modality LUT, for a rescale whenever it
     *  changes. */
    void updateTable(double slope, double intercept) {
        if (m_h.hasModalityLut) {
            if (m_lut.empty()) buildModalityLutTable();
        } else if (m_lut.empty() || slope != m_lutSlope || intercept != m_lutIntercept) {
            buildRescaleTable(slope, intercept);
        }
    }

    void buildModalityLutTable() {
        // Modality LUT instead of the rescale: LUT[stored - first], clamped to the table;
        // MONOCHROME1 inverts the LUT's output range instead of the stored values.
        const auto n = std::int64_t(m_h.modalityLut.size());
        const std::int64_t top = (std::int64_t(1) << m_h.lutBits) - 1;
        m_lut.resize(std::size_t(1) << m_h.bitsAllocated);
        m_padChanged.assign(m_lut.size(), 0);
        for (std::size_t w = 0; w < m_lut.size(); ++w) {
            const std::int64_t i = std::clamp<std::int64_t>(
                storedValue(std::uint32_t(w), m_uninverted) - m_h.lutFirst, 0, n - 1);
            const std::int64_t out = std::min<std::int64_t>(m_h.modalityLut[std::size_t(i)], top);
            m_lut[w] = padWord(w, static_cast<float>(m_pf.invert ? top - out : out));
        }
    }

    void buildRescaleTable(double slope, double intercept) {
        m_lut.resize(std::size_t(1) << m_h.bitsAllocated);
        m_padChanged.assign(m_lut.size(), 0);
        for (std::size_t w = 0; w < m_lut.size(); ++w)
            m_lut[w] =
                padWord(w, static_cast<float>(double(storedValue(std::uint32_t(w), m_pf)) * slope +
                                              intercept));
        m_lutSlope = slope;
        m_lutIntercept = intercept;
    }

    template <class Word>
    void convertThroughTable(const Word* src, float* dst) {
        const std::vector<float>& lut = m_lut;
        if (!m_padding.on) {
            for (std::uint64_t i = 0; i < m_frameVox; ++i) dst[i] = lut[src[i]];
            return;
        }
        std::int64_t changed = 0;
        for (std::uint64_t i = 0; i < m_frameVox; ++i) {
            dst[i] = lut[src[i]];
            changed += m_padChanged[src[i]];
        }
        m_counts.padded += changed;
    }

    void convertWords32(std::uint64_t first, double slope, double intercept, float* dst) {
        static_assert(std::endian::native == std::endian::little,
                      "32-bit pixel words assume a little endian host");
        const auto* src = static_cast<const Uint16*>(m_raw) + 2 * first;
        for (std::uint64_t i = 0; i < m_frameVox; ++i) {
            std::uint32_t w;
            std::memcpy(&w, src + 2 * i, 4);
            const float value =
                static_cast<float>(double(storedValue(w, m_pf)) * slope + intercept);
            const bool pad = m_padding(storedValue(w, m_uninverted));
            m_counts.padded += pad && value != m_padding.fill;
            dst[i] = pad ? m_padding.fill : value;
        }
    }

    const DicomHeader& m_h;
    const void* m_raw;
    const std::uint64_t m_frameVox;
    const PixelFormat m_pf;
    PixelFormat m_uninverted; ///< m_pf without the inversion: padding matches these values
    const Padding m_padding;
    DecodeCounts& m_counts;
    std::vector<float> m_lut; ///< 8 and 16-bit words: each word's value
    std::vector<std::uint8_t> m_padChanged; ///< per word: padding whose value the fill changes
    double m_lutSlope = NAN, m_lutIntercept = NAN; ///< the rescale m_lut was built for
};

/** Converts the listed frames of one file into their slots of `stack`. */
DecodeCounts decodeFile(const DicomHeader& h, DcmFileFormat& ff,
                        const std::vector<std::pair<int, std::int64_t>>& frames, float* stack,
                        std::int64_t sliceVox, bool invert, bool hu) {
    DcmDataset* ds = ff.getDataset();
    DecodeCounts counts;
    Jpeg2000Frames j2k; // JPEG 2000: decoded here with OpenJPEG
    const void* raw = nullptr;
    if (isJpeg2000(h.xfer)) {
        std::vector<int> wanted;
        for (const auto& fr : frames) wanted.push_back(fr.first);
        j2k = decodeJpeg2000(h, *ds, wanted);
        raw = j2k.words.data();
        counts.j2kSignReinterpreted = j2k.signReinterpreted;
        counts.j2kLossyUndeclared = j2k.irreversible && !h.lossyDeclared;
    } else {
        raw = nativePixelData(h, *ds);
    }
    FrameConverter converter(h, raw, invert, hu, counts);
    for (const auto& [frame, slot] : frames) converter.convert(frame, stack + slot * sliceVox);
    return counts;
}

/** Bilinear sample of slice `s` (cols x rows) at (fx, fy); `fill` outside it. */
inline float sample(const float* s, std::int64_t cols, std::int64_t rows, double fx, double fy,
                    float fill) {
    constexpr double eps = 1e-6;
    if (fx < -eps || fy < -eps || fx > double(cols - 1) + eps || fy > double(rows - 1) + eps)
        return fill;
    fx = std::clamp(fx, 0.0, double(cols - 1));
    fy = std::clamp(fy, 0.0, double(rows - 1));
    const std::int64_t x0 =
        std::min<std::int64_t>(std::int64_t(fx), std::max<std::int64_t>(cols - 2, 0));
    const std::int64_t y0 =
        std::min<std::int64_t>(std::int64_t(fy), std::max<std::int64_t>(rows - 2, 0));
    const std::int64_t x1 = std::min(x0 + 1, cols - 1);
    const std::int64_t y1 = std::min(y0 + 1, rows - 1);
    const double ax = fx - double(x0), ay = fy - double(y0);
    const float* r0 = s + y0 * cols;
    const float* r1 = s + y1 * cols;
    const double top = r0[x0] + ax * (r0[x1] - r0[x0]);
    const double bottom = r1[x0] + ax * (r1[x1] - r1[x0]);
    return static_cast<float>(top + ay * (bottom - top));
}

void resampleStack(const std::vector<float>& stack, std::int64_t cols, std::int64_t rows,
                   const GeometryPlan& plan, float fill, std::vector<float>& out, ThreadPool& pool,
                   Progress& prog, const CancelToken* cancel) {
    const std::int64_t nx = plan.dims[0], ny = plan.dims[1], nz = plan.dims[2];
    const std::size_t n = plan.t.size();
    const std::int64_t sliceIn = cols * rows;
    runParallel(pool, nz, 1, [&](std::int64_t j) {
        checkCancel(cancel);
        const double z = plan.z0 + double(j) * plan.spacing[2];
        std::size_t k =
            std::size_t(std::upper_bound(plan.t.begin(), plan.t.end(), z) - plan.t.begin());
        k = k == 0 ? 0 : k - 1;
        k = std::min(k, n - 2);
        const double w = std::clamp((z - plan.t[k]) / (plan.t[k + 1] - plan.t[k]), 0.0, 1.0);
        float* dst = out.data() + j * nx * ny;
        auto sampleInto = [&](std::size_t s, float* target) {
            const float* src = stack.data() + std::int64_t(s) * sliceIn;
            for (std::int64_t y = 0; y < ny; ++y)
                for (std::int64_t x = 0; x < nx; ++x)
                    target[y * nx + x] = sample(src, cols, rows, double(x) - plan.du[s],
                                                double(y) - plan.dv[s], fill);
        };
        if (w <= 1e-6) {
            sampleInto(k, dst);
        } else if (w >= 1.0 - 1e-6) {
            sampleInto(k + 1, dst);
        } else {
            std::vector<float> upper(static_cast<std::size_t>(nx * ny));
            sampleInto(k, dst);
            sampleInto(k + 1, upper.data());
            const float wf = static_cast<float>(w);
            for (std::int64_t i = 0; i < nx * ny; ++i)
                dst[i] += wf * (upper[std::size_t(i)] - dst[i]);
        }
        prog.step();
    });
}

void validate(const Dims3& dims, const Vec3& spacing, const std::string& source) {
    try {
        validateGeometry(dims, spacing, source);
    } catch (const LoadError& e) {
        throw DicomError(e.what());
    }
}

/** The decoded slices (and the resampled volume beside them) must fit in the memory this
 *  process may take: rows x columns x frames come from the headers, and compressed pixel data
 *  can declare far more than the files hold. */
void checkSeriesMemory(std::int64_t stackVoxels, const GeometryPlan& plan,
                       const std::string& source) {
    const std::uint64_t voxels =
        std::uint64_t(stackVoxels) +
        (plan.resample ? std::uint64_t(plan.dims[0] * plan.dims[1] * plan.dims[2]) : 0);
    try {
        checkMemoryFor(voxels * sizeof(float), source,
                       "the series' " + std::to_string(voxels) + " voxels as float" +
                           (plan.resample ? " (slices and resampled volume)" : ""));
    } catch (const LoadError& e) {
        throw DicomError(e.what());
    }
}

/** "DICOM series <key> in <folder>" for messages, or the file's path for a single file. */
std::string seriesSource(const DicomSeriesInfo& series) {
    const std::string name = series.key.empty() ? series.seriesUid : series.key;
    return series.files.size() == 1
               ? series.files[0].string()
               : "DICOM series " + (name.empty() ? std::string("(unnamed)") : name) +
                     (series.files.empty() ? std::string()
                                           : " in " + series.files[0].parent_path().string());
}

/** The series' files, parsed (their pixel data loads on demand), and their headers. */
struct SeriesFiles {
    std::vector<DicomHeader> headers;
    std::vector<std::unique_ptr<DcmFileFormat>> parsed;
};

/** Reads the files in parallel; throws for a file whose pixel format cannot be loaded. */
SeriesFiles readSeriesFiles(const DicomSeriesInfo& series, ThreadPool& pool,
                            const ProgressFn& progress, const CancelToken* cancel) {
    const std::size_t nFiles = series.files.size();
    SeriesFiles files;
    files.headers.resize(nFiles);
    files.parsed.resize(nFiles);
    Progress prog(progress, "reading DICOM headers", 0.0, 0.1, std::int64_t(nFiles));
    runParallel(pool, std::int64_t(nFiles), 4, [&](std::int64_t i) {
        checkCancel(cancel);
        const auto k = static_cast<std::size_t>(i);
        files.headers[k] = readHeader(series.files[k], &files.parsed[k]);
        if (const std::string why = unsupportedReason(files.headers[k]); !why.empty())
            fail(series.files[k], why);
        prog.step();
    });
    return files;
}

void checkSameImageSize(const std::vector<DicomHeader>& hs, const std::string& source) {
    const std::int64_t cols = hs[0].cols, rows = hs[0].rows;
    for (const DicomHeader& h : hs)
        if (h.cols != cols || h.rows != rows)
            throw DicomError(source + ": mixed image sizes: " + hs[0].path.string() + " is " +
                             std::to_string(cols) + " x " + std::to_string(rows) + ", " +
                             h.path.string() + " is " + std::to_string(h.cols) + " x " +
                             std::to_string(h.rows) + " (a scan puts them in separate series)");
}

/** The frames that make up the series (in file order), for the geometry plan and the decoder. */
struct SeriesFrames {
    std::vector<PlanSlice> slices;
    std::vector<FrameRef> refs;
};

/** Each file's frames in the series' selection (every frame when it selects none). */
SeriesFrames selectFrames(const DicomSeriesInfo& series, const std::vector<DicomHeader>& hs,
                          const std::string& source) {
    SeriesFrames out;
    for (std::size_t i = 0; i < hs.size(); ++i) {
        const DicomHeader& h = hs[i];
        std::vector<std::int32_t> sel;
        if (!series.frames.empty() && !series.frames[i].empty())
            sel = series.frames[i];
        else
            for (std::int32_t f = 0; f < std::int32_t(h.frames); ++f) sel.push_back(f);
        for (std::int32_t f : sel) {
            if (f < 0 || f >= h.frames)
                throw DicomError(source + ": " + h.path.string() + " has " +
                                 std::to_string(h.frames) + " frames, frame " +
                                 std::to_string(f + 1) + " was asked for");
            out.slices.push_back({&h.frameInfo[static_cast<std::size_t>(f)], sliceLabel(h, f),
                                  h.frames > 1, h.gantryTilt, int(i)});
            out.refs.push_back({int(i), f});
        }
    }
    return out;
}

/** The volume's warnings, in order, each added once. */
struct Warnings {
    std::vector<std::string> list;
    void add(const std::string& w) {
        if (std::find(list.begin(), list.end(), w) == list.end()) list.push_back(w);
    }
};

/** The scan's warnings, the files' malformed attributes and the plan's warnings. */
Warnings initialWarnings(const DicomSeriesInfo& series, const std::vector<DicomHeader>& hs,
                         const GeometryPlan& plan) {
    Warnings warnings;
    warnings.list = series.warnings;
    std::set<std::string> seen;
    for (const DicomHeader& h : hs)
        for (const auto& p : h.problems)
            if (seen.insert(p).second) warnings.add(h.path.filename().string() + ": " + p);
    for (const auto& w : plan.warnings) warnings.add(w);
    return warnings;
}

/** The modality transform over the series' slices. */
struct Rescale {
    bool isCt = false;
    bool all = true; ///< every slice has a rescale (or the Modality LUT)
    bool any = false;
    bool typeHu = true; ///< every file's RescaleType is HU
    std::string otherType; ///< a RescaleType other than HU ("LUT": a non-HU Modality LUT)
    bool lut = false; ///< the Modality LUT replaces the rescale
};

/** The slices' rescale; throws when only some of them have one. */
Rescale sliceRescale(const std::vector<DicomHeader>& hs, const SeriesFrames& frames,
                     const std::string& source) {
    Rescale r;
    const auto& slices = frames.slices;
    for (std::size_t s = 0; s < slices.size(); ++s) {
        const DicomHeader& h = hs[static_cast<std::size_t>(frames.refs[s].file)];
        r.isCt = r.isCt || h.modality == "CT";
        r.all = r.all && slices[s].info->hasRescale;
        r.any = r.any || slices[s].info->hasRescale;
        r.typeHu = r.typeHu && h.rescaleType == "HU";
        if (!h.rescaleType.empty() && h.rescaleType != "HU") r.otherType = h.rescaleType;
    }
    if (r.any && !r.all) {
        for (std::size_t s = 0; s < slices.size(); ++s)
            if (!slices[s].info->hasRescale)
                throw DicomError(source +
                                 ": RescaleSlope/RescaleIntercept (0028,1053/1052) missing in " +
                                 slices[s].label +
                                 " but present in other slices: their values "
                                 "would not be comparable");
    }
    return r;
}

/** A Modality LUT (in every file or in none, else throws) replaces the rescale. */
void applyModalityLut(const std::vector<DicomHeader>& hs, const std::string& source, Rescale& r,
                      Warnings& warnings) {
    bool anyLut = false, allLutHu = true;
    for (const DicomHeader& h : hs) {
        anyLut = anyLut || h.hasModalityLut;
        allLutHu = allLutHu && h.hasModalityLut && h.lutType == "HU";
    }
    if (!anyLut) return;
    for (const DicomHeader& h : hs)
        if (!h.hasModalityLut)
            throw DicomError(source + ": Modality LUT Sequence (0028,3000) missing in " +
                             h.path.string() + " but present in other files of the series");
    r.lut = true;
    r.all = true; // the LUT is the modality transform
    r.any = true;
    r.otherType = allLutHu ? std::string() : "LUT";
    r.typeHu = allLutHu;
    warnings.add("Modality LUT Sequence (0028,3000) applied (ModalityLUTType '" + hs[0].lutType +
                 "')");
}

void warnMonochrome1(const std::vector<DicomHeader>& hs, bool hu, Warnings& warnings) {
    bool anyMono1 = false;
    for (const DicomHeader& h : hs) anyMono1 = anyMono1 || h.photometric == "MONOCHROME1";
    if (!anyMono1) return;
    if (hu)
        warnings.add("MONOCHROME1: Hounsfield units kept as they are (MONOCHROME1 only says how to "
                     "display them: low values white)");
    else
        warnings.add(
            "MONOCHROME1: stored values inverted (v -> min + max of the BitsStored range - v, "
            "before rescale) so that larger values are brighter");
}

/** Units: Hounsfield for CT with a rescale (or RescaleType HU), else intensity. True for HU. */
bool decideUnits(const std::vector<DicomHeader>& hs, const SeriesFrames& frames,
                 const std::string& source, Warnings& warnings) {
    Rescale r = sliceRescale(hs, frames, source);
    applyModalityLut(hs, source, r, warnings);
    // A CT rescale gives Hounsfield units unless RescaleType says otherwise (it is only written
    // when the values are not HU; 'US' means unspecified).
    const bool hu = r.all && ((r.isCt && r.otherType.empty()) || r.typeHu);
    if (r.isCt && r.all && !r.otherType.empty() && !r.lut)
        warnings.add("RescaleType (0028,1054) '" + r.otherType +
                     "' on a CT image: the rescaled "
                     "values are not declared Hounsfield units and are loaded as intensity");
    if (r.isCt && !r.all)
        warnings.add(
            "CT without RescaleSlope/RescaleIntercept: values are stored pixel values, not "
            "Hounsfield units");
    warnMonochrome1(hs, hu, warnings);
    return hu;
}

/** The sorted slices, decoded, and what decoding counted over all files. */
struct DecodedStack {
    std::vector<float> voxels;
    DecodeCounts counts;
};

/** Decodes every file's frames into the stack of sorted slices (the volume itself when no
 *  resampling is needed): one file per task, its parsed data freed as soon as it is decoded. */
DecodedStack decodeSlices(SeriesFiles& files, const std::vector<FrameRef>& refs,
                          const GeometryPlan& plan, std::int64_t sliceVox, bool hu,
                          ThreadPool& pool, const ProgressFn& progress, const CancelToken* cancel) {
    const std::vector<DicomHeader>& hs = files.headers;
    const std::size_t nFiles = hs.size();
    const std::size_t nSlices = refs.size();
    DecodedStack out;
    std::vector<float>& stack = out.voxels;
    stack.resize(static_cast<std::size_t>(sliceVox) * nSlices);
    std::vector<std::vector<std::pair<int, std::int64_t>>> perFile(nFiles);
    for (std::size_t k = 0; k < nSlices; ++k) {
        const FrameRef& ref = refs[static_cast<std::size_t>(plan.order[k])];
        perFile[static_cast<std::size_t>(ref.file)].emplace_back(ref.frame, std::int64_t(k));
    }
    std::atomic<std::int64_t> nonFinite{0}, padded{0};
    std::atomic<bool> j2kSign{false}, j2kLossy{false};
    {
        Progress prog(progress, "decoding DICOM pixels", 0.1, plan.resample ? 0.8 : 1.0,
                      std::int64_t(nFiles));
        runParallel(pool, std::int64_t(nFiles), 1, [&](std::int64_t i) {
            checkCancel(cancel);
            const auto k = static_cast<std::size_t>(i);
            const bool invert = hs[k].photometric == "MONOCHROME1" && !hu;
            const DecodeCounts c =
                decodeFile(hs[k], *files.parsed[k], perFile[k], stack.data(), sliceVox, invert, hu);
            nonFinite += c.nonFinite;
            padded += c.padded;
            if (c.j2kSignReinterpreted) j2kSign = true;
            if (c.j2kLossyUndeclared) j2kLossy = true;
            files.parsed[k].reset(); // frees the file's pixel data at once
            prog.step();
        });
    }
    out.counts.nonFinite = nonFinite.load();
    out.counts.padded = padded.load();
    out.counts.j2kSignReinterpreted = j2kSign.load();
    out.counts.j2kLossyUndeclared = j2kLossy.load();
    return out;
}

/** What decoding changed or found: non-finite values, JPEG 2000 surprises, padding. */
void warnDecoding(const DecodeCounts& counts, const std::vector<DicomHeader>& hs,
                  std::size_t voxels, bool hu, Warnings& warnings) {
    if (counts.nonFinite > 0)
        warnings.add(std::to_string(counts.nonFinite) +
                     " non-finite float pixel values (NaN/Inf) set to 0");
    if (counts.j2kSignReinterpreted)
        warnings.add(
            "JPEG 2000 codestream signedness differs from PixelRepresentation (0028,0103) " +
            std::to_string(hs[0].pixelRepresentation) +
            ": the samples' BitsStored bits are read as the header declares (" +
            (hs[0].pixelRepresentation == 1 ? "two's complement" : "unsigned") + ")");
    if (counts.j2kLossyUndeclared)
        warnings.add("lossy JPEG 2000 (irreversible 9/7 wavelet) although LossyImageCompression "
                     "(0028,2110) does not "
                     "say so: the values are approximations of the original");
    if (counts.padded > 0) {
        const auto h = std::find_if(
            hs.begin(), hs.end(), [](const DicomHeader& x) { return x.paddingValue.has_value(); });
        std::string what = "PixelPaddingValue (0028,0120) " + std::to_string(*h->paddingValue);
        if (h->paddingLimit)
            what += " to PixelPaddingRangeLimit (0028,0121) " + std::to_string(*h->paddingLimit);
        char share[32];
        std::snprintf(share, sizeof share, "%.1f", 100.0 * double(counts.padded) / double(voxels));
        warnings.add(what + ": " + std::to_string(counts.padded) + " padding pixels (" + share +
                     " %, no measurement there) set to " +
                     (hu ? "air (-1000 HU)" : "0 (no signal)"));
    }
}

/** The series description, else "<modality> series [number]", else "DICOM series". */
std::string volumeName(const DicomHeader& h0) {
    return !h0.description.empty() ? h0.description
           : !h0.modality.empty()
               ? h0.modality + " series" + (h0.seriesNumber.empty() ? "" : " " + h0.seriesNumber)
               : std::string("DICOM series");
}

/** The volume on the plan's grid: the stack itself, or the stack resampled onto it (outside the
 *  slices: the stack's minimum). */
Volume assembleVolume(std::vector<float>&& stack, const GeometryPlan& plan, bool hu,
                      const DicomHeader& h0, ThreadPool& pool, const ProgressFn& progress,
                      const CancelToken* cancel) {
    Volume vol;
    vol.dims = plan.dims;
    vol.spacing = plan.spacing;
    vol.origin = plan.origin;
    vol.direction = plan.direction;
    vol.units = hu ? ValueUnits::HounsfieldUnits : ValueUnits::Intensity;
    vol.name = volumeName(h0);
    if (!plan.resample) {
        vol.voxels = std::move(stack);
    } else {
        float fill = std::numeric_limits<float>::infinity();
        for (float v : stack) fill = std::min(fill, v);
        vol.voxels.resize(static_cast<std::size_t>(vol.voxelCount()));
        Progress prog(progress, "resampling DICOM slices", 0.8, 1.0, plan.dims[2]);
        resampleStack(stack, h0.cols, h0.rows, plan, fill, vol.voxels, pool, prog, cancel);
    }
    return vol;
}

} // namespace

DicomVolume loadDicomSeries(const DicomSeriesInfo& series, const ProgressFn& progress,
                            const CancelToken* cancel) {
    initDcmtk();
    const std::string source = seriesSource(series);
    if (series.files.empty()) throw DicomError(source + ": no files");
    if (!series.frames.empty() && series.frames.size() != series.files.size())
        throw DicomError(source + ": the frame selection lists " +
                         std::to_string(series.frames.size()) + " files, the series " +
                         std::to_string(series.files.size()));

    ThreadPool pool;
    SeriesFiles files = readSeriesFiles(series, pool, progress, cancel);
    const std::vector<DicomHeader>& hs = files.headers;
    checkSameImageSize(hs, source);
    const std::int64_t cols = hs[0].cols, rows = hs[0].rows;

    // The frames that make up the series, and their geometry.
    const SeriesFrames frames = selectFrames(series, hs, source);
    validate({cols, rows, std::int64_t(frames.slices.size())}, {1, 1, 1}, source);
    const GeometryPlan plan = planGeometry(frames.slices, cols, rows, source);
    validate(plan.dims, plan.spacing, source);
    checkSeriesMemory(cols * rows * std::int64_t(frames.slices.size()), plan, source);

    Warnings warnings = initialWarnings(series, hs, plan);
    const bool hu = decideUnits(hs, frames, source, warnings);
    DecodedStack stack =
        decodeSlices(files, frames.refs, plan, cols * rows, hu, pool, progress, cancel);
    warnDecoding(stack.counts, hs, stack.voxels.size(), hu, warnings);

    DicomVolume result;
    result.volume =
        assembleVolume(std::move(stack.voxels), plan, hu, hs[0], pool, progress, cancel);
    if (progress) progress(1.0, "DICOM series loaded");
    result.warnings = std::move(warnings.list);
    return result;
}

DicomVolume loadDicomFile(const std::filesystem::path& file) {
    DicomHeader h = readHeader(file);
    if (const std::string why = unsupportedReason(h); !why.empty()) fail(file, why);
    std::vector<std::string> skipped;
    std::vector<DicomHeader> hs;
    hs.push_back(std::move(h));
    std::vector<DicomSeriesInfo> series = groupIntoSeries(hs, skipped);
    if (series.empty()) fail(file, "no image in the file");
    DicomVolume v = loadDicomSeries(series[0]);
    if (series.size() > 1)
        v.warnings.insert(v.warnings.begin(), file.string() + " holds " +
                                                  std::to_string(series.size()) +
                                                  " volumes; loaded the first (" +
                                                  std::to_string(series[0].frameCount) +
                                                  " frames); scan the file to choose another");
    return v;
}

std::vector<float> dicom_detail::decodeAllFrames(const DicomHeader& h, DcmFileFormat& ff,
                                                 bool invert, std::int64_t* nonFinite,
                                                 std::int64_t* padded) {
    const std::int64_t frameVox = h.rows * h.cols;
    std::vector<float> out(static_cast<std::size_t>(frameVox * h.frames));
    std::vector<std::pair<int, std::int64_t>> frames;
    for (std::int64_t f = 0; f < h.frames; ++f) frames.emplace_back(int(f), f);
    const DecodeCounts c = decodeFile(h, ff, frames, out.data(), frameVox, invert, false);
    if (nonFinite) *nonFinite = c.nonFinite;
    if (padded) *padded = c.padded;
    return out;
}

} // namespace fvr::core
