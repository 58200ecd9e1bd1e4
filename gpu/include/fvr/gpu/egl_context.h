#pragma once
/** A headless OpenGL 4.3 core context through EGL, current on the creating thread with no
 *  surface: for fvr-render --backend gpu, the GPU benches and the GPU tests. Needs no X server
 *  and no Qt. Prefers a hardware EGL device (EGL_EXT_device_enumeration + EGL_EXT_platform_device;
 *  NVIDIA's show EGL_NV_device_cuda), else Mesa's surfaceless platform (llvmpipe where there is
 *  no GPU). FVR_EGL_DEVICE=N picks device N of eglQueryDevicesEXT, FVR_EGL_DEVICE=surfaceless
 *  the surfaceless platform. */
#include <string>
#include <vector>

namespace fvr::gpu {

/** One EGL device as eglQueryDevicesEXT lists it. */
struct EglDeviceInfo {
    int index = 0;
    std::string extensions; ///< the device's extension string
    std::string name; ///< EGL_RENDERER_EXT where EGL_EXT_device_query_name is offered
    std::string drmFile; ///< EGL_DRM_DEVICE_FILE_EXT where offered ("/dev/dri/card0")
    bool software = false; ///< EGL_MESA_device_software, or no DRM/CUDA device behind it
    bool nvidia = false; ///< EGL_NV_device_cuda
};

class EglContext {
public:
    /** Creates the context and makes it current. Throws GlError naming what is missing (no EGL
     *  client extension, no device, no OpenGL 4.3 core context, no surfaceless support). */
    EglContext();
    ~EglContext();
    EglContext(const EglContext&) = delete;
    EglContext& operator=(const EglContext&) = delete;

    void makeCurrent();
    void doneCurrent();

    /** The EGL devices of this machine (empty when EGL_EXT_device_enumeration is missing). */
    static std::vector<EglDeviceInfo> devices();
    /** The client extensions of EGL (EGL_NO_DISPLAY), empty when there are none. */
    static std::string clientExtensions();

    /** The device index the context runs on, -1 for Mesa's surfaceless platform. */
    int deviceIndex() const { return m_device; }
    /** "EGL device 0 (NVIDIA ...)" or "EGL surfaceless platform". */
    const std::string& description() const { return m_description; }
    /** The display's EGL_VENDOR and EGL_VERSION. */
    const std::string& eglVersion() const { return m_eglVersion; }

private:
    void create();
    void release();

    void* m_display = nullptr;
    void* m_context = nullptr;
    int m_device = -1;
    std::string m_description;
    std::string m_eglVersion;
};

} // namespace fvr::gpu
