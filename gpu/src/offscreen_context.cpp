#include <fvr/gpu/offscreen_context.h>

#include <QGuiApplication>
#include <QOffscreenSurface>
#include <QOpenGLContext>

#include <string>

#include <fvr/gpu/errors.h>

namespace fvr::gpu {

OffscreenContext::OffscreenContext() {
    if (!QGuiApplication::instance()) throw GlError("OpenGL: no QGuiApplication");
    QSurfaceFormat fmt;
    fmt.setRenderableType(QSurfaceFormat::OpenGL);
    fmt.setVersion(4, 3);
    fmt.setProfile(QSurfaceFormat::CoreProfile);
    m_context = std::make_unique<QOpenGLContext>();
    m_context->setFormat(fmt);
    if (!m_context->create())
        throw GlError("OpenGL: could not create a context on platform '" +
                      QGuiApplication::platformName().toStdString() + "'");
    const QSurfaceFormat got = m_context->format();
    if (got.majorVersion() < 4 || (got.majorVersion() == 4 && got.minorVersion() < 3))
        throw GlError("OpenGL: 4.3 needed, got " + std::to_string(got.majorVersion()) + "." +
                      std::to_string(got.minorVersion()) + " on platform '" +
                      QGuiApplication::platformName().toStdString() + "'");
    m_surface = std::make_unique<QOffscreenSurface>();
    m_surface->setFormat(got);
    m_surface->create();
    makeCurrent();
}

OffscreenContext::~OffscreenContext() {
    if (m_context) m_context->doneCurrent();
}

void OffscreenContext::makeCurrent() {
    if (!m_context->makeCurrent(m_surface.get()))
        throw GlError("OpenGL: could not make the context current");
}

} // namespace fvr::gpu
