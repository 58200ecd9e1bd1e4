// Loading a DICOM series into a Volume: headers (parallel), geometry plan, pixel decoding and
// conversion to real values (parallel, one DcmFileFormat per file and thread), and resampling of
// uneven or sheared stacks onto a regular orthogonal grid.
//
// Pixel values are read as raw words: shifted down by HighBit + 1 - BitsStored (native and RLE
// data; JPEG and JPEG-LS decoders return the samples in the low bits), masked to BitsStored,
// sign-extended from bit BitsStored - 1 when PixelRepresentation is 1, inverted for MONOCHROME1
// (except Hounsfield units, see dicom.h), then rescaled (RescaleSlope/Intercept per frame).
#include "dicom_internal.h"

#include <fvr/core/io/open_study.h>

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
    std::int64_t padded = 0;    ///< padding pixels whose value changed to the fill
    bool j2kSignReinterpreted = false;
    bool j2kLossyUndeclared = false; ///< 9/7 wavelet without LossyImageCompression 01
};

/** Converts the listed frames of one file into their slots of `stack`. */
DecodeCounts decodeFile(const DicomHeader& h, DcmFileFormat& ff,
                        const std::vector<std::pair<int, std::int64_t>>& frames, float* stack,
                        std::int64_t sliceVox, bool invert, bool hu) {
    const fs::path& path = h.path;
    DcmDataset* ds = ff.getDataset();
    const std::uint64_t frameVox = std::uint64_t(h.rows) * std::uint64_t(h.cols);
    const std::uint64_t bytesPer = h.floatPixelData    ? 4
                                   : h.doublePixelData ? 8
                                                       : std::uint64_t(h.bitsAllocated / 8);
    // rows, cols <= 65535 and frames <= 16384: no overflow.
    const std::uint64_t need = frameVox * std::uint64_t(h.frames) * bytesPer;
    const std::string dims = std::to_string(h.cols) + " x " + std::to_string(h.rows) + " x " +
                             std::to_string(h.frames) + " frames x " + std::to_string(bytesPer) +
                             " bytes";

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
        if (h.encapsulated) {
            // Sizes against the compressed data were checked by readHeader.
            const OFCondition c = ds->chooseRepresentation(EXS_LittleEndianExplicit, nullptr);
            if (c.bad() || !ds->canWriteXfer(EXS_LittleEndianExplicit))
                fail(path, "cannot decode the " + h.xferName + " pixel data: " +
                               (c.bad() ? std::string(c.text()) : std::string("no decoder")));
        }

        const DcmTagKey tag = h.floatPixelData    ? DCM_FloatPixelData
                              : h.doublePixelData ? DCM_DoubleFloatPixelData
                                                  : DCM_PixelData;
        DcmElement* pe = nullptr;
        if (ds->findAndGetElement(tag, pe).bad() || !pe) fail(path, "Pixel Data (7FE0,0010) missing");
        const std::uint64_t have = pe->getLength();
        if (have < need)
            fail(path, "Pixel Data (7FE0,0010): expected " + dims + " = " + std::to_string(need) +
                           " bytes, found " + std::to_string(have) + " (truncated file or wrong header)");

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
    }

    const PixelFormat pf = pixelFormat(h, invert);
    PixelFormat uninverted = pf;
    uninverted.invert = false;
    const Padding padding(h, hu);
    std::vector<float> lut;
    std::vector<std::uint8_t> padChanged; // per word: padding whose value the fill changes
    auto padWord = [&](std::size_t w, float value) {
        const bool pad = padding(storedValue(std::uint32_t(w), uninverted));
        padChanged[w] = pad && value != padding.fill;
        return pad ? padding.fill : value;
    };
    double lutSlope = NAN, lutIntercept = NAN;
    std::int64_t& nonFinite = counts.nonFinite;
    for (const auto& [frame, slot] : frames) {
        const FrameInfo& fi = h.frameInfo[static_cast<std::size_t>(frame)];
        const double slope = fi.hasRescale ? fi.slope : 1.0;
        const double intercept = fi.hasRescale ? fi.intercept : 0.0;
        float* dst = stack + slot * sliceVox;
        const std::uint64_t first = std::uint64_t(frame) * frameVox;
        if (h.floatPixelData || h.doublePixelData) {
            for (std::uint64_t i = 0; i < frameVox; ++i) {
                const double v = h.floatPixelData ? double(static_cast<const Float32*>(raw)[first + i])
                                                  : static_cast<const Float64*>(raw)[first + i];
                double out = v * slope + intercept;
                if (!std::isfinite(out)) {
                    out = 0.0;
                    ++nonFinite;
                }
                dst[i] = static_cast<float>(out);
            }
        } else if (h.bitsAllocated <= 16) {
            if (h.hasModalityLut && lut.empty()) {
                // Modality LUT instead of the rescale: LUT[stored - first], clamped to the table;
                // MONOCHROME1 inverts the LUT's output range instead of the stored values.
                PixelFormat plain = pf;
                plain.invert = false;
                const auto n = std::int64_t(h.modalityLut.size());
                const std::int64_t top = (std::int64_t(1) << h.lutBits) - 1;
                lut.resize(std::size_t(1) << h.bitsAllocated);
                padChanged.assign(lut.size(), 0);
                for (std::size_t w = 0; w < lut.size(); ++w) {
                    const std::int64_t i =
                        std::clamp<std::int64_t>(storedValue(std::uint32_t(w), plain) - h.lutFirst, 0, n - 1);
                    const std::int64_t out = std::min<std::int64_t>(h.modalityLut[std::size_t(i)], top);
                    lut[w] = padWord(w, static_cast<float>(pf.invert ? top - out : out));
                }
            } else if (!h.hasModalityLut &&
                       (lut.empty() || slope != lutSlope || intercept != lutIntercept)) {
                lut.resize(std::size_t(1) << h.bitsAllocated);
                padChanged.assign(lut.size(), 0);
                for (std::size_t w = 0; w < lut.size(); ++w)
                    lut[w] = padWord(w, static_cast<float>(double(storedValue(std::uint32_t(w), pf)) * slope + intercept));
                lutSlope = slope;
                lutIntercept = intercept;
            }
            auto convert = [&](const auto* src) {
                if (!padding.on) {
                    for (std::uint64_t i = 0; i < frameVox; ++i) dst[i] = lut[src[i]];
                    return;
                }
                std::int64_t changed = 0;
                for (std::uint64_t i = 0; i < frameVox; ++i) {
                    dst[i] = lut[src[i]];
                    changed += padChanged[src[i]];
                }
                counts.padded += changed;
            };
            if (h.bitsAllocated == 8) convert(static_cast<const Uint8*>(raw) + first);
            else convert(static_cast<const Uint16*>(raw) + first);
        } else {
            static_assert(std::endian::native == std::endian::little, "32-bit pixel words assume a little endian host");
            const auto* src = static_cast<const Uint16*>(raw) + 2 * first;
            for (std::uint64_t i = 0; i < frameVox; ++i) {
                std::uint32_t w;
                std::memcpy(&w, src + 2 * i, 4);
                const float value = static_cast<float>(double(storedValue(w, pf)) * slope + intercept);
                const bool pad = padding(storedValue(w, uninverted));
                counts.padded += pad && value != padding.fill;
                dst[i] = pad ? padding.fill : value;
            }
        }
    }
    return counts;
}

/** Bilinear sample of slice `s` (cols x rows) at (fx, fy); `fill` outside it. */
inline float sample(const float* s, std::int64_t cols, std::int64_t rows, double fx, double fy,
                    float fill) {
    constexpr double eps = 1e-6;
    if (fx < -eps || fy < -eps || fx > double(cols - 1) + eps || fy > double(rows - 1) + eps) return fill;
    fx = std::clamp(fx, 0.0, double(cols - 1));
    fy = std::clamp(fy, 0.0, double(rows - 1));
    const std::int64_t x0 = std::min<std::int64_t>(std::int64_t(fx), std::max<std::int64_t>(cols - 2, 0));
    const std::int64_t y0 = std::min<std::int64_t>(std::int64_t(fy), std::max<std::int64_t>(rows - 2, 0));
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
        std::size_t k = std::size_t(std::upper_bound(plan.t.begin(), plan.t.end(), z) - plan.t.begin());
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
            for (std::int64_t i = 0; i < nx * ny; ++i) dst[i] += wf * (upper[std::size_t(i)] - dst[i]);
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

} // namespace

DicomVolume loadDicomSeries(const DicomSeriesInfo& series, const ProgressFn& progress,
                            const CancelToken* cancel) {
    initDcmtk();
    const std::string name = series.key.empty() ? series.seriesUid : series.key;
    const std::string source =
        series.files.size() == 1
            ? series.files[0].string()
            : "DICOM series " + (name.empty() ? std::string("(unnamed)") : name) +
                  (series.files.empty() ? std::string() : " in " + series.files[0].parent_path().string());
    if (series.files.empty()) throw DicomError(source + ": no files");
    if (!series.frames.empty() && series.frames.size() != series.files.size())
        throw DicomError(source + ": the frame selection lists " + std::to_string(series.frames.size()) +
                         " files, the series " + std::to_string(series.files.size()));
    const std::size_t nFiles = series.files.size();

    std::vector<DicomHeader> hs(nFiles);
    std::vector<std::unique_ptr<DcmFileFormat>> ffs(nFiles);
    ThreadPool pool;
    {
        Progress prog(progress, "reading DICOM headers", 0.0, 0.1, std::int64_t(nFiles));
        runParallel(pool, std::int64_t(nFiles), 4, [&](std::int64_t i) {
            checkCancel(cancel);
            const auto k = static_cast<std::size_t>(i);
            hs[k] = readHeader(series.files[k], &ffs[k]);
            if (const std::string why = unsupportedReason(hs[k]); !why.empty()) fail(series.files[k], why);
            prog.step();
        });
    }
    const std::int64_t cols = hs[0].cols, rows = hs[0].rows;
    for (const DicomHeader& h : hs)
        if (h.cols != cols || h.rows != rows)
            throw DicomError(source + ": mixed image sizes: " + hs[0].path.string() + " is " +
                             std::to_string(cols) + " x " + std::to_string(rows) + ", " +
                             h.path.string() + " is " + std::to_string(h.cols) + " x " +
                             std::to_string(h.rows) + " (a scan puts them in separate series)");

    // The frames that make up the series, and their geometry.
    std::vector<PlanSlice> slices;
    std::vector<FrameRef> refs;
    for (std::size_t i = 0; i < nFiles; ++i) {
        const DicomHeader& h = hs[i];
        std::vector<std::int32_t> sel;
        if (!series.frames.empty() && !series.frames[i].empty()) sel = series.frames[i];
        else
            for (std::int32_t f = 0; f < std::int32_t(h.frames); ++f) sel.push_back(f);
        for (std::int32_t f : sel) {
            if (f < 0 || f >= h.frames)
                throw DicomError(source + ": " + h.path.string() + " has " + std::to_string(h.frames) +
                                 " frames, frame " + std::to_string(f + 1) + " was asked for");
            slices.push_back({&h.frameInfo[static_cast<std::size_t>(f)], sliceLabel(h, f), h.frames > 1,
                              h.gantryTilt, int(i)});
            refs.push_back({int(i), f});
        }
    }
    validate({cols, rows, std::int64_t(slices.size())}, {1, 1, 1}, source);
    GeometryPlan plan = planGeometry(slices, cols, rows, source);
    validate(plan.dims, plan.spacing, source);

    std::vector<std::string> warnings;
    for (const std::string& w : series.warnings)
        if (series.loadable() || w.find(series.unloadableReason) == std::string::npos)
            warnings.push_back(w);
    auto warn = [&](const std::string& w) {
        if (std::find(warnings.begin(), warnings.end(), w) == warnings.end()) warnings.push_back(w);
    };
    {
        std::set<std::string> seen;
        for (const DicomHeader& h : hs)
            for (const auto& p : h.problems)
                if (seen.insert(p).second) warn(h.path.filename().string() + ": " + p);
    }
    for (const auto& w : plan.warnings) warn(w);

    // Units: Hounsfield for CT with a rescale (or RescaleType HU), else intensity.
    bool isCt = false, allRescale = true, anyRescale = false, rescaleTypeHu = true;
    std::string otherRescaleType;
    for (std::size_t s = 0; s < slices.size(); ++s) {
        const DicomHeader& h = hs[static_cast<std::size_t>(refs[s].file)];
        isCt = isCt || h.modality == "CT";
        allRescale = allRescale && slices[s].info->hasRescale;
        anyRescale = anyRescale || slices[s].info->hasRescale;
        rescaleTypeHu = rescaleTypeHu && h.rescaleType == "HU";
        if (!h.rescaleType.empty() && h.rescaleType != "HU") otherRescaleType = h.rescaleType;
    }
    if (anyRescale && !allRescale) {
        for (std::size_t s = 0; s < slices.size(); ++s)
            if (!slices[s].info->hasRescale)
                throw DicomError(source + ": RescaleSlope/RescaleIntercept (0028,1053/1052) missing in " +
                                 slices[s].label + " but present in other slices: their values "
                                 "would not be comparable");
    }
    // A CT rescale gives Hounsfield units unless RescaleType says otherwise (it is only written
    // when the values are not HU; 'US' means unspecified).
    bool anyLut = false, allLutHu = true;
    for (const DicomHeader& h : hs) {
        anyLut = anyLut || h.hasModalityLut;
        allLutHu = allLutHu && h.hasModalityLut && h.lutType == "HU";
    }
    if (anyLut) {
        for (const DicomHeader& h : hs)
            if (!h.hasModalityLut)
                throw DicomError(source + ": Modality LUT Sequence (0028,3000) missing in " +
                                 h.path.string() + " but present in other files of the series");
        allRescale = true; // the LUT is the modality transform
        anyRescale = true;
        otherRescaleType = allLutHu ? std::string() : "LUT";
        rescaleTypeHu = allLutHu;
        warn("Modality LUT Sequence (0028,3000) applied (ModalityLUTType '" + hs[0].lutType + "')");
    }
    const bool hu = allRescale && ((isCt && otherRescaleType.empty()) || rescaleTypeHu);
    if (isCt && allRescale && !otherRescaleType.empty() && !anyLut)
        warn("RescaleType (0028,1054) '" + otherRescaleType + "' on a CT image: the rescaled "
             "values are not declared Hounsfield units and are loaded as intensity");
    if (isCt && !allRescale)
        warn("CT without RescaleSlope/RescaleIntercept: values are stored pixel values, not "
             "Hounsfield units");
    bool anyMono1 = false;
    for (const DicomHeader& h : hs) anyMono1 = anyMono1 || h.photometric == "MONOCHROME1";
    if (anyMono1) {
        if (hu)
            warn("MONOCHROME1: Hounsfield units kept as they are (MONOCHROME1 only says how to "
                 "display them: low values white)");
        else
            warn("MONOCHROME1: stored values inverted (v -> min + max of the BitsStored range - v, "
                 "before rescale) so that larger values are brighter");
    }

    // Decode into the stack of sorted slices (the volume itself when no resampling is needed).
    const std::int64_t sliceVox = cols * rows;
    const std::size_t nSlices = slices.size();
    std::vector<float> stack(static_cast<std::size_t>(sliceVox) * nSlices);
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
            const DecodeCounts c = decodeFile(hs[k], *ffs[k], perFile[k], stack.data(), sliceVox, invert, hu);
            nonFinite += c.nonFinite;
            padded += c.padded;
            if (c.j2kSignReinterpreted) j2kSign = true;
            if (c.j2kLossyUndeclared) j2kLossy = true;
            ffs[k].reset(); // frees the file's pixel data at once
            prog.step();
        });
    }
    if (nonFinite > 0)
        warn(std::to_string(nonFinite.load()) + " non-finite float pixel values (NaN/Inf) set to 0");
    if (j2kSign)
        warn("JPEG 2000 codestream signedness differs from PixelRepresentation (0028,0103) " +
             std::to_string(hs[0].pixelRepresentation) + ": the samples' BitsStored bits are read as the header declares (" +
             (hs[0].pixelRepresentation == 1 ? "two's complement" : "unsigned") + ")");
    if (j2kLossy)
        warn("lossy JPEG 2000 (irreversible 9/7 wavelet) although LossyImageCompression (0028,2110) does not "
             "say so: the values are approximations of the original");
    if (padded > 0) {
        const auto h = std::find_if(hs.begin(), hs.end(), [](const DicomHeader& x) { return x.paddingValue.has_value(); });
        std::string what = "PixelPaddingValue (0028,0120) " + std::to_string(*h->paddingValue);
        if (h->paddingLimit) what += " to PixelPaddingRangeLimit (0028,0121) " + std::to_string(*h->paddingLimit);
        char share[32];
        std::snprintf(share, sizeof share, "%.1f", 100.0 * double(padded.load()) / double(stack.size()));
        warn(what + ": " + std::to_string(padded.load()) + " padding pixels (" + share +
             " %, no measurement there) set to " + (hu ? "air (-1000 HU)" : "0 (no signal)"));
    }

    DicomVolume result;
    Volume& vol = result.volume;
    vol.dims = plan.dims;
    vol.spacing = plan.spacing;
    vol.origin = plan.origin;
    vol.direction = plan.direction;
    vol.units = hu ? ValueUnits::HounsfieldUnits : ValueUnits::Intensity;
    const DicomHeader& h0 = hs[0];
    vol.name = !h0.description.empty() ? h0.description
               : !h0.modality.empty()  ? h0.modality + " series" + (h0.seriesNumber.empty() ? "" : " " + h0.seriesNumber)
                                       : std::string("DICOM series");
    if (!plan.resample) {
        vol.voxels = std::move(stack);
    } else {
        float fill = std::numeric_limits<float>::infinity();
        for (float v : stack) fill = std::min(fill, v);
        vol.voxels.resize(static_cast<std::size_t>(vol.voxelCount()));
        Progress prog(progress, "resampling DICOM slices", 0.8, 1.0, plan.dims[2]);
        resampleStack(stack, cols, rows, plan, fill, vol.voxels, pool, prog, cancel);
    }
    if (progress) progress(1.0, "DICOM series loaded");
    result.warnings = std::move(warnings);
    return result;
}

DicomVolume loadDicomFolder(const std::filesystem::path& folder, const std::string& key) {
    InputSource source;
    source.kind = InputKind::DicomFolder;
    source.path = folder;
    OpenOptions options;
    options.seriesKey = key;
    OpenedStudy study = openStudy(source, options);
    return {std::move(study.volume), std::move(study.warnings)};
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
        v.warnings.insert(v.warnings.begin(),
                          file.string() + " holds " + std::to_string(series.size()) +
                              " volumes; loaded the first (" + std::to_string(series[0].frameCount) +
                              " frames); scan the file to choose another");
    return v;
}

} // namespace fvr::core
