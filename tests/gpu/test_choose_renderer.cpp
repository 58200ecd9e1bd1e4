// gpu::chooseRenderer, the one rule fvr-render and the workstation choose their renderer by: a
// hardware GPU whenever allowed, a software OpenGL only when asked for, and every GPU failure a
// CPU fallback whose reason names what failed.
#include <gtest/gtest.h>

#include <fvr/core/render/preprocess.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/gpu/choose_renderer.h>
#include <fvr/gpu/errors.h>

#include "gl_fixture.h"

using namespace fvr::gpu;

namespace {

std::shared_ptr<const fvr::core::Spectrum> phantomSpectrum() {
    static const auto spectrum = [] {
        fvr::core::PreprocessOptions o;
        o.effort = fvr::core::PlannerEffort::Estimate;
        return fvr::core::preprocess(fvr::core::makeSheppLoganVolume(24), o);
    }();
    return spectrum;
}

/** The tests on the GL test context (llvmpipe where there is no GPU). */
class ChooseRendererGl : public fvr::test::GlTest {};

} // namespace

TEST(ChooseRenderer, NeverGivesTheCpuWithoutTryingTheGpu) {
    bool contextMade = false;
    RendererRequest r;
    r.use = GpuUse::Never;
    r.makeContext = [&] { contextMade = true; };
    const RendererChoice c = chooseRenderer(r);
    EXPECT_FALSE(c.onGpu());
    EXPECT_EQ(c.why, CpuReason::Asked);
    EXPECT_EQ(c.reason, "");
    EXPECT_FALSE(contextMade);
}

// fvr-render's EGL context failing (no display, no driver): the CPU, and the reason carries the
// context's own error in the one fallback text.
TEST(ChooseRenderer, AContextThatFailsGivesTheCpuNamingTheError) {
    for (GpuUse use : {GpuUse::Hardware, GpuUse::Any}) {
        RendererRequest r;
        r.use = use;
        r.makeContext = [] { throw GlError("EGL: no display (test)"); };
        const RendererChoice c = chooseRenderer(r);
        EXPECT_FALSE(c.onGpu());
        EXPECT_EQ(c.why, CpuReason::GpuFailed);
        EXPECT_EQ(c.reason,
                  "GPU backend unavailable (EGL: no display (test)): rendering on the CPU");
    }
}

// On a software OpenGL (llvmpipe here) the default takes the CPU and says which renderer it
// declined; GpuUse::Any takes it. On a hardware GPU both take the GPU.
TEST_F(ChooseRendererGl, SoftwareOpenGlOnlyWhenAllowed) {
    const GlInfo gl = currentGlInfo();
    RendererRequest r;
    r.spectra = {phantomSpectrum(), phantomSpectrum()};
    const RendererChoice byDefault = chooseRenderer(r);
    EXPECT_EQ(byDefault.gl.renderer, gl.renderer);
    if (gl.software()) {
        EXPECT_FALSE(byDefault.onGpu());
        EXPECT_EQ(byDefault.why, CpuReason::SoftwareGl);
        EXPECT_EQ(byDefault.reason, "the GPU is a software renderer (" + gl.renderer +
                                        "): rendering on the CPU, which is faster here");
    } else {
        EXPECT_TRUE(byDefault.onGpu()) << byDefault.reason;
        EXPECT_EQ(byDefault.why, CpuReason::None);
    }
    r.use = GpuUse::Any;
    const RendererChoice any = chooseRenderer(r);
    ASSERT_EQ(any.gpu.size(), 2u) << any.reason; // one renderer per spectrum, each uploaded
    EXPECT_EQ(any.why, CpuReason::None);
    EXPECT_EQ(any.reason, "");
    for (const auto& g : any.gpu) EXPECT_TRUE(g->hasSpectrum());
}

// A renderer that cannot take its spectrum falls back with the renderer's own words, made in
// chooseRenderer or uploaded later (the workstation's path).
TEST_F(ChooseRendererGl, ASpectrumTheGpuRefusesGivesTheCpu) {
    RendererRequest r;
    r.use = GpuUse::Any;
    r.spectra = {phantomSpectrum(), std::make_shared<const fvr::core::Spectrum>()}; // no data
    const RendererChoice c = chooseRenderer(r);
    EXPECT_FALSE(c.onGpu()); // none of them: the materials render together or not at all
    EXPECT_EQ(c.why, CpuReason::GpuFailed);
    EXPECT_EQ(c.reason,
              "GPU backend unavailable (GPU renderer: no spectrum): rendering on the CPU");

    r.spectra.clear(); // one renderer, its spectrum to come
    RendererChoice later = chooseRenderer(r);
    ASSERT_EQ(later.gpu.size(), 1u) << later.reason;
    EXPECT_FALSE(later.gpu.front()->hasSpectrum());
    std::unique_ptr<GpuFourierRenderer> gpu = std::move(later.gpu.front());
    EXPECT_EQ(uploadSpectrum(gpu, phantomSpectrum()), "");
    ASSERT_TRUE(gpu);
    EXPECT_TRUE(gpu->hasSpectrum());
    EXPECT_EQ(uploadSpectrum(gpu, nullptr),
              "GPU backend unavailable (GPU renderer: no spectrum): rendering on the CPU");
    EXPECT_FALSE(gpu);
}
