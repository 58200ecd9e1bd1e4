// MP4 (H.264) movies of grey frames through libavcodec/libavformat/libswscale.
#include <fvr/core/io/movie_writer.h>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <cmath>
#include <string>
#include <system_error>
#include <vector>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>

namespace fvr::core {

namespace {

std::string avError(int code) {
    char buf[AV_ERROR_MAX_STRING_SIZE] = {};
    av_strerror(code, buf, sizeof buf);
    return buf;
}

} // namespace

struct MovieWriter::Impl {
    std::filesystem::path path, tmp;
    int width = 0, height = 0; ///< of the frames given
    int encWidth = 0, encHeight = 0; ///< even
    AVFormatContext* fmt = nullptr;
    AVCodecContext* enc = nullptr;
    AVStream* stream = nullptr;
    AVFrame* frame = nullptr;
    AVPacket* packet = nullptr;
    SwsContext* sws = nullptr;
    std::vector<std::uint8_t> padded; ///< the frame with its odd edge repeated
    int64_t next = 0;
    bool finished = false;
    bool headerWritten = false;

    [[noreturn]] void fail(const std::string& what) const {
        throw WriteError(path.string() + ": " + what);
    }
    void check(int rc, const char* what) const {
        if (rc < 0) fail(std::string(what) + ": " + avError(rc));
    }
    /** Sends `f` (null: flush) and writes every packet the encoder gives back. */
    void encode(const AVFrame* f) {
        check(avcodec_send_frame(enc, f), "cannot encode a frame");
        for (;;) {
            const int rc = avcodec_receive_packet(enc, packet);
            if (rc == AVERROR(EAGAIN) || rc == AVERROR_EOF) return;
            check(rc, "cannot encode a frame");
            av_packet_rescale_ts(packet, enc->time_base, stream->time_base);
            packet->stream_index = stream->index;
            check(av_interleaved_write_frame(fmt, packet), "cannot write a frame");
        }
    }
    ~Impl() {
        if (fmt && fmt->pb) avio_closep(&fmt->pb);
        avformat_free_context(fmt);
        avcodec_free_context(&enc);
        av_frame_free(&frame);
        av_packet_free(&packet);
        sws_freeContext(sws);
        if (!finished && !tmp.empty()) {
            std::error_code ec;
            std::filesystem::remove(tmp, ec);
        }
    }
};

MovieWriter::MovieWriter(const std::filesystem::path& path, int width, int height, double fps,
                         int quality)
    : m(std::make_unique<Impl>()) {
    m->path = path;
    if (width <= 0 || height <= 0 || width > 8192 || height > 8192)
        m->fail("cannot make a movie of " + std::to_string(width) + " x " + std::to_string(height) +
                " frames (1 to 8192 pixels a side)");
    if (!(fps >= 0.1 && fps <= 240.0))
        m->fail("frame rate " + std::to_string(fps) + " is outside 0.1 to 240 frames/s");
    m->width = width;
    m->height = height;
    m->encWidth = (width + 1) & ~1;
    m->encHeight = (height + 1) & ~1;
    const AVCodec* codec = avcodec_find_encoder_by_name("libx264");
    if (!codec) codec = avcodec_find_encoder(AV_CODEC_ID_H264);
    if (!codec) m->fail("this FFmpeg (libavcodec) has no H.264 encoder");
    // FFmpeg's and x264's notes on stderr only for errors (ours say what failed).
    av_log_set_level(AV_LOG_ERROR);
    m->tmp = temporaryPathFor(path);
    m->check(avformat_alloc_output_context2(&m->fmt, nullptr, "mp4", m->tmp.c_str()),
             "cannot make an MP4 container");
    m->enc = avcodec_alloc_context3(codec);
    m->frame = av_frame_alloc();
    m->packet = av_packet_alloc();
    if (!m->enc || !m->frame || !m->packet) m->fail("out of memory for the encoder");
    m->stream = avformat_new_stream(m->fmt, nullptr);
    if (!m->stream) m->fail("cannot add a video stream");
    const AVRational rate = av_d2q(fps, 100000);
    m->enc->width = m->encWidth;
    m->enc->height = m->encHeight;
    m->enc->pix_fmt = AV_PIX_FMT_YUV420P;
    m->enc->time_base = av_inv_q(rate);
    m->enc->framerate = rate;
    m->enc->gop_size = 12;
    m->enc->color_range = AVCOL_RANGE_MPEG;
    if (m->fmt->oformat->flags & AVFMT_GLOBALHEADER) m->enc->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    if (std::string(codec->name) == "libx264") {
        av_opt_set(m->enc->priv_data, "preset", "medium", 0);
        av_opt_set(m->enc->priv_data, "crf", std::to_string(quality).c_str(), 0);
    }
    m->check(avcodec_open2(m->enc, codec, nullptr), "cannot open the H.264 encoder");
    m->check(avcodec_parameters_from_context(m->stream->codecpar, m->enc),
             "cannot set the stream's parameters");
    m->stream->time_base = m->enc->time_base;
    m->stream->avg_frame_rate = rate;
    m->check(avio_open(&m->fmt->pb, m->tmp.c_str(), AVIO_FLAG_WRITE), "cannot create the file");
    m->check(avformat_write_header(m->fmt, nullptr), "cannot write the MP4 header");
    m->headerWritten = true;
    m->frame->format = AV_PIX_FMT_YUV420P;
    m->frame->width = m->encWidth;
    m->frame->height = m->encHeight;
    m->check(av_frame_get_buffer(m->frame, 0), "out of memory for a frame");
    m->sws = sws_getContext(m->encWidth, m->encHeight, AV_PIX_FMT_GRAY8, m->encWidth, m->encHeight,
                            AV_PIX_FMT_YUV420P, SWS_POINT, nullptr, nullptr, nullptr);
    if (!m->sws) m->fail("cannot convert grey to YUV (libswscale)");
    m->padded.resize(std::size_t(m->encWidth) * m->encHeight);
}

MovieWriter::~MovieWriter() = default;

void MovieWriter::addFrame(const std::uint8_t* grey) {
    if (m->finished) m->fail("a frame after the movie was finished");
    // The frame into an even-sized buffer, the last column/row repeated where odd.
    const int W = m->width, H = m->height, EW = m->encWidth;
    for (int y = 0; y < m->encHeight; ++y) {
        const std::uint8_t* src = grey + std::size_t(std::min(y, H - 1)) * W;
        std::uint8_t* dst = m->padded.data() + std::size_t(y) * EW;
        std::copy(src, src + W, dst);
        if (EW > W) dst[W] = src[W - 1];
    }
    m->check(av_frame_make_writable(m->frame), "cannot reuse the frame buffer");
    const std::uint8_t* srcPlanes[1] = {m->padded.data()};
    const int srcStride[1] = {EW};
    sws_scale(m->sws, srcPlanes, srcStride, 0, m->encHeight, m->frame->data, m->frame->linesize);
    m->frame->pts = m->next++;
    m->encode(m->frame);
}

void MovieWriter::finish() {
    if (m->finished) return;
    if (m->next == 0) m->fail("a movie needs at least one frame");
    m->encode(nullptr);
    m->check(av_write_trailer(m->fmt), "cannot write the MP4 trailer");
    m->check(avio_closep(&m->fmt->pb), "cannot close the file");
    std::error_code ec;
    std::filesystem::rename(m->tmp, m->path, ec);
    if (ec) m->fail("cannot rename the finished movie into place: " + ec.message());
    m->finished = true;
}

int MovieWriter::framesWritten() const { return int(m->next); }

const char* MovieWriter::encoderName() const { return m->enc->codec->name; }

} // namespace fvr::core
