// DICOM headers through DCMTK: codec registration, reading a file's attributes without its pixel
// values (classic and enhanced multi-frame), and the checks that decide whether its pixel format
// can be loaded.
#include "dicom_charset.h"
#include "dicom_internal.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <sstream>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dccodec.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcmetinf.h>
#include <dcmtk/dcmdata/dcpixel.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/dcmjpeg/djdecode.h>
#include <dcmtk/dcmjpls/djdecode.h>
#include <dcmtk/oflog/oflog.h>

namespace fvr::core::dicom_detail {

void initDcmtk() {
    static std::once_flag once;
    std::call_once(once, [] {
        // DCMTK logs parser and codec complaints on the console; every problem we act on is
        // reported through DicomError or a warning instead. FVR_DCMTK_LOG=1 keeps DCMTK's log.
        if (!std::getenv("FVR_DCMTK_LOG"))
            OFLog::getLogger("dcmtk").setLogLevel(OFLogger::OFF_LOG_LEVEL);
        DJDecoderRegistration::registerCodecs(); // JPEG baseline, extended, lossless
        DJLSDecoderRegistration::registerCodecs(); // JPEG-LS lossless and near-lossless
        DcmRLEDecoderRegistration::registerCodecs();
        // Deflated Explicit VR Little Endian is inflated by dcmdata's input stream (zlib).
    });
}

void fail(const fs::path& file, const std::string& detail) {
    throw DicomError(file.string() + ": " + detail);
}

std::string sopClassName(const std::string& uid) {
    const char* name = uid.empty() ? nullptr : dcmFindNameOfUID(uid.c_str(), nullptr);
    if (!name) return {};
    // DCMTK spells the names in CamelCase ("RTStructureSetStorage"): words start at a capital
    // after a small letter or digit, and at the last capital of an acronym ("RT|Structure").
    const std::string s(name);
    const auto u8 = [](char c) { return static_cast<unsigned char>(c); };
    std::string out;
    for (std::size_t i = 0; i < s.size(); ++i) {
        const auto up = [&](std::size_t k) { return k < s.size() && std::isupper(u8(s[k])); };
        const auto low = [&](std::size_t k) { return k < s.size() && std::islower(u8(s[k])); };
        if (i > 0 && up(i) &&
            (low(i - 1) || std::isdigit(u8(s[i - 1])) || (up(i - 1) && low(i + 1))))
            out += ' ';
        out += s[i];
    }
    return out;
}

std::string describeSopClass(const std::string& uid) {
    if (uid.empty()) return "a DICOM object of unknown SOP class";
    const std::string name = sopClassName(uid);
    return name.empty() ? "SOP class " + uid : name + " (" + uid + ")";
}

std::string fmt(double v, int precision) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", precision, v);
    return buf;
}

namespace {

std::string trim(const OFString& s) {
    std::string r(s.c_str(), s.length());
    // Padding: spaces, and NULs that some writers use instead (OsiriX's "MONOCHROME2\0").
    static const std::string pad(" \t\r\n\0", 5);
    const auto b = r.find_first_not_of(pad);
    if (b == std::string::npos) return {};
    const auto e = r.find_last_not_of(pad);
    // Control bytes (a malformed file) are replaced so that messages stay printable.
    std::string out = r.substr(b, e - b + 1);
    for (char& c : out)
        if (static_cast<unsigned char>(c) < 0x20) c = '?';
    return out;
}

std::string getString(DcmItem* item, const DcmTagKey& tag) {
    if (!item) return {};
    OFString s;
    if (item->findAndGetOFStringArray(tag, s).good()) return trim(s);
    return {};
}

/** Reads exactly n finite numbers of a DS/FD/IS element; false if absent, short or invalid. */
bool getDoubles(DcmItem* item, const DcmTagKey& tag, double* out, int n) {
    if (!item) return false;
    for (int i = 0; i < n; ++i) {
        Float64 v = 0;
        if (item->findAndGetFloat64(tag, v, static_cast<unsigned long>(i)).bad() ||
            !std::isfinite(v))
            return false;
        out[i] = v;
    }
    return true;
}

/** True when the element is present (with any value, possibly malformed). */
bool present(DcmItem* item, const DcmTagKey& tag) { return item && item->tagExistsWithValue(tag); }

DcmItem* firstItem(DcmItem* item, const DcmTagKey& seqTag) {
    if (!item) return nullptr;
    DcmItem* sub = nullptr;
    if (item->findAndGetSequenceItem(seqTag, sub, 0).good()) return sub;
    return nullptr;
}

/** Position, orientation, spacing and rescale found directly in `item` (top level of a classic
 *  image, or one functional group item of an enhanced one) override those in `fi`. */
void readGeometry(DcmItem* item, FrameInfo& fi, std::vector<std::string>& problems) {
    double v[6];
    if (present(item, DCM_ImagePositionPatient)) {
        if (getDoubles(item, DCM_ImagePositionPatient, v, 3)) {
            fi.hasPosition = true;
            fi.position = {v[0], v[1], v[2]};
        } else {
            problems.push_back("ImagePositionPatient (0020,0032) is not 3 numbers: '" +
                               getString(item, DCM_ImagePositionPatient) + "'");
        }
    }
    if (present(item, DCM_ImageOrientationPatient)) {
        if (getDoubles(item, DCM_ImageOrientationPatient, v, 6)) {
            fi.hasOrientation = true;
            std::copy(v, v + 6, fi.orientation.begin());
        } else {
            problems.push_back("ImageOrientationPatient (0020,0037) is not 6 numbers: '" +
                               getString(item, DCM_ImageOrientationPatient) + "'");
        }
    }
    if (present(item, DCM_PixelSpacing)) {
        if (getDoubles(item, DCM_PixelSpacing, v, 2) && v[0] > 0 && v[1] > 0) {
            fi.hasPixelSpacing = true;
            fi.rowSpacing = v[0];
            fi.colSpacing = v[1];
        } else {
            problems.push_back("PixelSpacing (0028,0030) is not 2 positive numbers: '" +
                               getString(item, DCM_PixelSpacing) + "'");
        }
    }
    if (getDoubles(item, DCM_SliceThickness, v, 1) && v[0] > 0) fi.sliceThickness = v[0];
    if (getDoubles(item, DCM_SpacingBetweenSlices, v, 1) && v[0] > 0)
        fi.spacingBetweenSlices = v[0];
    const bool hasSlope = present(item, DCM_RescaleSlope);
    const bool hasIntercept = present(item, DCM_RescaleIntercept);
    if (hasSlope || hasIntercept) {
        fi.hasRescale = true;
        if (hasSlope) {
            if (getDoubles(item, DCM_RescaleSlope, v, 1))
                fi.slope = v[0];
            else
                fi.slope = NAN; // reported by unsupportedReason
        }
        if (hasIntercept) {
            if (getDoubles(item, DCM_RescaleIntercept, v, 1))
                fi.intercept = v[0];
            else
                fi.intercept = NAN;
        }
    }
}

/** One functional groups item (shared or per frame) of an enhanced multi-frame image. */
void readFunctionalGroups(DcmItem* fg, FrameInfo& fi, std::string& rescaleType,
                          std::vector<std::string>& problems) {
    if (!fg) return;
    if (DcmItem* it = firstItem(fg, DCM_PixelMeasuresSequence)) readGeometry(it, fi, problems);
    if (DcmItem* it = firstItem(fg, DCM_PlanePositionSequence)) readGeometry(it, fi, problems);
    if (DcmItem* it = firstItem(fg, DCM_PlaneOrientationSequence)) readGeometry(it, fi, problems);
    if (DcmItem* it = firstItem(fg, DCM_PixelValueTransformationSequence)) {
        readGeometry(it, fi, problems);
        if (auto t = getString(it, DCM_RescaleType); !t.empty()) rescaleType = t;
    }
    if (DcmItem* it = firstItem(fg, DCM_FrameContentSequence)) {
        if (auto s = getString(it, DCM_StackID); !s.empty()) fi.stack = s;
        if (auto s = getString(it, DCM_TemporalPositionIndex); !s.empty()) fi.temporal = s;
        if (DcmElement* e = nullptr;
            it->findAndGetElement(DCM_DimensionIndexValues, e).good() && e) {
            fi.dimensionIndex.clear();
            const unsigned long vm = std::min<unsigned long>(e->getVM(), 16);
            for (unsigned long i = 0; i < vm; ++i) {
                Uint32 x = 0;
                if (e->getUint32(x, i).good())
                    fi.dimensionIndex.push_back(static_cast<std::int32_t>(x));
            }
        }
    }
    if (DcmItem* it = firstItem(fg, DCM_MREchoSequence))
        if (auto s = getString(it, DCM_EffectiveEchoTime); !s.empty()) fi.echo = s;
    for (const DcmTagKey& seq : {DCM_MRImageFrameTypeSequence, DCM_CTImageFrameTypeSequence})
        if (DcmItem* it = firstItem(fg, seq))
            if (auto s = getString(it, DCM_FrameType); !s.empty()) fi.imageType = s;
    if (DcmItem* it = firstItem(fg, DCM_CardiacSynchronizationSequence))
        if (auto s = getString(it, DCM_NominalCardiacTriggerDelayTime); !s.empty())
            fi.triggerTime = s;
    if (DcmItem* it = firstItem(fg, DCM_MRDiffusionSequence))
        if (auto s = getString(it, DCM_DiffusionBValue); !s.empty()) fi.diffusion = s;
}

/** A pixel padding attribute (US or SS, VR per PixelRepresentation; UL/SL for 32-bit data) as a
 *  stored value: signed when the pixels are, whatever VR the file used. */
std::optional<std::int64_t> readPaddingValue(DcmItem* ds, const DcmTagKey& tag, bool signedPixels,
                                             std::vector<std::string>& problems) {
    DcmElement* e = nullptr;
    if (ds->findAndGetElement(tag, e).bad() || !e || e->getLength() == 0) return std::nullopt;
    Uint16 u16 = 0;
    Sint16 s16 = 0;
    Uint32 u32 = 0;
    Sint32 s32 = 0;
    if (e->getUint16(u16).good())
        return signedPixels ? std::int64_t(static_cast<Sint16>(u16)) : std::int64_t(u16);
    if (e->getSint16(s16).good())
        return signedPixels ? std::int64_t(s16) : std::int64_t(static_cast<Uint16>(s16));
    if (e->getUint32(u32).good())
        return signedPixels ? std::int64_t(static_cast<Sint32>(u32)) : std::int64_t(u32);
    if (e->getSint32(s32).good())
        return signedPixels ? std::int64_t(s32) : std::int64_t(static_cast<Uint32>(s32));
    problems.push_back(std::string(DcmTag(tag).getTagName()) + " " + tag.toString().c_str() +
                       ": not a US/SS/UL/SL number: ignored");
    return std::nullopt;
}

/** LUTDescriptor (entries, first mapped value, bits) and LUTData of a Modality LUT item. */
void readModalityLut(DcmItem* lut, DicomHeader& h) {
    DcmElement* desc = nullptr;
    if (lut->findAndGetElement(DCM_LUTDescriptor, desc).bad() || !desc || desc->getVM() != 3) {
        h.modalityLutProblem =
            "Modality LUT Sequence (0028,3000): LUTDescriptor (0028,3002) is not 3 numbers";
        return;
    }
    const bool signedDesc = desc->getTag().getEVR() == EVR_SS;
    Uint16 u[3] = {0, 0, 0};
    for (unsigned long i = 0; i < 3; ++i) {
        if (signedDesc) {
            Sint16 v = 0;
            desc->getSint16(v, i);
            u[i] = static_cast<Uint16>(v);
        } else {
            desc->getUint16(u[i], i);
        }
    }
    const std::int64_t entries = u[0] == 0 ? 65536 : u[0];
    // The first mapped value is signed when the pixels are (whatever the element's VR).
    Uint16 pr = 0;
    h.lutFirst = (signedDesc || (h.pixelRepresentation == 1) ||
                  (lut->findAndGetUint16(DCM_PixelRepresentation, pr).good() && pr == 1))
                     ? std::int64_t(static_cast<Sint16>(u[1]))
                     : std::int64_t(u[1]);
    h.lutBits = u[2];
    h.lutType = getString(lut, DCM_ModalityLUTType);
    if (h.lutBits < 1 || h.lutBits > 16) {
        h.modalityLutProblem = "Modality LUT Sequence (0028,3000): LUTDescriptor bits per entry " +
                               std::to_string(h.lutBits) + ", expected 1..16";
        return;
    }
    DcmElement* data = nullptr;
    Uint16* words = nullptr;
    if (lut->findAndGetElement(DCM_LUTData, data).bad() || !data ||
        data->getUint16Array(words).bad() || !words ||
        std::int64_t(data->getLength() / 2) < entries) {
        h.modalityLutProblem =
            "Modality LUT Sequence (0028,3000): LUTData (0028,3006) holds fewer than the " +
            std::to_string(entries) + " entries of its LUTDescriptor";
        return;
    }
    h.modalityLut.assign(words, words + entries);
}

/** What the first bytes of a file say about it. */
struct FileStart {
    bool preamble = false; ///< "DICM" at byte 128
    bool gzip = false; ///< the gzip magic bytes 1f 8b
    bool bareDataset = false; ///< no preamble, but it starts like a data set (group 0, 2, 4 or 8)
};

FileStart readFileStart(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    unsigned char b[132] = {};
    in.read(reinterpret_cast<char*>(b), sizeof b);
    const auto got = in.gcount();
    FileStart s;
    s.preamble = got == 132 && b[128] == 'D' && b[129] == 'I' && b[130] == 'C' && b[131] == 'M';
    s.gzip = got >= 2 && b[0] == 0x1f && b[1] == 0x8b;
    const int le = b[0] | (b[1] << 8), be = (b[0] << 8) | b[1];
    const auto groupStart = [](int g) { return g == 0 || g == 2 || g == 4 || g == 8; };
    s.bareDataset = got >= 4 && (groupStart(le) || groupStart(be));
    return s;
}

/** Why DCMTK could not parse the file, in words, DCMTK's status in parentheses. */
[[noreturn]] void failUnparsed(const fs::path& path, const FileStart& start, const OFCondition& c) {
    const std::string dcmtk = std::string("DCMTK: ") + c.text();
    if (start.gzip && !start.preamble)
        throw NotDicomError(path.string() +
                            ": not a DICOM file (gzip-compressed data: decompress it first)");
    if (!start.preamble && !start.bareDataset)
        throw NotDicomError(path.string() +
                            ": not a DICOM file (no DICM preamble, and it does not parse as "
                            "DICOM without one; " +
                            dcmtk + ")");
    const bool premature = c == EC_StreamNotifyClient || c == EC_PrematureSequDelimitationItem ||
                           c == EC_SequDelimitationItemMissing ||
                           c == EC_ItemDelimitationItemMissing;
    fail(path, std::string("not a readable DICOM file: ") +
                   (premature ? "it ends in the middle of an element (truncated file?; "
                              : "its data set is corrupt (") +
                   dcmtk + ")");
}

/** Checks the file and parses it with DCMTK (values above 4 KiB stay on disk). */
std::unique_ptr<DcmFileFormat> parseFile(const fs::path& path, std::uintmax_t& fileSize) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) fail(path, "not a regular file");
    fileSize = fs::file_size(path, ec);
    if (ec) fail(path, "cannot read: " + ec.message());
    if (fileSize < 16)
        throw NotDicomError(path.string() + ": not a DICOM file (" + std::to_string(fileSize) +
                            " bytes)");

    auto ff = std::make_unique<DcmFileFormat>();
    // Values above 4 KiB (pixel data, large private blocks) stay on disk until asked for.
    const OFCondition c =
        ff->loadFile(OFFilename(path.c_str()), EXS_Unknown, EGL_noChange, 4096, ERM_autoDetect);
    if (c.bad()) failUnparsed(path, readFileStart(path), c);
    if (!ff->getDataset()) fail(path, "not a readable DICOM file: no data set");
    return ff;
}

/** SOP class and instance, and which pixel data element the image has (none: not an image). */
void readSopAndPixelKind(DcmMetaInfo* meta, DcmDataset* ds, DicomHeader& h) {
    const fs::path& path = h.path;
    const std::string mediaClass = getString(meta, DCM_MediaStorageSOPClassUID);
    if (mediaClass == UID_MediaStorageDirectoryStorage || present(ds, DCM_DirectoryRecordSequence))
        fail(path, "a DICOMDIR (media directory), not an image");

    h.sopClassUid = getString(ds, DCM_SOPClassUID);
    if (h.sopClassUid.empty()) h.sopClassUid = mediaClass;
    h.sopInstanceUid = getString(ds, DCM_SOPInstanceUID);

    h.hasPixelData = present(ds, DCM_PixelData);
    h.floatPixelData = !h.hasPixelData && present(ds, DCM_FloatPixelData);
    h.doublePixelData =
        !h.hasPixelData && !h.floatPixelData && present(ds, DCM_DoubleFloatPixelData);
    if (!h.hasPixelData && !h.floatPixelData && !h.doublePixelData) {
        // A parse of a non-DICOM file without preamble can "succeed" with garbage elements: tell
        // those apart from real DICOM objects without images.
        if (h.sopClassUid.empty() && getString(meta, DCM_TransferSyntaxUID).empty())
            throw NotDicomError(path.string() +
                                ": not a DICOM file (no meta header, no SOP class, no pixel "
                                "data)");
        const std::string name = sopClassName(h.sopClassUid);
        throw NoImageError(path.string() + ": " + describeSopClass(h.sopClassUid) +
                               " has no image to render (no Pixel Data (7FE0,0010))",
                           !name.empty()           ? name
                           : h.sopClassUid.empty() ? std::string("unknown SOP class")
                                                   : h.sopClassUid);
    }
}

/** Transfer syntax: as written in the meta header, and as DCMTK read it; declared lossy
 *  compression. */
void readTransferSyntax(DcmMetaInfo* meta, DcmDataset* ds, DicomHeader& h) {
    const std::string metaXfer = getString(meta, DCM_TransferSyntaxUID);
    const E_TransferSyntax xfer = ds->getOriginalXfer();
    const DcmXfer xf(xfer);
    h.xfer = static_cast<int>(xfer);
    h.xferUid = xf.getXferID();
    h.xferName = xf.getXferName();
    if (!metaXfer.empty() && DcmXfer(metaXfer.c_str()).getXfer() == EXS_Unknown)
        fail(h.path, "transfer syntax " + metaXfer +
                         " (TransferSyntaxUID (0002,0010)) is not "
                         "supported (unknown to this DCMTK build)");
    h.encapsulated = xf.isEncapsulated();
    h.bigEndian = xf.isBigEndian();
    if (h.encapsulated)
        h.decodable =
            h.decodable &&
            (isJpeg2000(xfer) || DcmCodecList::canChangeCoding(xfer, EXS_LittleEndianExplicit));
    h.lossyDeclared = getString(ds, DCM_LossyImageCompression) == "01";
    if (h.lossyDeclared) {
        const std::string ratio = getString(ds, DCM_LossyImageCompressionRatio);
        const std::string method = getString(ds, DCM_LossyImageCompressionMethod);
        h.problems.push_back("lossy compressed image (LossyImageCompression (0028,2110) 01" +
                             (method.empty() ? std::string() : ", " + method) +
                             (ratio.empty() ? std::string() : ", ratio " + ratio) +
                             "): the values are approximations of the original");
    }
}

/** The text attributes the header keeps, copied from `ds` and converted to UTF-8 from its
 *  SpecificCharacterSet; what could not be converted (U+FFFD) is one of h.problems. */
std::unique_ptr<DcmItem> textInUtf8(DcmDataset* ds, DicomHeader& h) {
    auto text = std::make_unique<DcmItem>();
    for (const DcmTagKey& tag :
         {DCM_SpecificCharacterSet, DCM_PatientName, DCM_PatientID, DCM_StudyID,
          DCM_StudyDescription, DCM_AccessionNumber, DCM_ReferringPhysicianName, DCM_Manufacturer,
          DCM_SeriesDescription}) {
        DcmElement* element = nullptr;
        if (ds->findAndGetElement(tag, element).good() && element)
            text->insert(static_cast<DcmElement*>(element->clone()));
    }
    if (const std::string problem = convertTextToUtf8(*text); !problem.empty())
        h.problems.push_back(problem);
    return text;
}

/** Study, series and patient attributes (text in UTF-8), and the Modality LUT. */
void readSeriesAttributes(DcmDataset* ds, DicomHeader& h) {
    const std::unique_ptr<DcmItem> owned = textInUtf8(ds, h);
    DcmItem* text = owned.get();
    h.studyUid = getString(ds, DCM_StudyInstanceUID);
    h.seriesUid = getString(ds, DCM_SeriesInstanceUID);
    h.seriesNumber = getString(ds, DCM_SeriesNumber);
    h.patientName = getString(text, DCM_PatientName);
    h.patientId = getString(text, DCM_PatientID);
    h.studyDate = getString(ds, DCM_StudyDate);
    h.study = {getString(ds, DCM_StudyTime),
               getString(text, DCM_StudyID),
               getString(text, DCM_StudyDescription),
               getString(text, DCM_AccessionNumber),
               getString(text, DCM_ReferringPhysicianName),
               getString(ds, DCM_PatientSex),
               getString(ds, DCM_PatientBirthDate),
               getString(text, DCM_Manufacturer)};
    h.modality = getString(ds, DCM_Modality);
    h.description = getString(text, DCM_SeriesDescription);
    h.rescaleType = getString(ds, DCM_RescaleType);
    h.gantryTilt = getString(ds, DCM_GantryDetectorTilt);
    if (DcmItem* lut = firstItem(ds, DCM_ModalityLUTSequence)) {
        // An item without LUT data (seen in the wild) transforms nothing.
        h.hasModalityLut = present(lut, DCM_LUTData) || present(lut, DCM_LUTDescriptor);
        if (!h.hasModalityLut)
            h.problems.push_back("Modality LUT Sequence (0028,3000) has no LUT data: ignored");
        else
            readModalityLut(lut, h);
    }
}

/** Image pixel module: size, bits, representation, photometric, padding, frames. */
void readImagePixelModule(DcmDataset* ds, DicomHeader& h) {
    const fs::path& path = h.path;
    Uint16 u = 0;
    if (ds->findAndGetUint16(DCM_Rows, u).bad())
        fail(path, "not an image: Rows (0028,0010) missing");
    h.rows = u;
    if (ds->findAndGetUint16(DCM_Columns, u).bad())
        fail(path, "not an image: Columns (0028,0011) missing");
    h.cols = u;
    h.samplesPerPixel = ds->findAndGetUint16(DCM_SamplesPerPixel, u).good() ? u : 1;
    if (ds->findAndGetUint16(DCM_BitsAllocated, u).good())
        h.bitsAllocated = u;
    else if (h.floatPixelData)
        h.bitsAllocated = 32;
    else if (h.doublePixelData)
        h.bitsAllocated = 64;
    else
        fail(path, "BitsAllocated (0028,0100) missing");
    h.bitsStored = ds->findAndGetUint16(DCM_BitsStored, u).good() ? u : h.bitsAllocated;
    h.highBit = ds->findAndGetUint16(DCM_HighBit, u).good() ? u : h.bitsStored - 1;
    h.pixelRepresentation = ds->findAndGetUint16(DCM_PixelRepresentation, u).good() ? u : 0;
    h.photometric = getString(ds, DCM_PhotometricInterpretation);
    if (h.photometric.empty()) h.photometric = "MONOCHROME2";
    if (!h.floatPixelData && !h.doublePixelData) {
        h.paddingValue =
            readPaddingValue(ds, DCM_PixelPaddingValue, h.pixelRepresentation == 1, h.problems);
        if (h.paddingValue)
            h.paddingLimit = readPaddingValue(ds, DCM_PixelPaddingRangeLimit,
                                              h.pixelRepresentation == 1, h.problems);
    }

    if (present(ds, DCM_NumberOfFrames)) {
        Sint32 n = 0;
        if (ds->findAndGetSint32(DCM_NumberOfFrames, n).bad() || n < 1)
            fail(path, "NumberOfFrames (0028,0008): expected a number >= 1, found '" +
                           getString(ds, DCM_NumberOfFrames) + "'");
        h.frames = n;
    }
    if (h.frames > kMaxDimPerAxis)
        fail(path, "NumberOfFrames (0028,0008): expected at most " +
                       std::to_string(kMaxDimPerAxis) + ", found " + std::to_string(h.frames));
}

/** Pixel data size as stored (nothing is loaded here): fragments and their bytes when
 *  encapsulated, checked against the file size when not stream-compressed. */
void readPixelDataLength(DcmDataset* ds, std::uintmax_t fileSize, DicomHeader& h) {
    const fs::path& path = h.path;
    const E_TransferSyntax xfer = ds->getOriginalXfer();
    const DcmTagKey pixelTag = h.hasPixelData     ? DCM_PixelData
                               : h.floatPixelData ? DCM_FloatPixelData
                                                  : DCM_DoubleFloatPixelData;
    DcmElement* pe = nullptr;
    if (ds->findAndGetElement(pixelTag, pe).bad() || !pe)
        fail(path, "Pixel Data could not be read");
    if (h.encapsulated && h.hasPixelData) {
        auto* pd = dynamic_cast<DcmPixelData*>(pe);
        DcmPixelSequence* seq = nullptr;
        if (!pd || pd->getEncapsulatedRepresentation(xfer, nullptr, seq).bad() || !seq)
            fail(path, "Pixel Data (7FE0,0010): expected encapsulated fragments for " + h.xferName +
                           ", found none");
        const unsigned long items = seq->card();
        h.fragments = items > 0 ? static_cast<std::int64_t>(items) - 1 : 0; // item 0: offset table
        for (unsigned long i = 1; i < items; ++i) {
            DcmPixelItem* item = nullptr;
            if (seq->getItem(item, i).good() && item) h.pixelDataLength += item->getLengthField();
        }
    } else {
        h.pixelDataLength = pe->getLengthField();
        if (h.pixelDataLength == DCM_UndefinedLength)
            fail(path, "Pixel Data (7FE0,0010): undefined length (encapsulated) in " + h.xferName);
    }
    if (DcmXfer(xfer).getStreamCompression() == ESC_none && h.pixelDataLength > fileSize)
        fail(path, "Pixel Data (7FE0,0010): length " + std::to_string(h.pixelDataLength) +
                       " bytes exceeds the file size " + std::to_string(fileSize) +
                       " (truncated file?)");
}

/** The pixel data must be able to hold what the header describes: checked here, before any
 *  decoder or the loader allocates the image from the header's numbers. */
void checkPixelDataHoldsImage(const DicomHeader& h) {
    if (h.rows <= 0 || h.cols <= 0 || h.bitsAllocated <= 0) return;
    const fs::path& path = h.path;
    const std::uint64_t bytesPer = h.floatPixelData ? 4
                                   : h.doublePixelData
                                       ? 8
                                       : std::uint64_t(std::max(h.bitsAllocated, 8) / 8);
    // rows, cols <= 65535, frames <= 16384: no overflow.
    const std::uint64_t need =
        std::uint64_t(h.rows) * std::uint64_t(h.cols) * std::uint64_t(h.frames) * bytesPer;
    const std::string what = std::to_string(h.cols) + " x " + std::to_string(h.rows) + " x " +
                             std::to_string(h.frames) + " frames x " + std::to_string(bytesPer) +
                             " bytes = " + std::to_string(need) + " bytes";
    if (h.encapsulated) {
        if (h.fragments < h.frames)
            fail(path, "Pixel Data (7FE0,0010): NumberOfFrames is " + std::to_string(h.frames) +
                           " but the encapsulated data holds " + std::to_string(h.fragments) +
                           " fragments (each frame needs at least one)");
        // More than 1024:1 is not compression but a lying header (a decoder would allocate
        // the full size first); small images are let through whatever their ratio.
        const std::uint64_t limit =
            std::max<std::uint64_t>(256ull << 20, 1024ull * h.pixelDataLength);
        if (need > limit)
            fail(path, "Pixel Data (7FE0,0010): " + std::to_string(h.pixelDataLength) +
                           " compressed bytes cannot hold " + what +
                           " (more than 1024:1); refusing to decode");
    } else if (h.bitsAllocated >= 8 && h.pixelDataLength < need) {
        fail(path, "Pixel Data (7FE0,0010): expected " + what + ", found " +
                       std::to_string(h.pixelDataLength) + " (truncated file or wrong header)");
    }
}

/** Geometry: classic attributes at top level, then enhanced functional groups; one FrameInfo per
 *  frame. Each distinct problem is kept once in h.problems. */
void readFrames(DcmDataset* ds, DicomHeader& h) {
    std::vector<std::string> problems;
    FrameInfo base;
    readGeometry(ds, base, problems);
    base.echo = getString(ds, DCM_EchoNumbers);
    base.acquisition = getString(ds, DCM_AcquisitionNumber);
    base.temporal = getString(ds, DCM_TemporalPositionIdentifier);
    base.imageType = getString(ds, DCM_ImageType);
    base.triggerTime = getString(ds, DCM_TriggerTime);
    if (auto b = getString(ds, DCM_DiffusionBValue); !b.empty()) base.diffusion = b;

    DcmSequenceOfItems* perFrame = nullptr;
    DcmItem* shared = firstItem(ds, DCM_SharedFunctionalGroupsSequence);
    if (ds->findAndGetSequence(DCM_PerFrameFunctionalGroupsSequence, perFrame).bad())
        perFrame = nullptr;
    h.enhanced = shared || perFrame;
    if (h.enhanced) {
        readFunctionalGroups(shared, base, h.rescaleType, problems);
        const std::int64_t items = perFrame ? static_cast<std::int64_t>(perFrame->card()) : 0;
        if (perFrame && items != h.frames)
            fail(h.path, "PerFrameFunctionalGroupsSequence (5200,9230): expected " +
                             std::to_string(h.frames) + " items (NumberOfFrames), found " +
                             std::to_string(items));
        h.frameInfo.assign(static_cast<std::size_t>(h.frames), base);
        for (std::int64_t f = 0; f < items; ++f)
            readFunctionalGroups(perFrame->getItem(static_cast<unsigned long>(f)),
                                 h.frameInfo[static_cast<std::size_t>(f)], h.rescaleType, problems);
    } else {
        h.frameInfo.assign(static_cast<std::size_t>(h.frames), base);
        if (h.frames > 1) {
            // A classic multi-frame image (cine, NM...) has one position for the whole file: the
            // frames have none of their own. The first keeps the file's as its position.
            for (std::size_t f = 1; f < h.frameInfo.size(); ++f) h.frameInfo[f].hasPosition = false;
            h.frameInfo[0].fileLevelPosition = true;
        }
    }
    // Keep each distinct problem once (an enhanced file repeats them per frame).
    problems.insert(problems.end(), h.problems.begin(), h.problems.end());
    std::sort(problems.begin(), problems.end());
    problems.erase(std::unique(problems.begin(), problems.end()), problems.end());
    h.problems = std::move(problems);
}

} // namespace

DicomHeader readHeader(const fs::path& path, std::unique_ptr<DcmFileFormat>* keep) {
    initDcmtk();
    DicomHeader h;
    h.path = path;
    std::uintmax_t fileSize = 0;
    std::unique_ptr<DcmFileFormat> ff = parseFile(path, fileSize);
    DcmMetaInfo* meta = ff->getMetaInfo();
    DcmDataset* ds = ff->getDataset();
    readSopAndPixelKind(meta, ds, h);
    readTransferSyntax(meta, ds, h);
    readSeriesAttributes(ds, h);
    readImagePixelModule(ds, h);
    readPixelDataLength(ds, fileSize, h);
    checkPixelDataHoldsImage(h);
    readFrames(ds, h);
    if (keep) *keep = std::move(ff);
    return h;
}

std::string unsupportedReason(const DicomHeader& h) {
    if (!h.decodable)
        return h.xferName + " (" + h.xferUid + ") is not supported (no decoder in this build)";
    if (h.rows < 1 || h.cols < 1)
        return "Rows x Columns (0028,0010/0011): expected at least 1 x 1, found " +
               std::to_string(h.rows) + " x " + std::to_string(h.cols);
    if (h.samplesPerPixel != 1)
        return "colour images are not supported (SamplesPerPixel (0028,0002) " +
               std::to_string(h.samplesPerPixel) + ", PhotometricInterpretation " + h.photometric +
               ")";
    if (h.photometric != "MONOCHROME1" && h.photometric != "MONOCHROME2")
        return "PhotometricInterpretation (0028,0004) " + h.photometric +
               " is not supported (expected MONOCHROME1 or MONOCHROME2)";
    if (h.floatPixelData || h.doublePixelData) {
        if (h.bigEndian) return "Float Pixel Data in big endian files is not supported";
        return {};
    }
    if (h.bitsAllocated == 1)
        return "BitsAllocated (0028,0100) 1 (a bit-packed binary image, e.g. a segmentation) is "
               "not supported";
    if (h.bitsAllocated != 8 && h.bitsAllocated != 16 && h.bitsAllocated != 32)
        return "BitsAllocated (0028,0100): expected 8, 16 or 32, found " +
               std::to_string(h.bitsAllocated);
    if (h.bitsAllocated == 32 && h.bigEndian)
        return "32-bit pixels in a big endian file are not supported";
    if (h.bitsStored < 1 || h.bitsStored > h.bitsAllocated || h.highBit < h.bitsStored - 1 ||
        h.highBit >= h.bitsAllocated)
        return "BitsStored/HighBit (0028,0101/0102): expected 1 <= BitsStored <= BitsAllocated and "
               "BitsStored - 1 <= HighBit < BitsAllocated, found BitsAllocated " +
               std::to_string(h.bitsAllocated) + ", BitsStored " + std::to_string(h.bitsStored) +
               ", HighBit " + std::to_string(h.highBit);
    if (h.pixelRepresentation != 0 && h.pixelRepresentation != 1)
        return "PixelRepresentation (0028,0103): expected 0 or 1, found " +
               std::to_string(h.pixelRepresentation);
    if (h.hasModalityLut && !h.modalityLutProblem.empty()) return h.modalityLutProblem;
    if (h.hasModalityLut && h.bitsAllocated > 16)
        return "Modality LUT Sequence (0028,3000) with BitsAllocated " +
               std::to_string(h.bitsAllocated) + " is not supported";
    for (const FrameInfo& f : h.frameInfo) {
        if (!std::isfinite(f.slope) || f.slope == 0.0 || !std::isfinite(f.intercept))
            return "RescaleSlope/RescaleIntercept (0028,1053/1052): expected numbers with a "
                   "non-zero "
                   "slope, found slope " +
                   fmt(f.slope, 6) + ", intercept " + fmt(f.intercept, 6);
    }
    return {};
}

} // namespace fvr::core::dicom_detail
