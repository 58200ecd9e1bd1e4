#include <fvr/core/io/image_io.h>

#include <fvr/core/io/atomic_file.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

#include <zlib.h>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>

namespace fvr::core {

namespace fs = std::filesystem;

namespace {

/** Throws Error (LoadError or WriteError) naming the file and the problem: "<path>: <detail>". */
template <class Error>
[[noreturn]] void fail(const fs::path& path, const std::string& detail) {
    throw Error(path.string() + ": " + detail);
}

void appendU32BE(std::string& s, std::uint32_t v) {
    for (int i = 3; i >= 0; --i) s.push_back(char((v >> (8 * i)) & 0xff));
}

void appendChunk(std::string& png, const char* type, const std::string& payload) {
    appendU32BE(png, std::uint32_t(payload.size()));
    std::string body(type, 4);
    body += payload;
    png += body;
    appendU32BE(png, std::uint32_t(
                         crc32(0, reinterpret_cast<const Bytef*>(body.data()), uInt(body.size()))));
}

/** The .npy preamble and header: float32 little-endian, C order, shape (rows, cols), or
 *  (count, rows, cols) when count > 0, padded so that the data starts at a multiple of 64. */
std::string npyHeader(std::int64_t rows, std::int64_t cols, std::int64_t count) {
    std::ostringstream hdr;
    hdr << "{'descr': '<f4', 'fortran_order': False, 'shape': (";
    if (count > 0) hdr << count << ", ";
    hdr << rows << ", " << cols << "), }";
    std::string h = hdr.str();
    const std::size_t preamble = 10; // magic(6) + version(2) + header length(2)
    while ((preamble + h.size() + 1) % 64 != 0) h.push_back(' ');
    h.push_back('\n');
    std::string out("\x93NUMPY\x01\x00", 8);
    out.push_back(char(h.size() & 0xff));
    out.push_back(char((h.size() >> 8) & 0xff));
    out += h;
    return out;
}

/** A PNG of filtered scanlines `raw` (each row: a filter byte, then its samples): deflated into
 *  one IDAT, written atomically. colourType 0 grey, 2 RGB. */
void writePngFile(const fs::path& path, const std::string& raw, int rows, int cols, int bitDepth,
                  int colourType) {
    uLongf zlen = compressBound(uLong(raw.size()));
    std::string z(zlen, '\0');
    if (compress2(reinterpret_cast<Bytef*>(z.data()), &zlen,
                  reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()), 6) != Z_OK)
        fail<WriteError>(path, "PNG compression failed");
    z.resize(zlen);
    std::string png("\x89PNG\r\n\x1a\n", 8);
    std::string ihdr;
    appendU32BE(ihdr, std::uint32_t(cols));
    appendU32BE(ihdr, std::uint32_t(rows));
    ihdr.push_back(char(bitDepth));
    ihdr.push_back(char(colourType));
    ihdr.push_back('\0'); // deflate
    ihdr.push_back('\0'); // adaptive filtering
    ihdr.push_back('\0'); // not interlaced
    appendChunk(png, "IHDR", ihdr);
    appendChunk(png, "IDAT", z);
    appendChunk(png, "IEND", "");
    writeFileAtomic(path, png);
}

std::uint32_t readU32BE(const std::string& s, std::size_t at) {
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v = (v << 8) | std::uint8_t(s[at + std::size_t(i)]);
    return v;
}

/** The PNG's IHDR fields and its IDAT chunks, concatenated (the zlib stream). */
struct PngChunks {
    std::uint32_t width = 0, height = 0;
    int bitDepth = 0, colourType = 0, interlace = 0;
    std::string idat;
};

PngChunks pngChunks(const fs::path& path, const std::string& file) {
    if (file.size() < 8 || file.compare(0, 8, std::string("\x89PNG\r\n\x1a\n", 8)) != 0)
        fail<LoadError>(path, "not a PNG file");
    PngChunks c;
    bool header = false, end = false;
    for (std::size_t at = 8; !end;) {
        if (at + 12 > file.size()) fail<LoadError>(path, "PNG truncated (no IEND chunk)");
        const std::uint32_t len = readU32BE(file, at);
        const std::string type = file.substr(at + 4, 4);
        if (len > file.size() - at - 12) fail<LoadError>(path, "PNG chunk " + type + " truncated");
        const std::string data = file.substr(at + 8, len);
        if (type == "IHDR" && len == 13) {
            c.width = readU32BE(data, 0);
            c.height = readU32BE(data, 4);
            c.bitDepth = std::uint8_t(data[8]);
            c.colourType = std::uint8_t(data[9]);
            c.interlace = std::uint8_t(data[12]);
            header = true;
        } else if (type == "IDAT") {
            c.idat += data;
        }
        end = type == "IEND";
        at += 12 + std::size_t(len);
    }
    if (!header) fail<LoadError>(path, "PNG without an IHDR chunk");
    return c;
}

/** Undoes PNG filter `type` on one scanline (bpp bytes per pixel; prev: the row above, unfiltered,
 *  zeros for the first). */
void unfilterRow(const fs::path& path, int type, std::uint8_t* row, const std::uint8_t* prev,
                 std::size_t n, std::size_t bpp) {
    for (std::size_t i = 0; i < n; ++i) {
        const int a = i >= bpp ? row[i - bpp] : 0, b = prev[i], c = i >= bpp ? prev[i - bpp] : 0;
        int pred = 0;
        switch (type) {
        case 0: pred = 0; break;
        case 1: pred = a; break;
        case 2: pred = b; break;
        case 3: pred = (a + b) / 2; break;
        case 4: {
            const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b),
                      pc = std::abs(p - c);
            pred = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
            break;
        }
        default: fail<LoadError>(path, "PNG filter type " + std::to_string(type) + " unknown");
        }
        row[i] = std::uint8_t(row[i] + pred);
    }
}

} // namespace

std::vector<float> readPng(const fs::path& path, int& rows, int& cols) {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail<LoadError>(path, "cannot open");
    const std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const PngChunks c = pngChunks(path, file);
    if (c.colourType != 0 || (c.bitDepth != 8 && c.bitDepth != 16))
        fail<LoadError>(path, "PNG colour type " + std::to_string(c.colourType) + ", " +
                                  std::to_string(c.bitDepth) +
                                  " bits: only 8- or 16-bit grayscale is read");
    if (c.interlace != 0) fail<LoadError>(path, "interlaced PNG is not read");
    if (c.width == 0 || c.height == 0 || c.width > 65536 || c.height > 65536)
        fail<LoadError>(path, "PNG size " + std::to_string(c.width) + " x " +
                                  std::to_string(c.height) + " out of range");
    const std::size_t bpp = std::size_t(c.bitDepth / 8), stride = c.width * bpp;
    std::vector<std::uint8_t> raw(c.height * (stride + 1));
    uLongf len = uLongf(raw.size());
    if (uncompress(raw.data(), &len, reinterpret_cast<const Bytef*>(c.idat.data()),
                   uLong(c.idat.size())) != Z_OK ||
        len != raw.size())
        fail<LoadError>(path, "PNG image data corrupt or truncated");
    rows = int(c.height);
    cols = int(c.width);
    std::vector<std::uint8_t> zero(stride, 0);
    std::vector<float> out(std::size_t(rows) * std::size_t(cols));
    const double scale = bpp == 2 ? 65535.0 : 255.0;
    for (std::size_t r = 0; r < c.height; ++r) {
        std::uint8_t* row = raw.data() + r * (stride + 1) + 1;
        const std::uint8_t* prev = r > 0 ? row - stride - 1 : zero.data();
        unfilterRow(path, row[-1], row, prev, stride, bpp);
        for (std::size_t k = 0; k < c.width; ++k) {
            const unsigned v = bpp == 2 ? (unsigned(row[2 * k]) << 8) | row[2 * k + 1] : row[k];
            out[r * c.width + k] = float(double(v) / scale);
        }
    }
    return out;
}

std::vector<float> readPfm(const fs::path& path, int& rows, int& cols) {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail<LoadError>(path, "cannot open");
    std::string magic;
    double scale = 0.0;
    long long w = 0, h = 0;
    in >> magic >> w >> h >> scale;
    if (!in || magic == "PF") {
        if (magic == "PF") fail<LoadError>(path, "colour PFM (PF): only grayscale (Pf) is read");
        fail<LoadError>(path, "not a PFM file");
    }
    if (magic != "Pf") fail<LoadError>(path, "not a PFM file");
    if (w < 1 || h < 1 || w > 65536 || h > 65536 || scale == 0.0)
        fail<LoadError>(path, "PFM header out of range");
    in.get(); // the single whitespace before the data
    rows = int(h);
    cols = int(w);
    std::vector<float> stored(std::size_t(w * h));
    in.read(reinterpret_cast<char*>(stored.data()), std::streamsize(stored.size() * 4));
    if (!in) fail<LoadError>(path, "PFM data truncated");
    const bool little = scale < 0.0;
    const std::uint16_t probe = 1;
    const bool hostLittle = *reinterpret_cast<const std::uint8_t*>(&probe) == 1;
    std::vector<float> out(stored.size());
    for (long long r = 0; r < h; ++r) // stored bottom row first
        for (long long c = 0; c < w; ++c) {
            float v = stored[std::size_t((h - 1 - r) * w + c)];
            if (little != hostLittle) {
                auto* b = reinterpret_cast<std::uint8_t*>(&v);
                std::swap(b[0], b[3]);
                std::swap(b[1], b[2]);
            }
            out[std::size_t(r * w + c)] = v;
        }
    return out;
}

void writeNpy(const fs::path& path, const float* data, std::int64_t rows, std::int64_t cols,
              std::int64_t count) {
    const std::string header = npyHeader(rows, cols, count);
    const std::size_t n = std::size_t(rows * cols * std::max<std::int64_t>(1, count));
    AtomicFileWriter out(path); // the data written from where it is, not copied first
    out.write(header.data(), header.size());
    out.write(data, n * sizeof(float)); // x86/ARM: little-endian
    out.commit();
}

NpyStackWriter::NpyStackWriter(const fs::path& path, std::int64_t rows, std::int64_t cols,
                               std::int64_t count)
    : m_path(path), m_rows(rows), m_cols(cols), m_count(count) {
    if (rows <= 0 || cols <= 0 || count <= 0)
        fail<WriteError>(path, "a .npy stack needs at least one image of at least one pixel");
    m_file = std::make_unique<AtomicFileWriter>(path);
    const std::string header = npyHeader(rows, cols, count);
    m_file->write(header.data(), header.size());
}

NpyStackWriter::~NpyStackWriter() = default; // an unfinished file is removed

void NpyStackWriter::add(const float* image) {
    if (!m_file) fail<WriteError>(m_path, "the stack is closed");
    if (m_written >= m_count)
        fail<WriteError>(m_path,
                         "more images than the " + std::to_string(m_count) + " of the header");
    m_file->write(image, std::size_t(m_rows * m_cols) * sizeof(float)); // little-endian
    ++m_written;
}

void NpyStackWriter::finish() {
    if (!m_file) fail<WriteError>(m_path, "the stack is closed");
    std::unique_ptr<AtomicFileWriter> file = std::move(m_file); // removed unless committed
    if (m_written != m_count)
        fail<WriteError>(m_path, "the stack has " + std::to_string(m_written) + " images of the " +
                                     std::to_string(m_count) + " of its header");
    file->commit();
}

namespace {
/** The shape tuple of a .npy header, "(n, ...)": non-negative integers whose product stays
 *  within the largest file there can be (LoadError naming the file otherwise). */
std::vector<std::int64_t> npyShape(const fs::path& path, const std::string& header) {
    const auto open = header.find("'shape'"), close = header.find(')', open);
    const auto paren = open == std::string::npos ? open : header.find('(', open);
    if (paren == std::string::npos || close == std::string::npos || close < paren)
        fail<LoadError>(path, "shape: expected a tuple '(n, ...)' in the header");
    const std::string_view tuple = std::string_view(header).substr(paren + 1, close - paren - 1);
    std::vector<std::int64_t> shape;
    std::int64_t total = 1;
    for (std::size_t at = 0; at <= tuple.size();) {
        const std::size_t comma = std::min(tuple.find(',', at), tuple.size());
        const std::string_view word = trimSpace(tuple.substr(at, comma - at));
        at = comma + 1;
        if (word.empty()) continue; // "(3,)": the one-element tuple's trailing comma
        const auto n = parseNumber<std::int64_t>(word);
        if (!n || *n < 0 || (*n > 0 && total > (std::int64_t(1) << 60) / *n))
            fail<LoadError>(path, "shape: expected sizes >= 0 with a product below 2^60, found '" +
                                      std::string(tuple) + "'");
        shape.push_back(*n);
        total *= *n;
    }
    return shape;
}
} // namespace

std::vector<float> readNpy(const fs::path& path, std::vector<std::int64_t>& shape) {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail<LoadError>(path, "cannot open");
    char pre[10];
    in.read(pre, 10);
    if (!in || std::memcmp(pre, "\x93NUMPY", 6) != 0) fail<LoadError>(path, "not a .npy file");
    const std::size_t hlen = std::uint8_t(pre[8]) | (std::size_t(std::uint8_t(pre[9])) << 8);
    std::string h(hlen, '\0');
    in.read(h.data(), std::streamsize(hlen));
    if (h.find("'<f4'") == std::string::npos) fail<LoadError>(path, "descr: expected '<f4'");
    shape = npyShape(path, h);
    std::int64_t total = 1;
    for (const std::int64_t n : shape) total *= n;
    const auto dataStart = std::uint64_t(in.tellg());
    const auto fileSize = std::uint64_t(fs::file_size(path));
    if (std::uint64_t(total) * sizeof(float) != fileSize - dataStart)
        fail<LoadError>(path, "shape: expected " + std::to_string(total) + " floats, found " +
                                  std::to_string((fileSize - dataStart) / sizeof(float)));
    std::vector<float> v(static_cast<std::size_t>(total));
    in.read(reinterpret_cast<char*>(v.data()), std::streamsize(v.size() * sizeof(float)));
    if (!in) fail<LoadError>(path, "data: truncated");
    return v;
}

void writePfm(const fs::path& path, const float* data, int rows, int cols) {
    std::string out = "Pf\n" + std::to_string(cols) + " " + std::to_string(rows) + "\n-1.0\n";
    for (int r = rows - 1; r >= 0; --r)
        out.append(reinterpret_cast<const char*>(data + std::size_t(r) * cols),
                   std::size_t(cols) * sizeof(float));
    writeFileAtomic(path, out);
}

void writePng(const fs::path& path, const float* data, int rows, int cols, const DisplayWindow& w,
              int bitDepth) {
    if (bitDepth != 8 && bitDepth != 16) fail<WriteError>(path, "PNG bit depth must be 8 or 16");
    const int bpp = bitDepth / 8;
    const double maxv = bitDepth == 8 ? 255.0 : 65535.0;
    std::string raw;
    raw.reserve(std::size_t(rows) * (1 + std::size_t(cols) * bpp));
    for (int r = 0; r < rows; ++r) {
        raw.push_back('\0'); // filter: none
        for (int c = 0; c < cols; ++c) {
            const double t = w.map(double(data[std::size_t(r) * cols + c]));
            const auto q = std::uint32_t(std::lround(t * maxv));
            if (bpp == 2) raw.push_back(char(q >> 8));
            raw.push_back(char(q & 0xff));
        }
    }
    writePngFile(path, raw, rows, cols, bitDepth, 0);
}

void writePngRgb(const fs::path& path, const std::uint8_t* rgb, int rows, int cols) {
    std::string raw;
    raw.reserve(std::size_t(rows) * (1 + std::size_t(cols) * 3));
    for (int r = 0; r < rows; ++r) {
        raw.push_back('\0'); // filter: none
        raw.append(reinterpret_cast<const char*>(rgb + std::size_t(r) * cols * 3),
                   std::size_t(cols) * 3);
    }
    writePngFile(path, raw, rows, cols, 8, 2);
}

void writeProjection(const fs::path& path, const ProjectionImage& image) {
    const std::string ext = asciiLower(path.extension().string());
    const int W = image.width, H = image.height;
    if (ext == ".npy")
        writeNpy(path, image.pixels.data(), H, W);
    else if (ext == ".pfm")
        writePfm(path, image.pixels.data(), H, W);
    else if (ext == ".png")
        writePng(path, image.pixels.data(), H, W, autoWindow(image.pixels), 8);
    else
        fail<WriteError>(path, "unknown output format '" + ext + "' (expected .npy, .pfm or .png)");
}

} // namespace fvr::core
