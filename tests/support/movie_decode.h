#pragma once
// Tests: a movie decoded with FFmpeg (libavformat/libavcodec) into 8-bit grey frames, the
// oracle of the movie writer's tests (decoding, not the writer's own code).
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>
}

#include <cstdint>
#include <string>
#include <vector>

namespace fvr::test {

struct DecodedMovie {
    std::string error; ///< empty when decoded
    std::string codec; ///< e.g. "h264"
    int width = 0, height = 0;
    double fps = 0.0; ///< the stream's average frame rate
    std::vector<std::vector<std::uint8_t>> frames; ///< width x height grey each
};

inline DecodedMovie decodeMovie(const std::string& path) {
    DecodedMovie out;
    AVFormatContext* fmt = nullptr;
    if (avformat_open_input(&fmt, path.c_str(), nullptr, nullptr) < 0) {
        out.error = "cannot open";
        return out;
    }
    avformat_find_stream_info(fmt, nullptr);
    const int si = av_find_best_stream(fmt, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
    if (si < 0) {
        out.error = "no video stream";
        avformat_close_input(&fmt);
        return out;
    }
    AVStream* st = fmt->streams[si];
    const AVCodec* codec = avcodec_find_decoder(st->codecpar->codec_id);
    AVCodecContext* dec = avcodec_alloc_context3(codec);
    avcodec_parameters_to_context(dec, st->codecpar);
    avcodec_open2(dec, codec, nullptr);
    out.codec = codec->name;
    out.width = dec->width;
    out.height = dec->height;
    out.fps = av_q2d(st->avg_frame_rate);
    AVPacket* pkt = av_packet_alloc();
    AVFrame* frame = av_frame_alloc();
    SwsContext* sws = nullptr;
    const auto drain = [&] {
        while (avcodec_receive_frame(dec, frame) >= 0) {
            sws = sws_getCachedContext(sws, frame->width, frame->height,
                                       AVPixelFormat(frame->format), frame->width, frame->height,
                                       AV_PIX_FMT_GRAY8, SWS_POINT, nullptr, nullptr, nullptr);
            std::vector<std::uint8_t> grey(std::size_t(frame->width) * frame->height);
            std::uint8_t* dst[1] = {grey.data()};
            const int stride[1] = {frame->width};
            sws_scale(sws, frame->data, frame->linesize, 0, frame->height, dst, stride);
            out.frames.push_back(std::move(grey));
        }
    };
    while (av_read_frame(fmt, pkt) >= 0) {
        if (pkt->stream_index == si && avcodec_send_packet(dec, pkt) >= 0) drain();
        av_packet_unref(pkt);
    }
    avcodec_send_packet(dec, nullptr);
    drain();
    sws_freeContext(sws);
    av_frame_free(&frame);
    av_packet_free(&pkt);
    avcodec_free_context(&dec);
    avformat_close_input(&fmt);
    return out;
}

/** Pearson correlation of two equally long sequences. */
template <class A, class B>
double correlation(const A& a, const B& b) {
    const std::size_t n = std::min(a.size(), b.size());
    double ma = 0, mb = 0;
    for (std::size_t i = 0; i < n; ++i) ma += a[i], mb += b[i];
    ma /= double(n), mb /= double(n);
    double sab = 0, saa = 0, sbb = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const double x = a[i] - ma, y = b[i] - mb;
        sab += x * y, saa += x * x, sbb += y * y;
    }
    return sab / std::sqrt(saa * sbb);
}

} // namespace fvr::test
