#pragma once
/** Writers for projection images (no Qt): NumPy .npy, PFM, PNG (8/16-bit grayscale) through a
 *  display window (xray/display_window.h). All writes go to a temporary file renamed into place. */
#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include <fvr/core/render/projection.h>
#include <fvr/core/xray/display_window.h>

namespace fvr::core {

/** float32 little-endian, C order, shape (rows, cols) or (count, rows, cols) when count > 0. */
void writeNpy(const std::filesystem::path& path, const float* data, std::int64_t rows,
              std::int64_t cols, std::int64_t count = 0);

class AtomicFileWriter;

/**
 * A float32 .npy stack of `count` images of rows x cols written as it is produced (nothing of
 * it held in memory): the header with the final shape (count, rows, cols) first, then each image
 * as add() gets it, into `<path>.part` (io/atomic_file.h); finish() checks that all `count`
 * images came and moves the file into place (a short stack is removed). Destroyed before
 * finish() (an error, an exception), it removes the temporary file. Throws WriteError naming `path`
 * and the problem.
 */
class NpyStackWriter {
public:
    NpyStackWriter(const std::filesystem::path& path, std::int64_t rows, std::int64_t cols,
                   std::int64_t count);
    ~NpyStackWriter();
    NpyStackWriter(const NpyStackWriter&) = delete;
    NpyStackWriter& operator=(const NpyStackWriter&) = delete;

    /** Appends the next image: rows x cols floats. */
    void add(const float* image);
    void finish();
    std::int64_t written() const { return m_written; }

private:
    std::filesystem::path m_path;
    std::unique_ptr<AtomicFileWriter> m_file; ///< null once finished (or failed to finish)
    std::int64_t m_rows, m_cols, m_count, m_written = 0;
};

/** Reads a float32 .npy written by writeNpy (tests); shape returned in `shape`. */
std::vector<float> readNpy(const std::filesystem::path& path, std::vector<std::int64_t>& shape);
/** Grayscale PFM ("Pf", little-endian scale -1), rows stored bottom-to-top as the format says. */
void writePfm(const std::filesystem::path& path, const float* data, int rows, int cols);
/** Reads a grayscale PFM ("Pf", either byte order by the sign of its scale), rows returned top to
 *  bottom. LoadError naming the file: not a PFM, a colour PFM ("PF"), truncated. */
std::vector<float> readPfm(const std::filesystem::path& path, int& rows, int& cols);
/** Reads a grayscale PNG (colour type 0, 8 or 16 bits, not interlaced) as its levels scaled to
 *  [0, 1]. LoadError naming the file and what it holds otherwise (colour, a palette, interlace,
 *  a bad chunk or stream). */
std::vector<float> readPng(const std::filesystem::path& path, int& rows, int& cols);
/** Grayscale PNG; bitDepth 8 or 16; values mapped through the window. */
void writePng(const std::filesystem::path& path, const float* data, int rows, int cols,
              const DisplayWindow& window, int bitDepth = 8);

/** RGB PNG (8 bits per channel) of rows x cols x 3 bytes, row 0 at the top. */
void writePngRgb(const std::filesystem::path& path, const std::uint8_t* rgb, int rows, int cols);

/** Writes by extension: .npy (raw floats), .pfm (raw floats), .png (auto-windowed 8-bit).
 *  Throws WriteError (unknown extension, I/O failure) naming the path. */
void writeProjection(const std::filesystem::path& path, const ProjectionImage& image);

} // namespace fvr::core
