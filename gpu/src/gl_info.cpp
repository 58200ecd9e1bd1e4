#include <fvr/gpu/gl_info.h>

#include <QOpenGLContext>
#include <QOpenGLFunctions>

namespace fvr::gpu {

GlInfo currentGlInfo() {
    GlInfo info;
    QOpenGLContext* ctx = QOpenGLContext::currentContext();
    if (!ctx) return info;
    QOpenGLFunctions* f = ctx->functions();
    auto str = [&](GLenum e) {
        const auto* s = reinterpret_cast<const char*>(f->glGetString(e));
        return s ? std::string(s) : std::string();
    };
    info.vendor = str(GL_VENDOR);
    info.renderer = str(GL_RENDERER);
    info.version = str(GL_VERSION);
    const QSurfaceFormat fmt = ctx->format();
    info.major = fmt.majorVersion();
    info.minor = fmt.minorVersion();
    info.coreProfile = fmt.profile() == QSurfaceFormat::CoreProfile;
    return info;
}

} // namespace fvr::gpu
