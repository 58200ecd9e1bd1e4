#pragma once
/** An OpenGL 4.3 core context on an offscreen surface, current on the creating thread: for
 *  fvr-render --backend gpu and the GPU tests. Needs a QGuiApplication (under Xvfb use the xcb
 *  platform: Qt's "offscreen" platform gives only a compatibility context with Mesa). */
#include <memory>

class QOpenGLContext;
class QOffscreenSurface;

namespace fvr::gpu {

class OffscreenContext {
public:
    /** Throws GlError when no 4.3 core context can be created or made current. */
    OffscreenContext();
    ~OffscreenContext();
    QOpenGLContext* context() const { return m_context.get(); }
    void makeCurrent();

private:
    std::unique_ptr<QOpenGLContext> m_context;
    std::unique_ptr<QOffscreenSurface> m_surface;
};

} // namespace fvr::gpu
