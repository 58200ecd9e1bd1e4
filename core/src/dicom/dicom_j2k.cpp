// JPEG 2000 pixel data (transfer syntaxes 1.2.840.10008.1.2.4.90 and .91), decoded with
// OpenJPEG: Debian's DCMTK has no JPEG 2000 codec. The encapsulated fragments are split into
// frames (one codestream per frame), each codestream is decoded from memory, and the samples are
// written as little-endian words of BitsAllocated, samples in the low bits: what DCMTK's JPEG and
// JPEG-LS decoders give, so the loader's masking, sign extension and rescale apply unchanged.
#include "dicom_internal.h"

#include <algorithm>
#include <cstring>
#include <memory>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcpixel.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <dcmtk/dcmdata/dcxfer.h>

#include <openjpeg.h>

namespace fvr::core::dicom_detail {

namespace {

using Bytes = std::vector<std::uint8_t>;

bool startsWith(const Bytes& b, std::initializer_list<std::uint8_t> magic) {
    return b.size() >= magic.size() && std::equal(magic.begin(), magic.end(), b.begin());
}
/** A raw J2K codestream begins with SOC + SIZ; a JP2 file with its signature box. */
bool isCodestreamStart(const Bytes& b) {
    return startsWith(b, {0xFF, 0x4F, 0xFF, 0x51}) ||
           startsWith(b, {0x00, 0x00, 0x00, 0x0C, 0x6A, 0x50, 0x20, 0x20});
}

/** The encapsulated fragments (offset table excluded) and the Basic Offset Table. */
struct Fragments {
    std::vector<Bytes> items;
    std::vector<std::uint32_t> offsets;
};

Fragments readFragments(const DicomHeader& h, DcmDataset& ds) {
    DcmElement* pe = nullptr;
    if (ds.findAndGetElement(DCM_PixelData, pe).bad() || !pe)
        fail(h.path, "Pixel Data (7FE0,0010) missing");
    auto* pd = dynamic_cast<DcmPixelData*>(pe);
    DcmPixelSequence* seq = nullptr;
    if (!pd || pd->getEncapsulatedRepresentation(E_TransferSyntax(h.xfer), nullptr, seq).bad() ||
        !seq)
        fail(h.path,
             "Pixel Data (7FE0,0010): expected encapsulated JPEG 2000 fragments, found none");
    Fragments f;
    for (unsigned long i = 0; i < seq->card(); ++i) {
        DcmPixelItem* item = nullptr;
        if (seq->getItem(item, i).bad() || !item)
            fail(h.path,
                 "Pixel Data (7FE0,0010): fragment " + std::to_string(i) + " cannot be read");
        Uint8* p = nullptr;
        const Uint32 n = item->getLength();
        if (n > 0 && (item->getUint8Array(p).bad() || !p))
            fail(h.path, "Pixel Data (7FE0,0010): fragment " + std::to_string(i) +
                             " cannot be read (truncated file?)");
        if (i == 0) {
            for (Uint32 k = 0; k + 4 <= n; k += 4) {
                std::uint32_t v;
                std::memcpy(&v, p + k, 4);
                f.offsets.push_back(v); // little endian host (asserted in dicom_load.cpp)
            }
        } else {
            f.items.emplace_back(p, p + n);
        }
    }
    return f;
}

/** One codestream per frame: all fragments for a single frame; one fragment per frame when the
 *  counts agree; else the Basic Offset Table; else a new frame at each fragment that starts a
 *  codestream. */
std::vector<Bytes> splitFrames(const DicomHeader& h, Fragments f) {
    const auto frames = static_cast<std::size_t>(h.frames);
    std::vector<Bytes> out;
    auto join = [&](std::size_t begin, std::size_t end) {
        Bytes b;
        for (std::size_t i = begin; i < end; ++i)
            b.insert(b.end(), f.items[i].begin(), f.items[i].end());
        return b;
    };
    if (frames == 1) {
        out.push_back(join(0, f.items.size()));
        return out;
    }
    if (f.items.size() == frames) return std::move(f.items);
    std::vector<std::size_t> starts;
    if (f.offsets.size() == frames) {
        std::uint64_t pos = 0; // offsets count from the first fragment's item tag (8-byte headers)
        std::size_t next = 0;
        for (std::size_t i = 0; i < f.items.size() && next < frames; ++i) {
            if (pos == f.offsets[next]) starts.push_back(i), ++next;
            pos += 8 + f.items[i].size();
        }
        if (starts.size() != frames) starts.clear();
    }
    if (starts.empty())
        for (std::size_t i = 0; i < f.items.size(); ++i)
            if (isCodestreamStart(f.items[i])) starts.push_back(i);
    if (starts.size() != frames || starts.front() != 0)
        fail(h.path, "Pixel Data (7FE0,0010): " + std::to_string(f.items.size()) +
                         " JPEG 2000 fragments cannot be split into " + std::to_string(frames) +
                         " frames (no usable offset table, " + std::to_string(starts.size()) +
                         " codestream starts)");
    starts.push_back(f.items.size());
    for (std::size_t k = 0; k < frames; ++k) out.push_back(join(starts[k], starts[k + 1]));
    return out;
}

struct MemoryStream {
    const std::uint8_t* data = nullptr;
    std::size_t size = 0;
    std::size_t pos = 0;
};

OPJ_SIZE_T streamRead(void* buffer, OPJ_SIZE_T n, void* user) {
    auto* s = static_cast<MemoryStream*>(user);
    if (s->pos >= s->size) return static_cast<OPJ_SIZE_T>(-1);
    const std::size_t k = std::min<std::size_t>(n, s->size - s->pos);
    std::memcpy(buffer, s->data + s->pos, k);
    s->pos += k;
    return k;
}
OPJ_OFF_T streamSkip(OPJ_OFF_T n, void* user) {
    auto* s = static_cast<MemoryStream*>(user);
    if (n < 0) {
        const auto back = std::min<std::size_t>(std::size_t(-n), s->pos);
        s->pos -= back;
        return -OPJ_OFF_T(back);
    }
    const std::size_t k =
        std::min<std::size_t>(std::size_t(n), s->size - std::min(s->pos, s->size));
    s->pos += k;
    return OPJ_OFF_T(k);
}
OPJ_BOOL streamSeek(OPJ_OFF_T n, void* user) {
    auto* s = static_cast<MemoryStream*>(user);
    if (n < 0 || std::size_t(n) > s->size) return OPJ_FALSE;
    s->pos = std::size_t(n);
    return OPJ_TRUE;
}
void collectMessage(const char* msg, void* user) {
    auto* out = static_cast<std::string*>(user);
    std::string m = msg ? msg : "";
    while (!m.empty() && (m.back() == '\n' || m.back() == '\r')) m.pop_back();
    if (!m.empty() && out->empty()) *out = m; // the first error is the cause
}
void ignoreMessage(const char*, void*) {}

struct CodecDeleter {
    void operator()(opj_codec_t* c) const { opj_destroy_codec(c); }
};
struct StreamDeleter {
    void operator()(opj_stream_t* s) const { opj_stream_destroy(s); }
};
struct ImageDeleter {
    void operator()(opj_image_t* i) const { opj_image_destroy(i); }
};

using StreamPtr = std::unique_ptr<opj_stream_t, StreamDeleter>;
using CodecPtr = std::unique_ptr<opj_codec_t, CodecDeleter>;

/** An OpenJPEG input stream reading `mem` (which must outlive it). */
StreamPtr memoryStream(const DicomHeader& h, MemoryStream& mem) {
    StreamPtr stream(opj_stream_create(OPJ_J2K_STREAM_CHUNK_SIZE, OPJ_TRUE));
    if (!stream) fail(h.path, "JPEG 2000: cannot create a decoding stream");
    opj_stream_set_user_data(stream.get(), &mem, nullptr);
    opj_stream_set_user_data_length(stream.get(), mem.size);
    opj_stream_set_read_function(stream.get(), streamRead);
    opj_stream_set_skip_function(stream.get(), streamSkip);
    opj_stream_set_seek_function(stream.get(), streamSeek);
    return stream;
}

/** A strict decoder for a JP2 file or a raw J2K codestream; its first error goes to `error`. */
CodecPtr strictDecoder(const DicomHeader& h, const Bytes& code, std::string& error) {
    const bool jp2 = startsWith(code, {0x00, 0x00, 0x00, 0x0C, 0x6A, 0x50, 0x20, 0x20});
    CodecPtr codec(opj_create_decompress(jp2 ? OPJ_CODEC_JP2 : OPJ_CODEC_J2K));
    if (!codec) fail(h.path, "JPEG 2000: cannot create a decoder");
    opj_set_error_handler(codec.get(), collectMessage, &error);
    opj_set_warning_handler(codec.get(), ignoreMessage, nullptr);
    opj_set_info_handler(codec.get(), ignoreMessage, nullptr);
    opj_dparameters_t params;
    opj_set_default_decoder_parameters(&params);
    if (!opj_setup_decoder(codec.get(), &params)) fail(h.path, "JPEG 2000: decoder setup failed");
    // A truncated codestream is an error, not a partly decoded image (OpenJPEG 2.5's default,
    // made explicit: the corrupt-codestream test fails without it).
    opj_decoder_set_strict_mode(codec.get(), OPJ_TRUE);
    return codec;
}

/** The codestream header must describe one grayscale component of the header's size and at
 *  most BitsAllocated bits. */
void checkComponent(const DicomHeader& h, const opj_image_t& image, const std::string& where) {
    if (image.numcomps != 1)
        fail(h.path, "JPEG 2000 pixel data" + where + " has " + std::to_string(image.numcomps) +
                         " components; only grayscale (1) is supported");
    const opj_image_comp_t& c0 = image.comps[0];
    if (c0.dx != 1 || c0.dy != 1 || std::int64_t(c0.w) != h.cols || std::int64_t(c0.h) != h.rows)
        fail(h.path, "JPEG 2000 pixel data" + where + " is " + std::to_string(c0.w) + " x " +
                         std::to_string(c0.h) + ", the header says " + std::to_string(h.cols) +
                         " x " + std::to_string(h.rows));
    if (c0.prec < 1 || c0.prec > std::uint32_t(h.bitsAllocated))
        fail(h.path, "JPEG 2000 pixel data" + where + " holds " + std::to_string(c0.prec) +
                         "-bit samples, more than BitsAllocated " +
                         std::to_string(h.bitsAllocated));
}

/** Stores the decoded samples `s` of component c0 in `dst` as BitsAllocated-bit words.
 *  Samples must fit BitsStored bits; a codestream with more significant bits would be cut.
 *  Its signedness may differ from PixelRepresentation (some scanners write unsigned
 *  codestreams of signed pixels): the header decides, as for the other codecs, and the bits
 *  are read as BitsStored-bit two's complement, with a warning. */
void storeSamples(const DicomHeader& h, const OPJ_INT32* s, const opj_image_comp_t& c0,
                  const std::string& where, std::uint8_t* dst, Jpeg2000Frames& info) {
    const std::int64_t n = h.cols * h.rows;
    const int bits = h.bitsStored;
    const bool codestreamSigned = c0.sgnd != 0;
    const std::int64_t lo = codestreamSigned ? -(std::int64_t(1) << (bits - 1)) : 0;
    const std::int64_t hi =
        codestreamSigned ? (std::int64_t(1) << (bits - 1)) - 1 : (std::int64_t(1) << bits) - 1;
    const auto [mn, mx] = std::minmax_element(s, s + n);
    if (*mn < lo || *mx > hi)
        fail(h.path, "JPEG 2000 pixel data" + where + " holds values " + std::to_string(*mn) +
                         " .. " + std::to_string(*mx) + ", more than the BitsStored " +
                         std::to_string(bits) + " bits that the header declares");
    if (codestreamSigned != (h.pixelRepresentation == 1)) info.signReinterpreted = true;
    switch (h.bitsAllocated) {
    case 8:
        for (std::int64_t i = 0; i < n; ++i) dst[i] = static_cast<std::uint8_t>(s[i]);
        break;
    case 16:
        for (std::int64_t i = 0; i < n; ++i) {
            const auto w = static_cast<std::uint16_t>(s[i]);
            std::memcpy(dst + 2 * i, &w, 2);
        }
        break;
    default:
        for (std::int64_t i = 0; i < n; ++i) {
            const auto w = static_cast<std::uint32_t>(s[i]);
            std::memcpy(dst + 4 * i, &w, 4);
        }
    }
}

/** Decodes one codestream into `dst` (cols * rows words of BitsAllocated / 8 bytes). */
void decodeFrame(const DicomHeader& h, const Bytes& code, int frame, std::uint8_t* dst,
                 Jpeg2000Frames& info) {
    const std::string where = h.frames > 1 ? " (frame " + std::to_string(frame + 1) + ")" : "";
    if (code.empty()) fail(h.path, "JPEG 2000 pixel data" + where + " is empty");
    MemoryStream mem{code.data(), code.size(), 0};
    const StreamPtr stream = memoryStream(h, mem);
    std::string error;
    const CodecPtr codec = strictDecoder(h, code, error);

    opj_image_t* raw = nullptr;
    const bool header = opj_read_header(stream.get(), codec.get(), &raw);
    std::unique_ptr<opj_image_t, ImageDeleter> image(raw);
    auto broken = [&](const char* stage) {
        fail(h.path, std::string("JPEG 2000 pixel data") + where + ": " + stage + " failed" +
                         (error.empty() ? std::string() : ": " + error) +
                         " (truncated or corrupt codestream?)");
    };
    if (!header || !image) broken("reading the codestream header");
    checkComponent(h, *image, where);
    if (opj_codestream_info_v2_t* cs = opj_get_cstr_info(codec.get())) {
        // Wavelet 0: the irreversible 9/7 transform, lossy whatever the rate.
        if (cs->m_default_tile_info.tccp_info && cs->m_default_tile_info.tccp_info[0].qmfbid == 0)
            info.irreversible = true;
        opj_destroy_cstr_info(&cs);
    }
    if (!opj_decode(codec.get(), stream.get(), image.get())) broken("decoding");
    if (!opj_end_decompress(codec.get(), stream.get())) broken("finishing the decode");
    const OPJ_INT32* s = image->comps[0].data;
    if (!s) broken("decoding");
    storeSamples(h, s, image->comps[0], where, dst, info);
}

} // namespace

bool isJpeg2000(int xfer) { return xfer == EXS_JPEG2000LosslessOnly || xfer == EXS_JPEG2000; }

Jpeg2000Frames decodeJpeg2000(const DicomHeader& h, DcmDataset& ds,
                              const std::vector<int>& frames) {
    const std::vector<Bytes> code = splitFrames(h, readFragments(h, ds));
    const std::size_t frameBytes =
        std::size_t(h.cols) * std::size_t(h.rows) * std::size_t(h.bitsAllocated / 8);
    Jpeg2000Frames out;
    out.words.resize(frameBytes * code.size());
    for (int f : frames)
        decodeFrame(h, code[std::size_t(f)], f, out.words.data() + frameBytes * std::size_t(f),
                    out);
    return out;
}

} // namespace fvr::core::dicom_detail
