// MetaImage (.mhd/.mha) loader: header, geometry, encoding, data files and reading.
#include <fvr/core/io/volume_io.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <fvr/core/errors.h>

#include "volume_io_internal.h"

namespace fvr::core {

using namespace detail;

// ------------------------------------------------------------------------------------------------
// MetaImage

namespace {

constexpr std::size_t kMaxHeaderLine = 64 * 1024;
constexpr std::uint64_t kMaxHeaderBytes = 1 << 20;

struct DataPart {
    fs::path file;
    std::uint64_t offset = 0; ///< where the (compressed) data starts
    std::uint64_t bytes = 0; ///< uncompressed data bytes
    bool compressed = false;
    std::uint64_t compressedBytes = 0; ///< bytes of compressed data available from offset
};

/** Formats a MetaImage slice-file pattern holding one printf integer conversion (%d, %i, %u,
 *  optionally with a zero flag and width, e.g. %03d). The pattern is interpreted here instead of
 *  being handed to printf, so that a malicious header cannot use other conversions. */
std::optional<std::string> formatPattern(std::string_view pattern, std::int64_t value) {
    std::string out;
    bool used = false;
    for (std::size_t i = 0; i < pattern.size(); ++i) {
        if (pattern[i] != '%') {
            out += pattern[i];
            continue;
        }
        if (i + 1 < pattern.size() && pattern[i + 1] == '%') {
            out += '%';
            ++i;
            continue;
        }
        if (used) return std::nullopt;
        used = true;
        std::size_t j = i + 1;
        bool zero = false;
        if (j < pattern.size() && pattern[j] == '0') {
            zero = true;
            ++j;
        }
        int width = 0;
        while (j < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[j]))) {
            width = width * 10 + (pattern[j] - '0');
            if (width > 32) return std::nullopt;
            ++j;
        }
        if (j >= pattern.size() || (pattern[j] != 'd' && pattern[j] != 'i' && pattern[j] != 'u'))
            return std::nullopt;
        std::string digits = std::to_string(value < 0 ? -value : value);
        std::string sign = value < 0 ? "-" : "";
        std::string number;
        const std::size_t len = sign.size() + digits.size();
        if (std::size_t(width) > len) {
            if (zero)
                number = sign + std::string(width - len, '0') + digits;
            else
                number = std::string(width - len, ' ') + sign + digits;
        } else {
            number = sign + digits;
        }
        out += number;
        i = j;
    }
    if (!used) return std::nullopt;
    return out;
}

/** The MetaImage header: "Key = Value" lines up to and including ElementDataFile. */
struct MetaHeader {
    std::map<std::string, std::string, std::less<>> fields;
    std::uint64_t fileSize = 0; ///< size of the header file
    std::uint64_t localOffset = 0; ///< the first byte after the ElementDataFile line

    const std::string* get(std::string_view key) const {
        const auto it = fields.find(key);
        return it == fields.end() ? nullptr : &it->second;
    }
    /** The first of `keys` present, with its value; {nullptr, nullptr} when none is. */
    std::pair<const char*, const std::string*> firstOf(
        std::initializer_list<const char*> keys) const {
        for (const char* k : keys)
            if (const std::string* v = get(k)) return {k, v};
        return {nullptr, nullptr};
    }
};

/** Reads the header lines (keys case-sensitive); leaves `sb` just after ElementDataFile. */
MetaHeader readMetaHeader(const fs::path& path, std::streambuf& sb, std::uint64_t fileSize) {
    MetaHeader header;
    header.fileSize = fileSize;
    std::string line;
    bool tooLong = false;
    bool sawDataFile = false;
    std::uint64_t consumed = 0;
    while (readHeaderLine(sb, line, kMaxHeaderLine, tooLong)) {
        consumed += line.size() + 1;
        if (tooLong || consumed > kMaxHeaderBytes)
            fail(path, "header",
                 "expected 'Key = Value' text lines ending with ElementDataFile within the first "
                 "1 MiB, found a line or header longer than that (not a MetaImage file?)");
        const std::string_view t = trimSpace(line);
        if (t.empty()) continue;
        const std::size_t eq = t.find('=');
        if ((eq == std::string_view::npos || trimSpace(t.substr(0, eq)).empty()) &&
            header.fields.empty())
            throw LoadError(path.string() +
                            ": not a MetaImage file (its header is 'Key = Value' lines such as "
                            "'NDims = 3'; the first line is " +
                            quoteValue(t) + ")");
        if (eq == std::string_view::npos || trimSpace(t.substr(0, eq)).empty())
            fail(path, "header", "expected 'Key = Value' lines, found " + quoteValue(t));
        const std::string key(trimSpace(t.substr(0, eq)));
        header.fields[key] = std::string(trimSpace(t.substr(eq + 1)));
        if (key == "ElementDataFile") {
            sawDataFile = true;
            break;
        }
    }
    if (!sawDataFile)
        fail(path, "ElementDataFile", "expected the key (the last header line), found none");
    const auto localPos = sb.pubseekoff(0, std::ios::cur, std::ios::in);
    header.localOffset = localPos < 0 ? 0 : std::uint64_t(std::streamoff(localPos));
    return header;
}

/** The grid of a MetaImage: NDims, DimSize, spacing, origin and axis directions. */
struct MetaGeometry {
    std::size_t ndims = 0;
    std::vector<std::int64_t> dimSize; ///< the NDims sizes as written
    Dims3 dims{1, 1, 1};
    std::int64_t voxelCount = 0;
    Vec3 spacing{1.0, 1.0, 1.0};
    Vec3 origin{0.0, 0.0, 0.0};
    glm::dmat3 direction = Volume{}.direction;
    bool directionStated = false; ///< TransformMatrix, Rotation or Orientation present
};

/** NDims and DimSize, checked against the per-axis and total voxel limits. */
void readMetaDims(const fs::path& path, const MetaHeader& header, MetaGeometry& g) {
    const std::string* ndimsText = header.get("NDims");
    if (!ndimsText) fail(path, "NDims", "expected 1, 2 or 3, found no NDims key");
    const auto nd = parseNumber<std::int64_t>(*ndimsText);
    if (!nd || *nd < 1 || *nd > 3)
        fail(path, "NDims", "expected 1, 2 or 3, found " + quoteValue(*ndimsText));
    g.ndims = std::size_t(*nd);

    const std::string* dimText = header.get("DimSize");
    if (!dimText)
        fail(path, "DimSize",
             "expected " + std::to_string(g.ndims) + " sizes, found no DimSize key");
    const auto dimSize = parseNumbers<std::int64_t>(*dimText, g.ndims);
    if (!dimSize)
        fail(path, "DimSize",
             "expected " + std::to_string(g.ndims) + " integers (NDims = " +
                 std::to_string(g.ndims) + "), found " + quoteValue(*dimText));
    for (const std::int64_t d : *dimSize) {
        if (d < 1 || d > kMaxDimPerAxis)
            fail(path, "DimSize",
                 "expected 1.." + std::to_string(kMaxDimPerAxis) + " voxels per axis, found " +
                     quoteValue(*dimText));
    }
    g.dimSize = *dimSize;
    for (std::size_t a = 0; a < g.ndims; ++a) g.dims[a] = g.dimSize[a];
    g.voxelCount = g.dims[0] * g.dims[1] * g.dims[2];
    if (g.voxelCount > kMaxVoxels)
        fail(path, "DimSize",
             "expected at most " + std::to_string(kMaxVoxels) + " voxels in total, found " +
                 dimsText(g.dimSize) + " = " + std::to_string(g.voxelCount));
}

/** ElementSpacing (fallback ElementSize) and Offset / Origin / Position. */
void readMetaSpacingOrigin(const fs::path& path, const MetaHeader& header, MetaGeometry& g) {
    const std::size_t ndims = g.ndims;
    if (const auto [key, text] = header.firstOf({"ElementSpacing", "ElementSize"}); text) {
        const auto sp = parseNumbers<double>(*text, ndims);
        bool ok = bool(sp);
        if (ok)
            for (const double s : *sp) ok = ok && s > 0.0;
        if (!ok)
            fail(path, key,
                 "expected " + std::to_string(ndims) + " finite numbers > 0 (mm), found " +
                     quoteValue(*text));
        for (std::size_t a = 0; a < ndims; ++a) g.spacing[a] = (*sp)[a];
    }
    if (const auto [key, text] = header.firstOf({"Offset", "Origin", "Position"}); text) {
        const auto o = parseNumbers<double>(*text, ndims);
        if (!o)
            fail(path, key,
                 "expected " + std::to_string(ndims) + " finite numbers, found " +
                     quoteValue(*text));
        for (std::size_t a = 0; a < ndims; ++a) g.origin[a] = (*o)[a];
    }
}

/** TransformMatrix / Rotation / Orientation: the first NDims numbers are index axis 0's
 *  direction, and so on (as ITK's MetaImageIO reads them). */
void readMetaDirection(const fs::path& path, const MetaHeader& header, MetaGeometry& g) {
    const std::size_t ndims = g.ndims;
    const auto [key, text] = header.firstOf({"TransformMatrix", "Rotation", "Orientation"});
    if (!text) return;
    g.directionStated = true;
    const auto m = parseNumbers<double>(*text, ndims * ndims);
    if (!m)
        fail(path, key,
             "expected " + std::to_string(ndims * ndims) + " finite numbers, found " +
                 quoteValue(*text));
    for (std::size_t a = 0; a < ndims; ++a) {
        Vec3 axis{0, 0, 0};
        for (std::size_t c = 0; c < ndims; ++c) axis[c] = (*m)[a * ndims + c];
        const auto unit = normalized(axis);
        if (!unit) fail(path, key, "expected non-zero axis vectors, found " + quoteValue(*text));
        g.direction[a] = *unit;
    }
    if (ndims == 2)
        g.direction[2] =
            normalized(glm::cross(g.direction[0], g.direction[1])).value_or(Vec3{0, 0, 1});
}

/** How the voxel bytes are stored: element type, byte order, compression, HeaderSize. */
struct MetaEncoding {
    ElementType type{};
    std::string typeText; ///< the ElementType value as written
    std::uint64_t es = 0; ///< bytes per element
    bool bigEndian = false;
    bool compressed = false;
    std::uint64_t compressedDataSize = 0; ///< 0: not given
    std::int64_t headerSize = 0; ///< -1: the data ends the file

    /** "int16 (MET_SHORT, 2 bytes)" */
    std::string typeDesc() const {
        return std::string(typeName(type)) + " (" + typeText + ", " + std::to_string(es) +
               " bytes)";
    }
};

/** ElementType and ElementNumberOfChannels (scalar volumes only). */
void readMetaElementType(const fs::path& path, const MetaHeader& header, MetaEncoding& e) {
    const std::string* typeText = header.get("ElementType");
    if (!typeText)
        fail(path, "ElementType", "expected MET_UCHAR, MET_SHORT, ..., found no ElementType key");
    try {
        e.type = parseElementType(*typeText);
    } catch (const SettingsError&) {
        fail(path, "ElementType",
             "expected MET_CHAR, MET_UCHAR, MET_SHORT, MET_USHORT, MET_INT, MET_UINT, MET_LONG, "
             "MET_ULONG, MET_LONG_LONG, MET_ULONG_LONG, MET_FLOAT or MET_DOUBLE, found " +
                 quoteValue(*typeText));
    }
    e.typeText = *typeText;
    e.es = elementSize(e.type);
    if (const std::string* v = header.get("ElementNumberOfChannels")) {
        const auto ch = parseNumber<std::int64_t>(*v);
        if (!ch || *ch != 1)
            fail(path, "ElementNumberOfChannels",
                 "expected 1 (scalar volumes only), found " + quoteValue(*v));
    }
}

/** Byte order, BinaryData, CompressedData, CompressedDataSize and HeaderSize. */
void readMetaStorage(const fs::path& path, const MetaHeader& header, MetaEncoding& e) {
    if (const auto [key, text] = header.firstOf({"ElementByteOrderMSB", "BinaryDataByteOrderMSB"});
        text) {
        const auto b = parseBool(*text);
        if (!b) fail(path, key, "expected True or False, found " + quoteValue(*text));
        e.bigEndian = *b;
    }
    if (const std::string* v = header.get("BinaryData")) {
        const auto b = parseBool(*v);
        if (!b || !*b)
            fail(path, "BinaryData",
                 "expected True (ASCII MetaImage data is not supported), found " + quoteValue(*v));
    }
    if (const std::string* v = header.get("CompressedData")) {
        const auto b = parseBool(*v);
        if (!b) fail(path, "CompressedData", "expected True or False, found " + quoteValue(*v));
        e.compressed = *b;
    }
    if (const std::string* v = header.get("CompressedDataSize"); v && e.compressed) {
        const auto c = parseNumber<std::int64_t>(*v);
        if (!c || *c < 1)
            fail(path, "CompressedDataSize", "expected a byte count > 0, found " + quoteValue(*v));
        e.compressedDataSize = std::uint64_t(*c);
    }
    if (const std::string* v = header.get("HeaderSize")) {
        const auto h = parseNumber<std::int64_t>(*v);
        if (!h || *h < -1)
            fail(path, "HeaderSize",
                 "expected -1 (data at the end of the file) or a byte count >= 0, found " +
                     quoteValue(*v));
        e.headerSize = *h;
    }
    if (e.compressed && e.headerSize == -1)
        fail(path, "HeaderSize", "expected a byte count >= 0 with CompressedData = True, found -1");
}

/** Works out which bytes of which files hold the voxels (ElementDataFile as LOCAL, LIST, a
 *  pattern or one file name) and checks that every file is long enough. */
struct MetaDataLocator {
    const fs::path& path;
    const MetaHeader& header;
    const MetaGeometry& geo;
    const MetaEncoding& enc;
    std::vector<DataPart> parts;

    std::uint64_t totalBytes() const { return std::uint64_t(geo.voxelCount) * enc.es; }

    /** One external data file (or one of a LIST/pattern) holding `bytes` data bytes. */
    void external(const fs::path& name, std::uint64_t bytes, const std::string& what) {
        const fs::path file = name.is_absolute() ? name : path.parent_path() / name;
        const std::uint64_t size = regularFileSize(file, path, "ElementDataFile");
        DataPart p;
        p.file = file;
        p.bytes = bytes;
        if (enc.compressed) {
            p.compressed = true;
            p.offset = std::uint64_t(enc.headerSize);
            if (size < p.offset)
                fail(path, "ElementDataFile",
                     "'" + file.string() +
                         "': expected at least HeaderSize = " + std::to_string(p.offset) +
                         " bytes, found " + std::to_string(size) + " bytes");
            p.compressedBytes = size - p.offset;
        } else if (enc.headerSize == -1) {
            if (size < bytes)
                fail(path, "ElementDataFile",
                     "'" + file.string() + "': expected at least " + std::to_string(bytes) +
                         " bytes (" + what + ", HeaderSize = -1), found " + std::to_string(size) +
                         " bytes");
            p.offset = size - bytes;
        } else {
            p.offset = std::uint64_t(enc.headerSize);
            if (size != p.offset + bytes)
                fail(path, "ElementDataFile",
                     "'" + file.string() + "': expected " + std::to_string(p.offset + bytes) +
                         " bytes (" + what + " = " + std::to_string(bytes) +
                         " data bytes + HeaderSize " + std::to_string(p.offset) + "), found " +
                         std::to_string(size) + " bytes");
        }
        parts.push_back(p);
    }

    /** LOCAL, compressed: from HeaderSize (or the end of the header) to CompressedDataSize or
     *  the end of the file. */
    void localCompressed(DataPart& p) const {
        const std::uint64_t fileSize = header.fileSize;
        p.compressed = true;
        p.offset = enc.headerSize > 0 ? std::uint64_t(enc.headerSize) : header.localOffset;
        if (fileSize < p.offset)
            fail(path, "HeaderSize",
                 "expected at most the file size " + std::to_string(fileSize) + ", found " +
                     std::to_string(p.offset));
        p.compressedBytes = fileSize - p.offset;
        if (enc.compressedDataSize > 0) {
            if (enc.compressedDataSize > p.compressedBytes)
                fail(path, "CompressedDataSize",
                     "expected at most the " + std::to_string(p.compressedBytes) +
                         " bytes after the header, found " +
                         std::to_string(enc.compressedDataSize));
            p.compressedBytes = enc.compressedDataSize;
        }
    }

    /** LOCAL, uncompressed: at the end of the file (HeaderSize = -1) or after the header. */
    void localPlain(DataPart& p) const {
        const std::uint64_t fileSize = header.fileSize;
        const std::uint64_t total = totalBytes();
        if (enc.headerSize == -1) {
            if (fileSize < total)
                fail(path, "ElementDataFile",
                     "LOCAL: expected at least " + std::to_string(total) + " bytes (" +
                         dimsText(geo.dimSize) + " x " + enc.typeDesc() +
                         ", HeaderSize = -1), found " + std::to_string(fileSize) + " bytes");
            p.offset = fileSize - total;
            return;
        }
        p.offset = enc.headerSize > 0 ? std::uint64_t(enc.headerSize) : header.localOffset;
        if (fileSize < p.offset || fileSize - p.offset < total)
            fail(path, "ElementDataFile",
                 "LOCAL: expected " + std::to_string(total) + " data bytes (" +
                     dimsText(geo.dimSize) + " x " + enc.typeDesc() + ") after byte " +
                     std::to_string(p.offset) + ", found " +
                     std::to_string(fileSize > p.offset ? fileSize - p.offset : 0) + " bytes");
    }

    void local() {
        DataPart p;
        p.file = path;
        p.bytes = totalBytes();
        if (enc.compressed)
            localCompressed(p);
        else
            localPlain(p);
        parts.push_back(p);
    }

    /** "LIST [nD]": file names one per line after the header (read from `sb`), each an nD block
     *  (default NDims-1). */
    void list(const std::vector<std::string_view>& words, const std::string& dataFile,
              std::streambuf& sb) {
        std::int64_t fileDim = std::int64_t(geo.ndims) - 1;
        if (words.size() > 1) {
            // "<n>D" or "<n>": the number with an optional D (either case) after it.
            std::string_view w = words[1];
            if (!w.empty() && (w.back() == 'd' || w.back() == 'D')) w.remove_suffix(1);
            const auto d = parseNumber<std::int64_t>(w);
            if (!d)
                fail(path, "ElementDataFile",
                     "expected 'LIST' or 'LIST <n>D', found " + quoteValue(dataFile));
            if (*d >= 1 && *d <= std::int64_t(geo.ndims)) fileDim = *d;
        }
        std::int64_t perFile = 1;
        for (std::int64_t a = 0; a < fileDim; ++a) perFile *= geo.dimSize[std::size_t(a)];
        const std::int64_t nFiles = geo.voxelCount / perFile;
        std::int64_t found = 0;
        std::string line;
        bool tooLong = false;
        while (found < nFiles) {
            if (!readHeaderLine(sb, line, kMaxHeaderLine, tooLong) || tooLong) break;
            const std::string_view name = trimSpace(line);
            if (name.empty()) continue;
            external(fs::path(std::string(name)), std::uint64_t(perFile) * enc.es,
                     "LIST file " + std::to_string(found + 1) + " of " + std::to_string(nFiles) +
                         ": " + std::to_string(perFile) + " x " + enc.typeDesc());
            ++found;
        }
        if (found < nFiles)
            fail(path, "ElementDataFile",
                 "LIST: expected " + std::to_string(nFiles) +
                     " file names after the header (one per " + std::to_string(fileDim) +
                     "D block of " + dimsText(geo.dimSize) + "), found " + std::to_string(found));
    }

    void pattern(const std::vector<std::string_view>& words, const std::string& dataFile);
};

/** "pattern [start [end [step]]]": one file per slice of the last axis. */
void MetaDataLocator::pattern(const std::vector<std::string_view>& words,
                              const std::string& dataFile) {
    std::int64_t nums[3] = {1, 0, 1};
    // Up to three numbers at the end (start, end, step), read from the last word backwards.
    std::int64_t parsed[3] = {0, 0, 0};
    std::size_t nNums = 0;
    for (std::size_t k = words.size(); k > 1 && nNums < 3; --k) {
        const auto v = parseNumber<std::int64_t>(words[k - 1]);
        if (!v) break;
        parsed[nNums++] = *v;
    }
    std::reverse(parsed, parsed + nNums);
    if (words.size() - nNums < 1)
        fail(path, "ElementDataFile",
             "expected 'pattern start end step', found " + quoteValue(dataFile));
    // Pattern words may contain spaces: rejoin everything before the numbers.
    const std::size_t nameWords = words.size() - nNums;
    const char* begin = words[0].data();
    const char* end = words[nameWords - 1].data() + words[nameWords - 1].size();
    const std::string_view pattern(begin, std::size_t(end - begin));
    const std::int64_t nLast = geo.dimSize.back();
    if (nNums >= 1) nums[0] = parsed[0];
    nums[1] = nNums >= 2 ? parsed[1] : nums[0] + nLast - 1;
    if (nNums >= 3) nums[2] = parsed[2];
    const std::int64_t start = nums[0], stop = nums[1], step = nums[2];
    if (step == 0 || (stop - start != 0 && ((stop - start) > 0) != (step > 0)) ||
        std::abs(start) > (std::int64_t(1) << 40) || std::abs(stop) > (std::int64_t(1) << 40))
        fail(path, "ElementDataFile",
             "expected 'pattern start end step' with a step going from start to end, found " +
                 quoteValue(dataFile));
    const std::int64_t count = (stop - start) / step + 1;
    if (count != nLast)
        fail(path, "ElementDataFile",
             "expected " + std::to_string(nLast) + " files (one per slice, DimSize[" +
                 std::to_string(geo.ndims - 1) + "] = " + std::to_string(nLast) +
                 "), found a pattern giving " + std::to_string(count) + " (" +
                 quoteValue(dataFile) + ")");
    if (!formatPattern(pattern, 0))
        fail(path, "ElementDataFile",
             "expected a file pattern with one %d conversion (e.g. slice%03d.raw), found " +
                 quoteValue(pattern));
    const std::int64_t perFile = geo.voxelCount / nLast;
    for (std::int64_t k = 0; k < count; ++k) {
        const std::int64_t number = start + k * step;
        external(fs::path(*formatPattern(pattern, number)), std::uint64_t(perFile) * enc.es,
                 "slice file " + std::to_string(k + 1) + " of " + std::to_string(count) + ": " +
                     std::to_string(perFile) + " x " + enc.typeDesc());
    }
}

/** The data parts named by ElementDataFile, each checked against its file's size and, when
 *  compressed, against what its compressed bytes can hold. `sb` is just after the header. */
std::vector<DataPart> locateMetaData(const fs::path& path, const MetaHeader& header,
                                     const MetaGeometry& geo, const MetaEncoding& enc,
                                     std::streambuf& sb) {
    MetaDataLocator locate{path, header, geo, enc, {}};
    const std::string& dataFile = *header.get("ElementDataFile");
    const auto words = splitWords(dataFile);
    if (dataFile.empty())
        fail(path, "ElementDataFile",
             "expected LOCAL, a file name, LIST or a pattern, found an empty value");
    else if (iequals(dataFile, "local"))
        locate.local();
    else if (words[0] == "LIST")
        locate.list(words, dataFile, sb);
    else if (dataFile.find('%') != std::string::npos)
        locate.pattern(words, dataFile);
    else
        locate.external(fs::path(dataFile), locate.totalBytes(),
                        dimsText(geo.dimSize) + " x " + enc.typeDesc());

    for (const DataPart& p : locate.parts) {
        if (p.compressed && p.bytes > maxInflatedBytes(p.compressedBytes))
            fail(path, "CompressedData",
                 "'" + p.file.string() + "': expected " + std::to_string(p.bytes) +
                     " bytes after decompression, found only " + std::to_string(p.compressedBytes) +
                     " compressed bytes, which cannot hold that much");
    }
    return std::move(locate.parts);
}

/** Reads every part in turn into `dst` (room for all of them). */
void readMetaData(const fs::path& path, const std::vector<DataPart>& parts, const MetaEncoding& enc,
                  float* dst) {
    for (const DataPart& p : parts) {
        std::unique_ptr<ByteSource> src;
        if (p.compressed)
            src = std::make_unique<InflateSource>(p.file, p.offset, p.compressedBytes);
        else
            src = std::make_unique<FileSource>(p.file, p.offset);
        const std::size_t count = std::size_t(p.bytes / enc.es);
        const std::uint64_t got =
            readElements(*src, enc.type, enc.bigEndian, Scaling{}, count, dst);
        if (got != p.bytes) {
            const std::string err = src->error();
            fail(path, "ElementDataFile",
                 "'" + p.file.string() + "': expected " + std::to_string(p.bytes) +
                     (p.compressed ? " bytes after decompression"
                                   : " data bytes from byte " + std::to_string(p.offset)) +
                     ", found " + std::to_string(got) + " bytes" +
                     (err.empty() ? std::string() : " (" + err + ")"));
        }
        dst += count;
    }
}

} // namespace

Volume loadMetaImage(const fs::path& path) {
    const std::uint64_t headerFileSize = regularFileSize(path, path, "header");
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "header", "cannot open file");
    const MetaHeader header = readMetaHeader(path, *in.rdbuf(), headerFileSize);
    if (const std::string* v = header.get("ObjectType"); v && *v != "Image")
        fail(path, "ObjectType", "expected Image, found " + quoteValue(*v));

    MetaGeometry geo;
    readMetaDims(path, header, geo);
    readMetaSpacingOrigin(path, header, geo);
    readMetaDirection(path, header, geo);
    MetaEncoding enc;
    readMetaElementType(path, header, enc);
    readMetaStorage(path, header, enc);
    validateGeometry(geo.dims, geo.spacing, path.string());

    const std::vector<DataPart> parts = locateMetaData(path, header, geo, enc, *in.rdbuf());
    Volume vol =
        emptyVolume(geo.dims, geo.spacing, geo.origin, geo.direction, volumeName(path), path);
    vol.orientationStated = geo.directionStated;
    readMetaData(path, parts, enc, vol.voxels.data());
    return vol;
}

} // namespace fvr::core
