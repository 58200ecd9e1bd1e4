#pragma once
/** Typed GPU errors: callers fall back to the CPU renderer and say why. */
#include <stdexcept>
#include <string>

namespace fvr::gpu {

/** No usable OpenGL 4.3 context, a GL error, or a failed allocation. */
struct GlError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/** The spectrum does not fit in GPU memory or texture limits. */
struct GpuMemoryError : GlError {
    using GlError::GlError;
};

/** A shader failed to compile or link; what() names the shader file and line ("fft/rows.comp:42").
 */
struct ShaderError : GlError {
    using GlError::GlError;
};

} // namespace fvr::gpu
