#pragma once
/** Compiling an assembled compute shader into a GL program, the one place that calls the GL
 *  compiler and linker (the renderer and the GPU tests both use it), and binding buffers by name.
 *  Needs a current OpenGL 4.3 context. */
#include <string>

#include <fvr/gpu/bindings.h>
#include <fvr/gpu/shader_source.h>

namespace fvr::gpu {

/** Compiles and links `source` as a compute program and returns the program object (the caller
 *  deletes it). Throws ShaderError naming `name` (the path and defines) and the driver's log with
 *  each message mapped to the original file:line (ShaderSource::mapLog). */
unsigned compileComputeProgram(const ShaderSource& source, const std::string& name);

/** Binds `buffer` as the shader storage buffer at binding point `binding`: the host's only way
 *  to bind one, so every binding is named. */
void bindStorage(Binding binding, unsigned buffer);

} // namespace fvr::gpu
