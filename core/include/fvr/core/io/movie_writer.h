#pragma once
/** Movies of rendered frames: MP4 (H.264) through FFmpeg's libavcodec/libavformat/libswscale.
 *  Grey 8-bit frames in, YUV 4:2:0 out (what every player shows). No Qt. */
#include <cstdint>
#include <filesystem>
#include <memory>

namespace fvr::core {

class MovieWriter {
public:
    /** Starts `path` (written to a temporary file beside it and renamed by finish()): frames of
     *  width x height at `fps` frames per second. An odd width or height is padded by one
     *  column/row (H.264's 4:2:0 needs even sizes), repeating the last. `quality` is x264's
     *  constant rate factor (0 lossless luma, 18 visually lossless, 51 worst). Throws
     *  WriteError naming the path (no H.264 encoder, cannot create the file, bad size/rate). */
    MovieWriter(const std::filesystem::path& path, int width, int height, double fps,
                int quality = 18);
    /** Without finish() (an error, a cancel): the temporary file is removed, nothing is left. */
    ~MovieWriter();
    MovieWriter(const MovieWriter&) = delete;
    MovieWriter& operator=(const MovieWriter&) = delete;

    /** One frame, row-major 8-bit grey, `width` x `height` as given to the constructor. */
    void addFrame(const std::uint8_t* grey);
    /** Flushes the encoder, writes the trailer and renames the file into place. */
    void finish();
    int framesWritten() const;
    /** The encoder's name (e.g. "libx264"). */
    const char* encoderName() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m;
};

} // namespace fvr::core
