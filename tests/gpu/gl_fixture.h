#pragma once
// One QGuiApplication and one offscreen OpenGL 4.3 context for the whole GPU test executable,
// created on first use (never during test discovery, which runs without a display).
#include <QGuiApplication>
#include <memory>

#include <gtest/gtest.h>

#include <fvr/gpu/errors.h>
#include <fvr/gpu/gl_info.h>
#include <fvr/gpu/offscreen_context.h>

namespace fvr::test {

struct GlState {
    std::unique_ptr<QGuiApplication> app;
    std::unique_ptr<fvr::gpu::OffscreenContext> ctx;
};

inline GlState& glState() {
    static GlState state;
    return state;
}

/** Destroys the context, then the application, before static destruction (Qt must not be torn
 *  down after main returns). */
class GlEnvironment : public ::testing::Environment {
public:
    void TearDown() override {
        glState().ctx.reset();
        glState().app.reset();
    }
};
inline ::testing::Environment* const kGlEnvironment =
    ::testing::AddGlobalTestEnvironment(new GlEnvironment);

inline fvr::gpu::OffscreenContext& glContext() {
    static int argc = 1;
    static char name[] = "fvr_gpu_tests";
    static char* argv[] = {name, nullptr};
    auto& app = glState().app;
    auto& ctx = glState().ctx;
    if (!ctx) {
        app = std::make_unique<QGuiApplication>(argc, argv);
        ctx = std::make_unique<fvr::gpu::OffscreenContext>();
        const auto info = fvr::gpu::currentGlInfo();
        std::printf("[gl] GL_RENDERER %s, GL_VERSION %s\n", info.renderer.c_str(),
                    info.version.c_str());
    }
    ctx->makeCurrent();
    return *ctx;
}

class GlTest : public ::testing::Test {
protected:
    void SetUp() override { glContext(); }
};

} // namespace fvr::test
