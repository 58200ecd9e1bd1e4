#include <fvr/gpu/gl_info.h>

#include <epoxy/gl.h>

#include <dlfcn.h>

#include <fvr/core/text.h>

namespace fvr::gpu {

namespace {
/** `function()` of `library` when that library is already loaded (a context can only be current
 *  through a loaded library), else nullptr. */
const void* callIfLoaded(const char* library, const char* function) {
    void* handle = dlopen(library, RTLD_LAZY | RTLD_NOLOAD);
    if (!handle) return nullptr;
    const void* result = nullptr;
    if (void* sym = dlsym(handle, function)) result = reinterpret_cast<const void* (*)()>(sym)();
    dlclose(handle);
    return result;
}
} // namespace

const void* currentNativeContext() {
    if (const void* c = callIfLoaded("libEGL.so.1", "eglGetCurrentContext")) return c;
    if (const void* c = callIfLoaded("libGLX.so.0", "glXGetCurrentContext")) return c;
    return callIfLoaded("libGL.so.1", "glXGetCurrentContext");
}

bool GlInfo::software() const {
    const std::string r = core::asciiLower(renderer);
    for (const char* name :
         {"llvmpipe", "softpipe", "swrast", "swiftshader", "software rasterizer"})
        if (r.find(name) != std::string::npos) return true;
    return false;
}

GlInfo currentGlInfo() {
    GlInfo info;
    if (!currentNativeContext()) return info;
    auto str = [](GLenum e) {
        const auto* s = reinterpret_cast<const char*>(glGetString(e));
        return s ? std::string(s) : std::string();
    };
    info.vendor = str(GL_VENDOR);
    info.renderer = str(GL_RENDERER);
    info.version = str(GL_VERSION);
    const int v = epoxy_gl_version();
    info.major = v / 10;
    info.minor = v % 10;
    info.desktop = epoxy_is_desktop_gl();
    if (info.desktop && v >= 32) {
        GLint mask = 0;
        glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &mask);
        info.coreProfile = (mask & GL_CONTEXT_CORE_PROFILE_BIT) != 0;
    }
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &info.max3dTextureSize);
    GLint freeKiB[4] = {-1, 0, 0, 0};
    if (epoxy_has_gl_extension("GL_NVX_gpu_memory_info"))
        glGetIntegerv(0x9049, freeKiB); // GL_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX
    else if (epoxy_has_gl_extension("GL_ATI_meminfo"))
        glGetIntegerv(0x87FC, freeKiB); // GL_TEXTURE_FREE_MEMORY_ATI
    info.freeMemoryKiB = freeKiB[0];
    while (glGetError() != GL_NO_ERROR) {}
    return info;
}

} // namespace fvr::gpu
