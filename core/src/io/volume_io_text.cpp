// Volume loaders: the messages and the locale independent text parsing they share.
#include "volume_io_internal.h"

#include <algorithm>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <fvr/core/errors.h>

namespace fvr::core::detail {

// ------------------------------------------------------------------------------------------------
// Messages

[[noreturn]] void fail(const fs::path& file, std::string_view field, const std::string& detail) {
    std::string msg = file.string();
    msg += ": ";
    msg += field;
    msg += ": ";
    msg += detail;
    throw LoadError(msg);
}

/** A header value quoted for a message: at most 80 characters, control bytes shown as '?'. */
std::string quoteValue(std::string_view s) {
    std::string out = "'";
    const std::size_t n = std::min<std::size_t>(s.size(), 80);
    for (std::size_t i = 0; i < n; ++i) {
        const auto c = static_cast<unsigned char>(s[i]);
        out += (c >= 0x20 && c < 0x7f) ? char(c) : '?';
    }
    if (s.size() > n) out += "...";
    out += "'";
    return out;
}

std::string dimsText(const std::vector<std::int64_t>& d) {
    std::string s;
    for (std::size_t i = 0; i < d.size(); ++i) s += (i ? " x " : "") + std::to_string(d[i]);
    return s;
}

const char* typeName(ElementType t) {
    switch (t) {
    case ElementType::Int8: return "int8";
    case ElementType::UInt8: return "uint8";
    case ElementType::Int16: return "int16";
    case ElementType::UInt16: return "uint16";
    case ElementType::Int32: return "int32";
    case ElementType::UInt32: return "uint32";
    case ElementType::Int64: return "int64";
    case ElementType::UInt64: return "uint64";
    case ElementType::Float32: return "float32";
    case ElementType::Float64: return "float64";
    }
    return "unknown";
}

// ------------------------------------------------------------------------------------------------
// Text helpers (locale independent: text.h's parseNumber and asciiLower, never strtod/tolower)

std::vector<std::string_view> splitWords(std::string_view s) {
    std::vector<std::string_view> words;
    std::size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && isAsciiSpace(s[i])) ++i;
        std::size_t j = i;
        while (j < s.size() && !isAsciiSpace(s[j])) ++j;
        if (j > i) words.push_back(s.substr(i, j - i));
        i = j;
    }
    return words;
}

std::optional<bool> parseBool(std::string_view s) {
    const std::string l = asciiLower(trimSpace(s));
    if (l == "true" || l == "1" || l == "yes") return true;
    if (l == "false" || l == "0" || l == "no") return false;
    return std::nullopt;
}

bool endsWith(std::string_view s, std::string_view suffix) {
    return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

/** The volume name: the file name without .gz and the format extension. */
std::string volumeName(const fs::path& path) {
    std::string name = path.filename().string();
    const std::string l = asciiLower(name);
    for (const char* ext : {".nii.gz", ".nii", ".mhd", ".mha"}) {
        if (endsWith(l, ext)) return name.substr(0, name.size() - std::strlen(ext));
    }
    return path.stem().string();
}

} // namespace fvr::core::detail
