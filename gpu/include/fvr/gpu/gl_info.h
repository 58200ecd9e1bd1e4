#pragma once
/** What the current OpenGL context offers (logged by GL tests and shown in the about box). */
#include <string>

namespace fvr::gpu {

struct GlInfo {
    std::string vendor, renderer, version;
    int major = 0, minor = 0;
    bool coreProfile = false;
    /** Compute shaders need OpenGL 4.3. */
    bool hasCompute() const { return major > 4 || (major == 4 && minor >= 3); }
};

/** Queries the context current on this thread; returns an empty GlInfo when there is none. */
GlInfo currentGlInfo();

} // namespace fvr::gpu
