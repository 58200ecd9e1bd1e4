#pragma once
// One headless EGL OpenGL 4.3 context for the whole GPU test executable (no X server, no Qt),
// created on first use (never during test discovery).
#include <cstdio>
#include <memory>

#include <gtest/gtest.h>

#include <fvr/gpu/egl_context.h>
#include <fvr/gpu/errors.h>
#include <fvr/gpu/gl_info.h>

namespace fvr::test {

inline std::unique_ptr<fvr::gpu::EglContext>& glState() {
    static std::unique_ptr<fvr::gpu::EglContext> ctx;
    return ctx;
}

/** Destroys the context before static destruction (the GL driver may be gone by then). */
class GlEnvironment : public ::testing::Environment {
public:
    void TearDown() override { glState().reset(); }
};
inline ::testing::Environment* const kGlEnvironment =
    ::testing::AddGlobalTestEnvironment(new GlEnvironment);

inline fvr::gpu::EglContext& glContext() {
    auto& ctx = glState();
    if (!ctx) {
        ctx = std::make_unique<fvr::gpu::EglContext>();
        const auto info = fvr::gpu::currentGlInfo();
        std::printf("[gl] %s, GL_RENDERER %s, GL_VERSION %s\n", ctx->description().c_str(),
                    info.renderer.c_str(), info.version.c_str());
    }
    ctx->makeCurrent();
    return *ctx;
}

class GlTest : public ::testing::Test {
protected:
    void SetUp() override { glContext(); }
};

} // namespace fvr::test
