// The polychromatic spectral sum on the GPU: material frames rendered on the GPU stay
// there and one compute pass evaluates the response's table. Oracle: the CPU's
// SpectralResponse::apply on the same material frames read back (same table, same
// interpolation), and the exact double sum over the bins.
#include <cmath>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/xray/polychromatic_render.h>
#include <fvr/gpu/gpu_renderer.h>

#include "gl_fixture.h"

using namespace fvr::core;
using namespace fvr::gpu;
using fvr::test::GlTest;

namespace {

struct ChestMaterials {
    std::vector<std::unique_ptr<GpuFourierRenderer>> renderers;
    std::vector<const GpuFourierRenderer*> frames;
    std::vector<ProjectionImage> massThickness; ///< read back, g/cm^2
    RenderParams params{ViewFrame::fromDirUp({0.2, -1.0, 0.1}, {0, 0, 1}), {128, 3.5}};
};

/** The chest phantom (64^3) as materials, each rendered on the GPU at M = 128 (AP). */
ChestMaterials renderChest(const std::vector<Material>& materials) {
    static const Volume hu = makeChestPhantomVolume(64);
    PreprocessOptions po;
    po.effort = PlannerEffort::Estimate;
    ChestMaterials out;
    for (const auto& s : preprocessMaterials(hu, {materials, 70.0}, po)) {
        auto r = std::make_unique<GpuFourierRenderer>();
        r->setSpectrum(s);
        r->renderToGpu(out.params);
        ProjectionImage img = r->readback();
        for (float& v : img.pixels) v *= 0.1f; // rho x mm -> g/cm^2, as PolychromaticRenderer
        out.massThickness.push_back(std::move(img));
        out.frames.push_back(r.get());
        out.renderers.push_back(std::move(r));
    }
    return out;
}

} // namespace

TEST_F(GlTest, SpectralSumOnTheGpuEqualsTheCpuTable) {
    for (const auto& materials : {defaultMaterials(), parseMaterials("air,lung,fat,soft,bone")}) {
        ChestMaterials chest = renderChest(materials);
        std::vector<const float*> rhoL;
        for (const auto& img : chest.massThickness) rhoL.push_back(img.pixels.data());
        const std::size_t count = chest.massThickness[0].pixels.size();
        for (double kvp : {70.0, 120.0}) {
            auto response = std::make_shared<const SpectralResponse>(tubeSpectrum(kvp, 2.5),
                                                                     DetectorModel{}, materials);
            std::vector<float> cpu(count, 0.0f);
            response->apply(rhoL, cpu.data(), std::int64_t(count));
            // The sum becomes the frame of the first material's renderer (rendered again below).
            GpuFourierRenderer& out = *chest.renderers.front();
            out.spectralSum(chest.frames, response);
            const std::vector<float> gpu = out.readback().pixels;
            out.renderToGpu(chest.params);
            out.spectralSum(chest.frames, response,
                            GpuFourierRenderer::SpectralOutput::NegativeLog);
            const std::vector<float> gpuLog = out.readback().pixels;
            double worst = 0.0, worstLog = 0.0, worstExact = 0.0, darkest = 1.0;
            for (std::size_t p = 0; p < count; ++p) {
                const double g = -std::log(double(gpu[p])), ref = -std::log(double(cpu[p]));
                worst = std::max(worst, std::abs(g - ref) / (1.0 + ref));
                worstLog = std::max(worstLog, std::abs(double(gpuLog[p]) - ref) / (1.0 + ref));
                std::vector<double> d;
                for (const float* m : rhoL) d.push_back(m[p]);
                worstExact =
                    std::max(worstExact, std::abs(g + std::log(response->exact(d.data()))));
                darkest = std::min(darkest, double(gpu[p]));
            }
            std::printf("[gpu-poly] %zu materials, %g kV: |GPU - CPU| %.2e (I/I0), %.2e "
                        "(-ln written), |GPU - exact| %.2e in -ln(I/I0), darkest I/I0 %.3g\n",
                        materials.size(), kvp, worst, worstLog, worstExact, darkest);
            EXPECT_LT(darkest, 0.05); // the chest attenuates: not a trivial image
            EXPECT_LT(worst, 1e-5) << kvp << " kV";
            EXPECT_LT(worstLog, 1e-5) << kvp << " kV";
            EXPECT_LT(worstExact, 5e-3) << kvp << " kV";
            out.renderToGpu(chest.params);
        }
        // One material's g/cm^2 (the workstation's material view), as read back.
        const int last = int(materials.size()) - 1;
        auto response = std::make_shared<const SpectralResponse>(tubeSpectrum(80.0, 2.5),
                                                                 DetectorModel{}, materials);
        chest.renderers.back()->spectralSum(chest.frames, response,
                                            GpuFourierRenderer::SpectralOutput::Material, last);
        const auto shown = chest.renderers.back()->readback().pixels;
        for (std::size_t p = 0; p < count; ++p)
            ASSERT_FLOAT_EQ(shown[p], rhoL[std::size_t(last)][p]) << p;
        EXPECT_THROW(chest.renderers.back()->spectralSum({chest.frames[0]}, response),
                     SettingsError);
    }
}
