#pragma once
// What fvr-render's option declarations share across their files (options.cpp, and the cone
// beam's in options_cone.cpp): the number readers, the check that words a core error as
// CLI11's, and the cone-beam declarations and checks.
#include <cmath>
#include <functional>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>
#include <fvr/core/vec3.h>

#include "options.h"

namespace fvr::cli::detail {

using core::SettingsError;

/** A finite number, or nothing. */
inline std::optional<double> toNumber(const std::string& s) {
    const auto v = core::parseNumber<double>(s);
    if (!v || !std::isfinite(*v)) return std::nullopt;
    return v;
}

/** "x,y,z" as three finite numbers, or nothing. */
inline std::optional<core::Vec3> toVec3(const std::string& s) {
    std::vector<double> v;
    std::stringstream ss(s);
    std::string tok;
    while (std::getline(ss, tok, ',')) {
        const auto x = toNumber(tok);
        if (!x) return std::nullopt;
        v.push_back(*x);
    }
    if (v.size() != 3) return std::nullopt;
    return core::Vec3{v[0], v[1], v[2]};
}

/** Checks a value with a core function that throws SettingsError ("what: expected ...");
 *  the message without its "what: " (the option's name takes its place). */
template <class Check>
CLI::Validator coreCheck(Check check) {
    return CLI::Validator(
        [check](std::string& s) -> std::string {
            try {
                check(s);
                return {};
            } catch (const SettingsError& e) {
                const std::string m = e.what();
                const auto colon = m.find(": ");
                return colon != std::string::npos && colon < m.find('\'') ? m.substr(colon + 2) : m;
            }
        },
        "");
}

/** Checks a number: finite, then `ok` (message "<expected>, found <value>"). CLI11 puts the
 *  option's name in front of the message. */
inline CLI::Validator numberCheck(std::function<bool(double)> ok = {}, std::string expected = {}) {
    return CLI::Validator(
        [ok = std::move(ok), expected = std::move(expected)](std::string& s) -> std::string {
            const auto v = toNumber(s);
            if (!v) return "expected a number, found '" + s + "'";
            if (ok && !ok(*v)) return expected + ", found " + s;
            return {};
        },
        "");
}

/** An option whose value a core parser turns into `target` (an enum, optional or not). */
template <class Target, class Parse>
CLI::Option* addParsed(CLI::App& app, const std::string& name, Target& target, Parse parse,
                       const std::string& text, const std::string& help) {
    return app
        .add_option_function<std::string>(
            name, [&target, parse](const std::string& s) { target = parse(s); }, help)
        ->check(coreCheck(parse))
        ->option_text(text);
}

/** A number option (`double` or `std::optional<double>`) checked by numberCheck. */
template <class Target>
CLI::Option* addNumber(CLI::App& app, const std::string& name, Target& target,
                       const std::string& text, const std::string& help,
                       std::function<bool(double)> ok = {}, std::string expected = {}) {
    return app
        .add_option_function<std::string>(
            name, [&target](const std::string& s) { target = *toNumber(s); }, help)
        ->check(numberCheck(std::move(ok), std::move(expected)))
        ->option_text(text);
}

/** The output format of --out's extension; SettingsError for any other. */
inline OutputFormat outputFormat(const std::string& path) {
    const std::string ext = core::asciiLower(std::filesystem::path(path).extension().string());
    if (ext == ".npy") return OutputFormat::Npy;
    if (ext == ".pfm") return OutputFormat::Pfm;
    if (ext == ".png") return OutputFormat::Png;
    if (ext == ".dcm") return OutputFormat::Dicom;
    throw SettingsError("--out: unknown output format '" + ext +
                        "' (expected .npy, .pfm, .png or .dcm)");
}

/** The cone beam's options (options_cone.cpp): the camera, --geometry-from, and the treatment
 *  beams (IEC 61217, RT Plans). */
void declareCone(CLI::App& app, ConeOptions& c);
void declareBeam(CLI::App& app, ConeOptions& c);
/** The cone-beam checks that need the parsed command line: cone options without --geometry
 *  cone, parallel options with it, the camera's own checks and the RT Plan read (before any
 *  input loads). */
void checkGeometry(const CLI::App& app, Options& o);

} // namespace fvr::cli::detail
