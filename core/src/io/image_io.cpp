#include <fvr/core/io/image_io.h>

#include <fvr/core/io/atomic_file.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
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

} // namespace

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
    ihdr.push_back('\0'); // grayscale
    ihdr.push_back('\0');
    ihdr.push_back('\0');
    ihdr.push_back('\0');
    appendChunk(png, "IHDR", ihdr);
    appendChunk(png, "IDAT", z);
    appendChunk(png, "IEND", "");
    writeFileAtomic(path, png);
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
