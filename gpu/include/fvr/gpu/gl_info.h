#pragma once
/** What the current OpenGL context offers (logged by GL tests and shown in the about box). */
#include <string>

namespace fvr::gpu {

struct GlInfo {
    std::string vendor, renderer, version;
    int major = 0, minor = 0;
    bool coreProfile = false;
    bool desktop = false; ///< desktop OpenGL (not OpenGL ES)
    int max3dTextureSize = 0;
    /** Free GPU memory in KiB where the driver reports it (GL_NVX_gpu_memory_info,
     *  GL_ATI_meminfo), else -1. */
    long long freeMemoryKiB = -1;
    /** A software renderer (Mesa llvmpipe, softpipe or swrast, SwiftShader): slower than the
     *  CPU renderer, so the automatic choices do not take it. */
    bool software() const;
    /** Compute shaders need OpenGL 4.3. */
    bool hasCompute() const { return desktop && (major > 4 || (major == 4 && minor >= 3)); }
};

/** The native context (EGL or GLX) current on this thread, or nullptr when there is none: every
 *  GL call of fvr::gpu needs one. Works whichever library created it (Qt, EglContext). */
const void* currentNativeContext();

/** Queries the context current on this thread; returns an empty GlInfo when there is none. */
GlInfo currentGlInfo();

} // namespace fvr::gpu
