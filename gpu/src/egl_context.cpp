#include <fvr/gpu/egl_context.h>

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include <fvr/gpu/errors.h>
#include <fvr/gpu/gl_info.h>

namespace fvr::gpu {

namespace {

std::string eglErrorName(EGLint e) {
    switch (e) {
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    default:
        return "EGL error 0x" + [e] {
            char buf[16];
            std::snprintf(buf, sizeof buf, "%04x", unsigned(e));
            return std::string(buf);
        }();
    }
}

[[noreturn]] void fail(const std::string& what) {
    throw GlError("EGL: " + what + " (" + eglErrorName(eglGetError()) + ")");
}

bool hasExtension(const char* list, const char* name) {
    if (!list) return false;
    const std::size_t n = std::strlen(name);
    for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
    return false;
}

template <typename Fn>
Fn proc(const char* name) {
    return reinterpret_cast<Fn>(eglGetProcAddress(name));
}

std::vector<EGLDeviceEXT> queryDevices() {
    const auto query = proc<PFNEGLQUERYDEVICESEXTPROC>("eglQueryDevicesEXT");
    // EGL_EXT_device_base is device_enumeration and device_query in one; NVIDIA's libEGL
    // (580) lists only it, so looking for device_enumeration alone found no devices there.
    const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if ((!hasExtension(client, "EGL_EXT_device_enumeration") &&
         !hasExtension(client, "EGL_EXT_device_base")) ||
        !query)
        return {};
    EGLint n = 0;
    if (!query(0, nullptr, &n) || n <= 0) return {};
    std::vector<EGLDeviceEXT> devices(std::size_t(n), nullptr);
    if (!query(n, devices.data(), &n)) return {};
    devices.resize(std::size_t(n));
    return devices;
}

EglDeviceInfo describeDevice(EGLDeviceEXT device, int index) {
    const auto query = proc<PFNEGLQUERYDEVICESTRINGEXTPROC>("eglQueryDeviceStringEXT");
    EglDeviceInfo info;
    info.index = index;
    auto str = [&](EGLint name) {
        const char* s = query ? query(device, name) : nullptr;
        return s ? std::string(s) : std::string();
    };
    info.extensions = str(EGL_EXTENSIONS);
    const char* ext = info.extensions.c_str();
    if (hasExtension(ext, "EGL_EXT_device_query_name")) info.name = str(EGL_RENDERER_EXT);
    if (hasExtension(ext, "EGL_EXT_device_drm")) info.drmFile = str(EGL_DRM_DEVICE_FILE_EXT);
    info.nvidia = hasExtension(ext, "EGL_NV_device_cuda");
    info.software = hasExtension(ext, "EGL_MESA_device_software") ||
                    (!info.nvidia && !hasExtension(ext, "EGL_EXT_device_drm"));
    eglGetError(); // a string a device does not offer is no error of ours
    return info;
}

/** The device FVR_EGL_DEVICE names, else the first NVIDIA device, else the first hardware one;
 *  -1: Mesa's surfaceless platform. */
int chooseDevice(const std::vector<EglDeviceInfo>& devices) {
    if (const char* env = std::getenv("FVR_EGL_DEVICE"); env && *env) {
        if (std::string(env) == "surfaceless") return -1;
        char* end = nullptr;
        const long n = std::strtol(env, &end, 10);
        if (*end != '\0' || n < 0 || n >= long(devices.size()))
            throw GlError("EGL: FVR_EGL_DEVICE=" + std::string(env) + " names no device (" +
                          std::to_string(devices.size()) +
                          " EGL devices, 0-based; or 'surfaceless')");
        return int(n);
    }
    for (const auto& d : devices)
        if (d.nvidia) return d.index;
    for (const auto& d : devices)
        if (!d.software) return d.index;
    return -1;
}

EGLDisplay openDisplay(int device, std::string& description) {
    const auto getDisplay = proc<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
    const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!client || !getDisplay)
        throw GlError("EGL: no EGL client extensions (libEGL without EGL_EXT_platform_base: "
                      "no headless OpenGL here)");
    if (device >= 0) {
        if (!hasExtension(client, "EGL_EXT_platform_device"))
            throw GlError("EGL: EGL_EXT_platform_device is missing (cannot open an EGL device)");
        const auto devices = queryDevices();
        const EglDeviceInfo info = describeDevice(devices[std::size_t(device)], device);
        description = "EGL device " + std::to_string(device) +
                      (info.name.empty() ? "" : " (" + info.name + ")");
        return getDisplay(EGL_PLATFORM_DEVICE_EXT, devices[std::size_t(device)], nullptr);
    }
    if (!hasExtension(client, "EGL_MESA_platform_surfaceless"))
        throw GlError("EGL: no hardware EGL device and no EGL_MESA_platform_surfaceless "
                      "(install Mesa's libegl-mesa0 for software rendering, or a GPU driver)");
    description = "EGL surfaceless platform";
    return getDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
}

/** A config for a desktop OpenGL context (none needed with EGL_KHR_no_config_context). */
EGLConfig chooseConfig(EGLDisplay display, const char* extensions) {
    if (hasExtension(extensions, "EGL_KHR_no_config_context")) return EGL_NO_CONFIG_KHR;
    const EGLint attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE,
                              EGL_PBUFFER_BIT, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint n = 0;
    if (!eglChooseConfig(display, attribs, &config, 1, &n) || n < 1)
        fail("no EGL config renders desktop OpenGL on this display");
    return config;
}

} // namespace

std::string EglContext::clientExtensions() {
    const char* s = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    eglGetError();
    return s ? std::string(s) : std::string();
}

std::vector<EglDeviceInfo> EglContext::devices() {
    std::vector<EglDeviceInfo> out;
    const auto devices = queryDevices();
    for (std::size_t i = 0; i < devices.size(); ++i)
        out.push_back(describeDevice(devices[i], int(i)));
    return out;
}

EglContext::EglContext() {
    try {
        create();
    } catch (...) {
        release();
        throw;
    }
}

void EglContext::create() {
    m_device = chooseDevice(devices());
    EGLDisplay display = openDisplay(m_device, m_description);
    EGLint major = 0, minor = 0;
    if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor))
        fail("could not initialise the display of " + m_description);
    m_display = display;
    m_eglVersion = std::string(eglQueryString(display, EGL_VENDOR)) + " EGL " +
                   eglQueryString(display, EGL_VERSION);
    const char* ext = eglQueryString(display, EGL_EXTENSIONS);
    if (!hasExtension(ext, "EGL_KHR_create_context") ||
        !hasExtension(ext, "EGL_KHR_surfaceless_context"))
        throw GlError("EGL: " + m_description +
                      " lacks EGL_KHR_create_context or EGL_KHR_surfaceless_context");
    if (!eglBindAPI(EGL_OPENGL_API)) fail(m_description + " offers no desktop OpenGL");
    const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION_KHR,
                              4,
                              EGL_CONTEXT_MINOR_VERSION_KHR,
                              3,
                              EGL_CONTEXT_OPENGL_PROFILE_MASK_KHR,
                              EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT_KHR,
                              EGL_NONE};
    m_context = eglCreateContext(display, chooseConfig(display, ext), EGL_NO_CONTEXT, attribs);
    if (m_context == EGL_NO_CONTEXT) {
        m_context = nullptr;
        fail("no OpenGL 4.3 core context on " + m_description);
    }
    makeCurrent();
    const GlInfo info = currentGlInfo();
    if (!info.hasCompute())
        throw GlError("EGL: OpenGL 4.3 needed, " + m_description + " gave " + info.version);
}

EglContext::~EglContext() { release(); }

void EglContext::release() {
    if (m_display) {
        if (eglGetCurrentContext() == m_context)
            eglMakeCurrent(m_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        if (m_context) eglDestroyContext(m_display, m_context);
        // No eglTerminate: displays are one per device, shared by every EglContext on it.
    }
    m_display = m_context = nullptr;
}

void EglContext::makeCurrent() {
    if (!eglMakeCurrent(m_display, EGL_NO_SURFACE, EGL_NO_SURFACE, m_context))
        fail("could not make the context current on " + m_description);
}

void EglContext::doneCurrent() {
    eglMakeCurrent(m_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
}

} // namespace fvr::gpu
