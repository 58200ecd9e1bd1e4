#pragma once
/** The shaders of resources/shaders, embedded at build time (gpu/cmake/embed_shaders.cmake). */
#include <cstddef>

namespace fvr::gpu::detail {

struct EmbeddedShader {
    const char* path; ///< relative to resources/shaders, e.g. "fft/rows.comp"
    const char* text;
};
extern const EmbeddedShader kEmbeddedShaders[];
extern const std::size_t kEmbeddedShaderCount;

} // namespace fvr::gpu::detail
