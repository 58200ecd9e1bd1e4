#include <fvr/core/pacs/dicom_url.h>

#include <algorithm>
#include <optional>

#include <fvr/core/text.h>

namespace fvr::core::pacs {
namespace {

constexpr std::string_view kScheme = "dicom://";

[[noreturn]] void fail(const std::string& url, const std::string& what) {
    throw PacsError("\"" + url + "\": " + what +
                    " (expected dicom://CALLED_AE@host:port[/STUDY_UID[/SERIES_UID]])");
}

bool isUid(const std::string& s) {
    return !s.empty() && s.size() <= 64 && s.front() != '.' && s.back() != '.' &&
           std::all_of(s.begin(), s.end(),
                       [](char c) { return c == '.' || (c >= '0' && c <= '9'); });
}

int parsePort(const std::string& url, const std::string& text) {
    // Digits only: no sign or spaces inside a URL.
    const bool digits = text.find_first_not_of("0123456789") == std::string::npos;
    const std::optional<int> port = digits ? parseNumber<int>(text) : std::nullopt;
    if (!port || *port < 1 || *port > 65535)
        fail(url, "the port \"" + text + "\" is not a number from 1 to 65535");
    return *port;
}

void parsePath(const std::string& url, const std::string& path, DicomUrl& out) {
    if (path.empty()) return;
    const auto slash = path.find('/');
    out.studyUid = path.substr(0, slash);
    if (slash != std::string::npos) {
        out.seriesUid = path.substr(slash + 1);
        if (!out.seriesUid.empty() && out.seriesUid.back() == '/') out.seriesUid.pop_back();
        if (out.seriesUid.find('/') != std::string::npos)
            fail(url, "more than a study and a series UID in the path");
        if (!out.seriesUid.empty() && !isUid(out.seriesUid))
            fail(url, "the series UID \"" + out.seriesUid +
                          "\" is not a DICOM UID (digits and dots, at most 64)");
    }
    if (!isUid(out.studyUid))
        fail(url, "the study UID \"" + out.studyUid +
                      "\" is not a DICOM UID (digits and dots, at most 64)");
}

} // namespace

bool isDicomUrl(const std::string& text) { return istartsWith(text, kScheme); }

DicomUrl parseDicomUrl(const std::string& url) {
    if (!isDicomUrl(url)) fail(url, "not a dicom:// URL");
    const std::string rest = url.substr(kScheme.size());
    const auto at = rest.find('@');
    if (at == std::string::npos || at == 0) fail(url, "no called AE title before '@'");
    DicomUrl out;
    out.node.calledAe = rest.substr(0, at);
    const auto slash = rest.find('/', at);
    const std::string hostPort =
        rest.substr(at + 1, slash == std::string::npos ? slash : slash - at - 1);
    const auto colon = hostPort.rfind(':');
    out.node.host = hostPort.substr(0, colon);
    if (out.node.host.empty()) fail(url, "no host after '@'");
    if (colon != std::string::npos) out.node.port = parsePort(url, hostPort.substr(colon + 1));
    if (slash != std::string::npos) parsePath(url, rest.substr(slash + 1), out);
    try {
        validate(out.node);
    } catch (const PacsError& e) {
        fail(url, e.what());
    }
    return out;
}

std::string toString(const DicomUrl& url) {
    std::string s =
        "dicom://" + url.node.calledAe + "@" + url.node.host + ":" + std::to_string(url.node.port);
    if (!url.studyUid.empty()) s += "/" + url.studyUid;
    if (!url.seriesUid.empty()) s += "/" + url.seriesUid;
    return s;
}

} // namespace fvr::core::pacs
