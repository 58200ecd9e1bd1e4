#pragma once
/** Locale independent text helpers: ASCII case folding for file names, extensions, header keys
 *  and URL schemes, and whole-string number parsing for header values. The C library's tolower
 *  and strtod follow the process locale, which the workstation sets from the user's environment
 *  (Qt does): these do not, so a file reads the same in every front end and every locale. */
#include <charconv>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>

namespace fvr::core {

/** Whether `c` is ASCII whitespace: space, tab, CR, LF, FF or VT (the C locale's isspace). */
constexpr bool isAsciiSpace(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
}

/** `s` without leading and trailing ASCII whitespace. */
std::string_view trimSpace(std::string_view s);

/** `s` with A-Z mapped to a-z; every other byte (UTF-8 included) as it is. */
std::string asciiLower(std::string_view s);

/** Whether `a` and `b` are equal ignoring ASCII case. */
bool iequals(std::string_view a, std::string_view b);

/** Whether `s` starts with `prefix`, ignoring ASCII case. */
bool istartsWith(std::string_view s, std::string_view prefix);

/** The shortest decimal text that reads back as `v` ("0.2", "1200", "1e-06"), whatever the
 *  locale: numbers in messages and sidecars. */
std::string formatNumber(double v);

/** The number that the whole of `s` spells, in decimal: surrounding whitespace and one leading
 *  '+' are allowed; nothing else (empty text, other characters before or after the number, a
 *  value outside T's range) gives nullopt. Floating-point T also reads exponents, "inf" and
 *  "nan": callers that need a finite value check it. Callers word their own messages (the file,
 *  field, expected and found text). */
template <class T>
std::optional<T> parseNumber(std::string_view s) {
    static_assert(std::is_arithmetic_v<T> && !std::is_same_v<T, bool>,
                  "parseNumber reads integers and floating-point numbers");
    s = trimSpace(s);
    if (!s.empty() && s.front() == '+') {
        s.remove_prefix(1);
        if (!s.empty() && s.front() == '-') return std::nullopt; // "+-1" is no number
    }
    if (s.empty()) return std::nullopt;
    T value{};
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
    if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
    return value;
}

} // namespace fvr::core
