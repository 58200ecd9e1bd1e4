// DICOM text to UTF-8 (dicom_charset.h): DCMTK's converter, the ISO 2022 Japanese sets through
// the C library's ISO-2022-JP-2, U+FFFD for what neither can convert.
#include "dicom_charset.h"

#include <dcmtk/config/osconfig.h> // first DCMTK include
#include <dcmtk/dcmdata/dcspchrs.h>
#include <dcmtk/dcmdata/dctk.h>

#include <iconv.h>

#include <cerrno>
#include <cstring>
#include <vector>

namespace fvr::core::dicom_detail {
namespace {

/** The VRs whose values SpecificCharacterSet governs (PS3.5 6.1.2.3). */
bool textVr(DcmEVR vr) {
    return vr == EVR_SH || vr == EVR_LO || vr == EVR_ST || vr == EVR_LT || vr == EVR_UT ||
           vr == EVR_UC || vr == EVR_PN;
}

/** Where the escape state of ISO 2022 returns to the initial one (PS3.5 6.1.2.5.3), as DCMTK
 *  has them: components and groups of a name, values, lines of a text. */
const char* delimitersOf(DcmEVR vr) {
    if (vr == EVR_PN) return "\\^=";
    if (vr == EVR_ST || vr == EVR_LT || vr == EVR_UT) return "\r\n\t\f";
    return "\\";
}

bool plainAscii(const OFString& s) {
    for (std::size_t i = 0; i < s.length(); ++i) {
        const unsigned char c = static_cast<unsigned char>(s[i]);
        if (c >= 0x80 || c == 0x1b) return false;
    }
    return true;
}

std::string trimmed(std::string s) {
    const auto b = s.find_first_not_of(' ');
    if (b == std::string::npos) return "";
    return s.substr(b, s.find_last_not_of(' ') - b + 1);
}

/** Whether `charset` names only the ISO 2022 Japanese sets (and the default ASCII), which the
 *  C library decodes as ISO-2022-JP-2 (ESC $ B, ESC $ ( D, ESC ( B). */
bool japaneseIso2022(const std::string& charset) {
    bool japanese = false;
    std::size_t from = 0;
    while (from <= charset.size()) {
        std::size_t to = charset.find('\\', from);
        if (to == std::string::npos) to = charset.size();
        const std::string term = trimmed(charset.substr(from, to - from));
        if (term == "ISO 2022 IR 87" || term == "ISO 2022 IR 159")
            japanese = true;
        else if (!term.empty() && term != "ISO 2022 IR 6")
            return false;
        from = to + 1;
    }
    return japanese;
}

/** A value in ISO-2022-JP-2 to UTF-8 with iconv; false when it is not such text. The whole value
 *  at once: a JIS byte may be '^' or '=', and a writer returns to ASCII before each delimiter
 *  (PS3.5 6.1.2.5.3), so the state needs no reset there. */
bool iso2022JpToUtf8(const std::string& in, std::string& out) {
    const iconv_t cd = ::iconv_open("UTF-8", "ISO-2022-JP-2");
    if (cd == reinterpret_cast<iconv_t>(-1)) return false;
    std::vector<char> src(in.begin(), in.end());
    std::vector<char> dst(in.size() * 4 + 16);
    char* inPtr = src.data();
    std::size_t inLeft = src.size();
    char* outPtr = dst.data();
    std::size_t outLeft = dst.size();
    bool ok = ::iconv(cd, &inPtr, &inLeft, &outPtr, &outLeft) != static_cast<std::size_t>(-1) &&
              ::iconv(cd, nullptr, nullptr, &outPtr, &outLeft) != static_cast<std::size_t>(-1);
    ::iconv_close(cd);
    if (ok) out.assign(dst.data(), dst.size() - outLeft);
    return ok;
}

/** The element's name for a message: "PatientName (0010,0010)". */
std::string elementName(const DcmElement& e) {
    DcmTag tag(e.getTag());
    return std::string(tag.getTagName()) + " " + tag.toString().c_str();
}

} // namespace

std::string validUtf8(std::string_view text, bool* replaced) {
    static const char kReplacement[] = "\xEF\xBF\xBD";
    std::string out;
    out.reserve(text.size());
    bool any = false;
    std::size_t i = 0;
    while (i < text.size()) {
        const unsigned char c = static_cast<unsigned char>(text[i]);
        int n = c < 0x80                   ? 1
                : (c >= 0xC2 && c <= 0xDF) ? 2
                : (c >= 0xE0 && c <= 0xEF) ? 3
                : (c >= 0xF0 && c <= 0xF4) ? 4
                                           : 0;
        bool good = n > 0 && i + n <= text.size();
        for (int k = 1; good && k < n; ++k)
            good = (static_cast<unsigned char>(text[i + k]) & 0xC0) == 0x80;
        if (good && n >= 3) { // no overlong forms, surrogates or code points past U+10FFFF
            const unsigned char d = static_cast<unsigned char>(text[i + 1]);
            good = !(c == 0xE0 && d < 0xA0) && !(c == 0xED && d >= 0xA0) &&
                   !(c == 0xF0 && d < 0x90) && !(c == 0xF4 && d >= 0x90);
        }
        if (good) {
            out.append(text.substr(i, n));
            i += n;
        } else {
            out += kReplacement;
            any = true;
            ++i;
        }
    }
    if (replaced) *replaced = any;
    return out;
}

std::string convertTextToUtf8(DcmItem& item, const std::string& charset) {
    std::vector<DcmElement*> texts; // the elements with bytes to convert
    for (unsigned long i = 0; i < item.card(); ++i) {
        DcmElement* e = item.getElement(i);
        OFString value;
        if (e && textVr(e->ident()) && e->getTag() != DCM_SpecificCharacterSet &&
            e->getOFStringArray(value).good() && !plainAscii(value))
            texts.push_back(e);
    }
    const std::string set = trimmed(charset);
    const bool utf8Already = set == "ISO_IR 192";
    DcmSpecificCharacterSet converter;
    const bool dcmtk = !texts.empty() && !utf8Already && !set.empty() &&
                       converter.selectCharacterSet(set.c_str(), "ISO_IR 192").good();
    const bool japanese = !dcmtk && japaneseIso2022(set);
    std::vector<std::string> failed;
    for (DcmElement* e : texts) {
        OFString raw;
        e->getOFStringArray(raw);
        const std::string value(raw.c_str(), raw.length());
        std::string out;
        bool ok = false;
        if (dcmtk) {
            OFString converted;
            ok = converter.convertString(raw, converted, delimitersOf(e->ident())).good();
            if (ok) out.assign(converted.c_str(), converted.length());
        } else if (japanese) {
            ok = iso2022JpToUtf8(value, out);
        } else if (utf8Already || set.empty()) {
            // Declared UTF-8, or undeclared bytes beyond ASCII (against the standard, but
            // writers do it with UTF-8): kept where they are UTF-8.
            bool replaced = false;
            out = validUtf8(value, &replaced);
            ok = !replaced;
        }
        if (!ok) {
            out = validUtf8(value);
            failed.push_back(elementName(*e));
        }
        if (out != value) e->putOFStringArray(OFString(out.c_str(), out.size()));
    }
    if (!set.empty() && !utf8Already)
        item.putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 192");
    if (failed.empty()) return "";
    std::string names;
    for (const std::string& n : failed) names += (names.empty() ? "" : ", ") + n;
    const std::string why =
        set.empty()   ? "bytes beyond ASCII that are not UTF-8, and no SpecificCharacterSet "
                        "(0008,0005) says what they are"
        : utf8Already ? "bytes that are not UTF-8 under SpecificCharacterSet \"ISO_IR 192\""
                      : "text that cannot be converted from SpecificCharacterSet \"" + set +
                            "\" to UTF-8 (bytes not of that set, or a set no converter here knows)";
    return names + ": " + why + "; each byte that is not UTF-8 is shown as U+FFFD";
}

std::string convertTextToUtf8(DcmItem& item) {
    OFString charset;
    item.findAndGetOFStringArray(DCM_SpecificCharacterSet, charset);
    return convertTextToUtf8(item, std::string(charset.c_str(), charset.length()));
}

} // namespace fvr::core::dicom_detail
