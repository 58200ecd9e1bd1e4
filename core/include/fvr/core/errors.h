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

/** Writing an output file failed. */
struct WriteError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

} // namespace fvr::core
