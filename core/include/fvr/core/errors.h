#pragma once
/** Typed errors raised at input boundaries. Every message names the file (or source), the field
 *  or tag, and what was expected versus what was found, so that callers can show it as is. */
#include <stdexcept>
#include <string>

namespace fvr::core {

/** Base of every error caused by bad input (files, command-line values, settings). */
struct InputError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/** A volume or image file could not be read: missing/invalid header field, size mismatch,
 *  unsupported element type, truncated data. */
struct LoadError : InputError {
    using InputError::InputError;
};

/** A requested rendering or preprocessing setting is invalid (slice size, kernel, factor...). */
struct SettingsError : InputError {
    using InputError::InputError;
};

/** A background job was cancelled by its caller. */
struct Cancelled : std::runtime_error {
    Cancelled() : std::runtime_error("cancelled") {}
};

/** A frame could not be rendered as asked: its image would hold values that are not finite
 *  (float overflow), which no output may carry silently. */
struct RenderError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/** `s` for a message, in single quotes, with NUL shown as \0 and other control bytes as \xNN
 *  (a message cut at an embedded NUL would hide the rest of the value). */
inline std::string quotedWithEscapes(const std::string& s) {
    static constexpr char kHex[] = "0123456789abcdef";
    std::string out = "'";
    for (const char ch : s) {
        const auto c = static_cast<unsigned char>(ch);
        if (c == 0)
            out += "\\0";
        else if (c < 0x20 || c == 0x7f)
            out += std::string("\\x") + kHex[c >> 4] + kHex[c & 15];
        else
            out += ch;
    }
    return out + "'";
}

/** Throws SettingsError "<what> holds a NUL character: '<value, escaped>'" when `s` has one: a
 *  path or value passed on as a C string would silently lose everything after it. */
inline void refuseNul(const std::string& s, const std::string& what) {
    if (s.find('\0') != std::string::npos)
        throw SettingsError(what + " holds a NUL character: " + quotedWithEscapes(s));
}

/** Writing an output file failed. */
struct WriteError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

} // namespace fvr::core
