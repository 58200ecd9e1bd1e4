// GPU renderer on a real OpenGL 4.3 context (headless EGL; Mesa llvmpipe where no GPU): the inverse
// transforms against FFTW in double, projections against the CPU renderer, every shader.
#include <epoxy/gl.h>

#include <complex>
#include <random>
#include <set>

#include <fftw3.h>
#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/gpu/bindings.h>
#include <fvr/gpu/gpu_renderer.h>
#include <fvr/gpu/shader_program.h>
#include <fvr/gpu/shader_source.h>

#include "gl_fixture.h"
#include "image_metrics.h"
#include "test_support.h"

using namespace fvr::core;
using namespace fvr::gpu;
using fvr::test::GlTest;

namespace {

struct ErrorStats {
    double maxRel = 0, rmsRel = 0;
};

ErrorStats relErrors(const std::vector<std::complex<double>>& ref,
                     const std::vector<std::complex<double>>& got) {
    double maxAbs = 0, maxErr = 0, e2 = 0, r2 = 0;
    for (std::size_t i = 0; i < ref.size(); ++i) {
        maxAbs = std::max(maxAbs, std::abs(ref[i]));
        maxErr = std::max(maxErr, std::abs(got[i] - ref[i]));
        e2 += std::norm(got[i] - ref[i]);
        r2 += std::norm(ref[i]);
    }
    return {maxErr / maxAbs, std::sqrt(e2 / r2)};
}

std::shared_ptr<const Spectrum> spectrumOf(const Volume& v, TransformKind t, double over) {
    PreprocessOptions o;
    o.effort = PlannerEffort::Estimate;
    o.transform = t;
    o.oversampling = over;
    o.mapping = ValueMapping::Mu;
    return preprocess(v, o);
}

} // namespace

TEST_F(GlTest, EveryShaderCompiles) {
    GpuFourierRenderer r;
    for (int M : {64, 512, 2048})
        EXPECT_EQ(r.compileAll(M), 42) << "M " << M; // + the spectral sum for 1..5 materials
}

TEST_F(GlTest, CompileErrorsNameTheShaderFileAndLine) {
    std::map<std::string, std::string> files{
        {"bad.comp", "#version 430\nlayout(local_size_x = 1) in;\n#include \"inc.glsl\"\nvoid "
                     "main() { f(); }\n"},
        {"inc.glsl", "float f() {\n  return undefinedThing;\n}\n"}};
    auto reader = [&](const std::string& p) -> std::optional<std::string> {
        auto it = files.find(p);
        return it == files.end() ? std::nullopt : std::optional<std::string>(it->second);
    };
    const auto src = ShaderSource::assemble("bad.comp", {}, reader);
    try {
        glDeleteProgram(compileComputeProgram(src, "bad.comp"));
        FAIL() << "bad.comp compiled";
    } catch (const ShaderError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("shader bad.comp failed to compile"), std::string::npos) << what;
        EXPECT_NE(what.find("inc.glsl:2"), std::string::npos) << what;
    }
}

// The compiler's own view of each program's interface: every storage block, the display image and
// the spectrum's sampler sit at the binding point the host binds them to (fvr/gpu/bindings.h).
TEST_F(GlTest, CompiledProgramsBindWhereTheHostBinds) {
    const std::map<std::string, Binding> blocks{
        {"SliceOut", Binding::PassOutput},
        {"RowsIn", Binding::PassInput},
        {"RowsOut", Binding::PassOutput},
        {"ColsIn", Binding::PassInput},
        {"ColsOut", Binding::PassOutput},
        {"TIn", Binding::PassInput},
        {"HOut", Binding::PassOutput},
        {"ImageIn", Binding::PassInput},
        {"Out", Binding::PassOutput},
        {"Table", Binding::SpectralTable},
        {"TwiddleBuffer", Binding::Twiddles},
        {"KernelTableBuffer", Binding::KernelTable},
        {"KernelDerivativeBuffer", Binding::KernelDerivative},
        {"FilterAxisBuffer", Binding::FilterAxis},
        {"M0", materialBinding(0)},
        {"M1", materialBinding(1)},
        {"M2", materialBinding(2)},
        {"M3", materialBinding(3)},
        {"M4", materialBinding(4)},
        {"ConeOut", Binding::PassOutput},
        {"ConeViews", Binding::PassInput}};
    const std::vector<std::pair<std::string, ShaderSource::Defines>> programs{
        {"slice/slice.comp", {{"TAPS", "4"}, {"DEPTH_CUE", "1"}}},
        {"fft/rows.comp", {{"MAX_M", "64"}, {"WG_SIZE", "32"}}},
        {"fft/rows.comp",
         {{"MAX_M", "64"}, {"WG_SIZE", "32"}, {"TAPS", "2"}, {"FUSED_SLICE", "1"}}},
        {"fft/cols.comp",
         {{"MAX_M", "64"}, {"WG_SIZE", "32"}, {"OUTPUT_REAL", "1"}, {"FUSED_DISPLAY", "1"}}},
        {"fft/hartley_correct.comp", {{"FUSED_DISPLAY", "1"}}},
        {"display/display.comp", {}},
        {"xray/spectral_sum.comp", {{"MATERIALS", "5"}}},
        {"cone/cone_ray.comp", {{"MODEL", "1"}, {"HW_FILTER", "1"}, {"SKIP_EMPTY", "1"}}}};
    std::set<std::string> seen;
    int images = 0, samplers = 0;
    for (const auto& [path, defines] : programs) {
        const auto src = ShaderSource::assemble(path, defines, ShaderSource::defaultReader());
        const GLuint prog = compileComputeProgram(src, path);
        GLint count = 0;
        glGetProgramInterfaceiv(prog, GL_SHADER_STORAGE_BLOCK, GL_ACTIVE_RESOURCES, &count);
        for (GLint i = 0; i < count; ++i) {
            char name[64] = {0};
            glGetProgramResourceName(prog, GL_SHADER_STORAGE_BLOCK, GLuint(i), sizeof name, nullptr,
                                     name);
            const GLenum prop = GL_BUFFER_BINDING;
            GLint bound = -1;
            glGetProgramResourceiv(prog, GL_SHADER_STORAGE_BLOCK, GLuint(i), 1, &prop, 1, nullptr,
                                   &bound);
            ASSERT_TRUE(blocks.count(name)) << path << ": storage block " << name;
            EXPECT_EQ(bound, GLint(point(blocks.at(name)))) << path << ": " << name;
            seen.insert(name);
        }
        for (const auto& [uniform, unit] :
             {std::pair{"displayOut", point(ImageUnit::Display)},
              std::pair{"uSpectrum", point(TextureUnit::Spectrum)},
              std::pair{"uVolume", point(TextureUnit::Volume)},
              std::pair{"uOccupancy", point(TextureUnit::Occupancy)}}) {
            const GLint loc = glGetUniformLocation(prog, uniform);
            if (loc < 0) continue;
            GLint value = -1;
            glGetUniformiv(prog, loc, &value);
            EXPECT_EQ(value, GLint(unit)) << path << ": " << uniform;
            ++(std::string(uniform) == "displayOut" ? images : samplers);
        }
        glDeleteProgram(prog);
    }
    EXPECT_EQ(seen.size(), blocks.size()) << "a storage block above is in no program";
    EXPECT_EQ(images, 3);
    EXPECT_EQ(samplers, 4);
}

TEST_F(GlTest, InverseFftMatchesFftwDouble) {
    GpuFourierRenderer r;
    std::mt19937 rng(5);
    std::normal_distribution<double> g;
    for (int M : {64, 128, 256, 512, 1024, 2048}) { // 2048: several butterflies per thread
        std::vector<std::complex<float>> in(std::size_t(M) * M);
        std::vector<fftw_complex> din(in.size()), dout(in.size());
        for (std::size_t i = 0; i < in.size(); ++i) {
            in[i] = {float(g(rng)), float(g(rng))};
            din[i][0] = in[i].real();
            din[i][1] = in[i].imag();
        }
        fftw_plan p = fftw_plan_dft_2d(M, M, din.data(), dout.data(), FFTW_BACKWARD, FFTW_ESTIMATE);
        fftw_execute(p);
        fftw_destroy_plan(p);
        const auto out = r.inverseFft2D(in, M);
        std::vector<std::complex<double>> ref(in.size()), got(in.size());
        for (std::size_t i = 0; i < in.size(); ++i) {
            ref[i] = {dout[i][0], dout[i][1]};
            got[i] = out[i];
        }
        const auto e = relErrors(ref, got);
        std::printf("[gpu fft] M %4d max rel %.2e rms rel %.2e\n", M, e.maxRel, e.rmsRel);
        EXPECT_LT(e.maxRel, 2e-6) << "M " << M;
        EXPECT_LT(e.rmsRel, 5e-7) << "M " << M;
    }
}

TEST_F(GlTest, InverseFhtMatchesDoubleHartley) {
    GpuFourierRenderer r;
    std::mt19937 rng(6);
    std::normal_distribution<double> g;
    for (int M : {64, 256, 1024}) {
        std::vector<float> in(std::size_t(M) * M);
        std::vector<fftw_complex> din(in.size()), dout(in.size());
        for (std::size_t i = 0; i < in.size(); ++i) {
            in[i] = float(g(rng));
            din[i][0] = in[i];
            din[i][1] = 0;
        }
        // Oracle: the 2D Hartley transform of real data is Re F - Im F (FFTW, double).
        fftw_plan p = fftw_plan_dft_2d(M, M, din.data(), dout.data(), FFTW_FORWARD, FFTW_ESTIMATE);
        fftw_execute(p);
        fftw_destroy_plan(p);
        const auto out = r.inverseFht2D(in, M);
        std::vector<std::complex<double>> ref(in.size()), got(in.size());
        for (std::size_t i = 0; i < in.size(); ++i) {
            ref[i] = dout[i][0] - dout[i][1];
            got[i] = out[i];
        }
        const auto e = relErrors(ref, got);
        std::printf("[gpu fht] M %4d max rel %.2e rms rel %.2e\n", M, e.maxRel, e.rmsRel);
        EXPECT_LT(e.maxRel, 2e-6) << "M " << M;
        EXPECT_LT(e.rmsRel, 5e-7) << "M " << M;
    }
}

TEST_F(GlTest, ProjectionsMatchCpuRendererOnPhantom) {
    const Volume v = makeSheppLoganVolume(48);
    const ViewFrame views[] = {ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}),
                               ViewFrame::fromDirUp({1, 0, 0}, {0, 0, 1}),
                               ViewFrame::fromDirUp({-0.4, 0.8, -0.45}, {0, 0, 1})};
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        auto s = spectrumOf(v, t, 1.5);
        CpuFourierRenderer cpu(s, 2);
        GpuFourierRenderer gpu;
        gpu.setSpectrum(s);
        for (bool fuse : {true, false}) {
            gpu.setFuseSlice(fuse);
            for (Kernel k : allKernels())
                for (int M : {64, 128})
                    for (const auto& view : views) {
                        const RenderParams p{view, {M, defaultPixelSize(v.dims, v.spacing, M)}, k};
                        const auto a = cpu.render(p);
                        const auto b = gpu.render(p);
                        const auto c = fvr::test::compare(b.pixels, a.pixels);
                        EXPECT_GT(c.psnr, 90.0) << transformName(t) << " " << kernelName(k) << " M "
                                                << M << " fused " << fuse;
                    }
        }
    }
}

TEST_F(GlTest, DeapodizedKaiserBesselMatchesCpu) {
    const Volume v = makeSheppLoganVolume(48);
    const ViewFrame views[] = {ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}),
                               ViewFrame::fromDirUp({-0.4, 0.8, -0.45}, {0, 0, 1})};
    for (auto t : {TransformKind::Fft, TransformKind::Fht})
        for (double over : {1.25, 2.0})
            for (Kernel k : {Kernel::KaiserBessel4, Kernel::KaiserBessel6}) {
                PreprocessOptions o;
                o.effort = PlannerEffort::Estimate;
                o.transform = t;
                o.oversampling = over;
                o.mapping = ValueMapping::Mu;
                o.deapodizeFor = k;
                auto s = preprocess(v, o);
                CpuFourierRenderer cpu(s, 2);
                GpuFourierRenderer gpu;
                gpu.setSpectrum(s);
                for (bool fuse : {true, false}) {
                    gpu.setFuseSlice(fuse);
                    for (const auto& view : views) {
                        const RenderParams p{
                            view, {128, defaultPixelSize(v.dims, v.spacing, 128)}, k};
                        const auto c =
                            fvr::test::compare(gpu.render(p).pixels, cpu.render(p).pixels);
                        std::printf("[gpu vs cpu] deapodized %s %s oversampling %.2f fused %d PSNR "
                                    "%.1f dB\n",
                                    transformName(t), kernelName(k), over, int(fuse), c.psnr);
                        EXPECT_GT(c.psnr, 90.0)
                            << transformName(t) << " " << kernelName(k) << " " << over;
                    }
                }
                // The spectrum was made for k: the GPU renderer refuses another kernel too.
                EXPECT_THROW(
                    gpu.render(
                        {views[0], {64, defaultPixelSize(v.dims, v.spacing, 64)}, Kernel::Linear}),
                    SettingsError);
            }
}

TEST_F(GlTest, ProjectionMatchesCpuOnRealVolume) {
    FVR_REQUIRE_DATA("volumes/headsq/headsq.mhd");
    const Volume v = loadVolume(fvr::test::sharedData() / "volumes/headsq/headsq.mhd");
    const ViewFrame view = ViewFrame::fromDirUp({0.3, 0.9, 0.3}, {0, 0, 1});
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        auto s = spectrumOf(v, t, 1.0);
        CpuFourierRenderer cpu(s, 2);
        GpuFourierRenderer gpu;
        gpu.setSpectrum(s);
        for (Kernel k : {Kernel::Linear, Kernel::CatmullRom, Kernel::Sinc4}) {
            const RenderParams p{view, {256, defaultPixelSize(v.dims, v.spacing, 256)}, k};
            const auto c = fvr::test::compare(gpu.render(p).pixels, cpu.render(p).pixels);
            std::printf("[gpu vs cpu] headsq %s %s PSNR %.1f dB\n", transformName(t), kernelName(k),
                        c.psnr);
            EXPECT_GT(c.psnr, 90.0);
        }
    }
}

TEST_F(GlTest, HalfPrecisionSpectrumCostIsMeasured) {
    const Volume v = makeSheppLoganVolume(48);
    auto s = spectrumOf(v, TransformKind::Fft, 2.0);
    const EllipsoidPhantom ph = EllipsoidPhantom::sheppLogan3D(256.0);
    const ViewFrame view = ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0});
    const RenderParams p{view, {128, defaultPixelSize(v.dims, v.spacing, 128)}, Kernel::CatmullRom};
    const auto truth = ph.project(view, p.image, ValueMapping::Mu, v.dims, v.spacing);
    GpuFourierRenderer gpu;
    gpu.setSpectrum(s, SpectrumPrecision::Float32);
    const auto full = gpu.render(p);
    const std::size_t bytes32 = gpu.spectrumTextureBytes();
    gpu.setSpectrum(s, SpectrumPrecision::Float16);
    const auto half = gpu.render(p);
    EXPECT_EQ(gpu.spectrumTextureBytes() * 2, bytes32);
    const double vsFull = fvr::test::compare(half.pixels, full.pixels).psnr;
    const double psnr32 = fvr::test::compare(full.pixels, truth.pixels).psnr;
    const double psnr16 = fvr::test::compare(half.pixels, truth.pixels).psnr;
    std::printf("[fp16] vs fp32 %.1f dB; vs analytic fp32 %.2f dB, fp16 %.2f dB\n", vsFull, psnr32,
                psnr16);
    EXPECT_GT(vsFull, 55.0);
    EXPECT_GT(psnr16, psnr32 - 0.5);
}

TEST_F(GlTest, TooLargeSpectrumIsRefusedWithSizes) {
    // Twice the context's 3D texture limit along x (llvmpipe: 2048, an H100: 16384), so the
    // refusal does not depend on the device; a few hundred KiB of host memory.
    GLint max3d = 0;
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &max3d);
    ASSERT_GT(max3d, 0);
    const std::int64_t n = 2 * std::int64_t(max3d);
    auto s = std::make_shared<Spectrum>();
    s->kind = TransformKind::Fht;
    s->padded = {n, 2, 2};
    s->volumeDims = {n, 2, 2};
    s->data = allocateFftw(s->floatCount());
    GpuFourierRenderer gpu;
    try {
        gpu.setSpectrum(s);
        FAIL() << "expected GpuMemoryError";
    } catch (const GpuMemoryError& e) {
        EXPECT_NE(std::string(e.what()).find(std::to_string(n)), std::string::npos) << e.what();
    }
    EXPECT_FALSE(gpu.hasSpectrum());
}

TEST_F(GlTest, DisplayTextureAndTimes) {
    const Volume v = makeSheppLoganVolume(32);
    GpuFourierRenderer gpu;
    gpu.setSpectrum(spectrumOf(v, TransformKind::Fft, 1.0));
    gpu.renderToGpu({ViewFrame{}, {128, defaultPixelSize(v.dims, v.spacing, 128)}, Kernel::Linear});
    EXPECT_NE(gpu.displayTexture({0.0, 100.0, false}), 0u);
    const auto t = gpu.lastTimes();
    EXPECT_GT(t.totalMs, 0.0);
    EXPECT_GE(t.totalMs + 1e-9, t.sliceMs + t.inverseMs);
    EXPECT_GT(t.displayMs, 0.0);
}

TEST(GpuRendererNoContext, RefusesWithoutContext) {
    fvr::test::glContext().doneCurrent();
    EXPECT_THROW(GpuFourierRenderer(), GlError);
}

TEST_F(GlTest, RenderersShareOneSpectrumTexture) {
    const Volume v = makeSheppLoganVolume(32);
    auto s = spectrumOf(v, TransformKind::Fft, 1.25);
    CpuFourierRenderer cpu(s, 2);
    const RenderParams p{ViewFrame::fromDirUp({0.3, 0.4, 0.85}, {0, -1, 0}),
                         {128, defaultPixelSize(v.dims, v.spacing, 128)},
                         Kernel::CatmullRom};
    auto a = std::make_unique<GpuFourierRenderer>();
    GpuFourierRenderer b;
    a->setSpectrum(s);
    b.setSpectrum(s);
    EXPECT_EQ(a->spectrumTexture(), b.spectrumTexture()); // one upload for both views
    a.reset(); // the other keeps it
    EXPECT_GT(fvr::test::compare(b.render(p).pixels, cpu.render(p).pixels).psnr, 90.0);
    GpuFourierRenderer c;
    c.setSpectrum(s, SpectrumPrecision::Float16); // another precision: its own texture
    EXPECT_NE(c.spectrumTexture(), b.spectrumTexture());
}

TEST_F(GlTest, DepthCueAndSliceFiltersMatchCpu) {
    // Depth cueing (derivative kernels; linear runs as a 3-tap variant) and the slice filters in
    // the shaders against the CPU renderer (itself tested against exact depth-weighted integrals
    // and the filters' definitions in fvr_unit_tests).
    const Volume v = makeSheppLoganVolume(40);
    const ViewFrame views[] = {ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}),
                               ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1})};
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        auto s = spectrumOf(v, t, 1.25);
        CpuFourierRenderer cpu(s, 2);
        GpuFourierRenderer gpu;
        gpu.setSpectrum(s);
        for (bool fuse : {true, false}) {
            gpu.setFuseSlice(fuse);
            for (Kernel k : {Kernel::Linear, Kernel::CatmullRom, Kernel::KaiserBessel6})
                for (const auto& view : views) {
                    RenderParams p{view, {64, defaultPixelSize(v.dims, v.spacing, 64)}, k};
                    p.depthCue = 0.7;
                    const auto c1 = fvr::test::compare(gpu.render(p).pixels, cpu.render(p).pixels);
                    EXPECT_GT(c1.psnr, 90.0) << "depth " << transformName(t) << " " << kernelName(k)
                                             << " fused " << fuse;
                    p.filter = {1.2, 3.0, 0.2};
                    const auto c2 = fvr::test::compare(gpu.render(p).pixels, cpu.render(p).pixels);
                    EXPECT_GT(c2.psnr, 90.0)
                        << "depth+filter " << transformName(t) << " " << kernelName(k);
                    p.depthCue = 0.0;
                    const auto c3 = fvr::test::compare(gpu.render(p).pixels, cpu.render(p).pixels);
                    EXPECT_GT(c3.psnr, 90.0)
                        << "filter " << transformName(t) << " " << kernelName(k);
                }
        }
    }
    const RenderParams bad{views[0], {64, 4.0}, Kernel::Nearest, 0.5};
    auto s = spectrumOf(v, TransformKind::Fft, 1.0);
    GpuFourierRenderer gpu;
    gpu.setSpectrum(s);
    EXPECT_THROW(gpu.renderToGpu(bad), SettingsError);
}

TEST_F(GlTest, TransmissionDisplayIsExpOfTheLineIntegrals) {
    // The display pass in Beer-Lambert mode: each 8-bit pixel is the window mapping of the log
    // exposure min(0, log10(exposure exp(-mu_water L))) of the read-back line integral L (film
    // look: inverted), as fvr::core::DisplayWindow::map computes it.
    const Volume v = makeSheppLoganVolume(32);
    GpuFourierRenderer gpu;
    gpu.setSpectrum(spectrumOf(v, TransformKind::Fft, 1.25));
    const int M = 128;
    gpu.renderToGpu({ViewFrame::fromDirUp({0.2, 0.3, 0.93}, {0, -1, 0}),
                     {M, defaultPixelSize(v.dims, v.spacing, M)},
                     Kernel::CatmullRom});
    const auto L = gpu.readback();
    for (bool film : {true, false}) {
        const DisplayWindow w{-2.5, -0.05, film, {waterAttenuationPerMm(60), 1.3}};
        const unsigned tex = gpu.displayTexture(w);
        std::vector<unsigned char> rgba(std::size_t(M) * M * 4);
        glBindTexture(GL_TEXTURE_2D, tex);
        glPixelStorei(GL_PACK_ALIGNMENT, 1);
        glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
        int worst = 0, distinct = 0;
        std::vector<bool> seen(256, false);
        for (std::size_t i = 0; i < L.pixels.size(); ++i) {
            const int want = int(std::lround(255.0 * w.map(L.pixels[i])));
            worst = std::max(worst, std::abs(int(rgba[4 * i]) - want));
            if (!seen[rgba[4 * i]]) seen[rgba[4 * i]] = true, ++distinct;
        }
        EXPECT_LE(worst, 1) << "film " << film;
        EXPECT_GT(distinct, 50); // a real gray ramp, not a blank image
    }
}

namespace {
std::vector<unsigned char> readTexture(unsigned tex, int M) {
    std::vector<unsigned char> rgba(std::size_t(M) * M * 4);
    glBindTexture(GL_TEXTURE_2D, tex);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    return rgba;
}
} // namespace

TEST_F(GlTest, DisplayFusedIntoTheLastPassEqualsTheDisplayPass) {
    // render(p, &window) maps the projection in the last pass of the inverse transform (the column
    // pass for FFT, the eq. 4 pass for FHT): the same bytes as the separate display pass over the
    // same render, the same float projection, and a later window change still runs the pass.
    const Volume v = makeSheppLoganVolume(32);
    const int M = 128;
    const RenderParams base{ViewFrame::fromDirUp({0.3, -0.2, 0.93}, {0, 1, 0}),
                            {M, 1.3 * defaultPixelSize(v.dims, v.spacing, M)},
                            Kernel::CatmullRom};
    const DisplayWindow windows[] = {{-1.0, 40.0, false, {}},
                                     {-2.5, -0.05, true, {waterAttenuationPerMm(70), 1.5}}};
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        GpuFourierRenderer gpu;
        gpu.setSpectrum(spectrumOf(v, t, 1.25));
        for (bool clip : {false, true})
            for (const auto& w : windows) {
                RenderParams p = base;
                p.clipToVolume = clip;
                const std::string what = std::string(transformName(t)) + (clip ? " clip" : "") +
                                         (w.transmission.active() ? " film" : " integrals");
                gpu.renderToGpu(p);
                const auto plain = gpu.readback();
                const auto separate = readTexture(gpu.displayTexture(w), M);
                EXPECT_FALSE(gpu.lastTimes().displayFused) << what;

                gpu.renderToGpu(p, &w);
                EXPECT_EQ(gpu.readback().pixels, plain.pixels) << what;
                const auto fused = readTexture(gpu.displayTexture(w), M);
                const auto times = gpu.lastTimes();
                EXPECT_TRUE(times.displayFused) << what;
                EXPECT_EQ(times.displayMs, 0.0) << what;
                EXPECT_EQ(fused, separate) << what;
                std::set<unsigned char> levels;
                for (std::size_t i = 0; i < fused.size(); i += 4) levels.insert(fused[i]);
                EXPECT_GT(levels.size(), 40u) << what; // a gray ramp, not a blank image

                // A new window after the fused render: the display pass maps it.
                DisplayWindow other = w;
                other.invert = !other.invert;
                const auto inverted = readTexture(gpu.displayTexture(other), M);
                int worst = 0;
                for (std::size_t i = 0; i < fused.size(); i += 4)
                    worst = std::max(worst, std::abs(int(inverted[i]) - (255 - int(fused[i]))));
                EXPECT_LE(worst, 1) << what;
            }
    }
}

TEST_F(GlTest, ClipToVolumeMatchesCpu) {
    const Volume v = makeSheppLoganVolume(40);
    const ViewFrame views[] = {ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}),
                               ViewFrame::fromDirUp({1, 0, 0}, {0, 0, 1})};
    for (auto t : {TransformKind::Fft, TransformKind::Fht}) {
        auto s = spectrumOf(v, t, 1.0);
        CpuFourierRenderer cpu(s, 2);
        GpuFourierRenderer gpu;
        gpu.setSpectrum(s);
        for (const auto& view : views) {
            RenderParams p{
                view, {128, 1.5 * defaultPixelSize(v.dims, v.spacing, 128)}, Kernel::Linear};
            p.clipToVolume = true;
            const auto a = cpu.render(p);
            const auto b = gpu.render(p);
            int zeros = 0;
            for (float x : b.pixels) zeros += x == 0.0f;
            EXPECT_GT(zeros, 128 * 128 / 10) << transformName(t);
            EXPECT_GT(fvr::test::compare(b.pixels, a.pixels).psnr, 90.0) << transformName(t);
        }
    }
}

TEST_F(GlTest, VoxelModelsApertureAndClampMatchCpu) {
    // The trilinear and B-spline voxel models (the spectrum's continuation beyond the band with
    // the period signs, times the model's transfer function), the pixel aperture and the
    // non-negative clamp in the shaders against the CPU renderer (itself tested against the
    // spatial projector with the same models in fvr_unit_tests). Even and odd voxel counts;
    // fine pixels, so that most slice samples lie beyond the band.
    const Volume even = makeSheppLoganVolume(40);
    const Volume odd = makeSheppLoganVolume(41);
    const ViewFrame views[] = {ViewFrame::fromDirUp({0.35, 0.2, 0.92}, {0, -1, 0}),
                               ViewFrame::fromDirUp({0, 1, 0}, {0, 0, 1})};
    for (const Volume* v : {&even, &odd})
        for (auto t : {TransformKind::Fft, TransformKind::Fht})
            for (Kernel k : {Kernel::Linear, Kernel::KaiserBessel4}) {
                PreprocessOptions o;
                o.effort = PlannerEffort::Estimate;
                o.transform = t;
                o.oversampling = 1.25;
                o.mapping = ValueMapping::Mu;
                if (k == Kernel::KaiserBessel4) o.deapodizeFor = k;
                auto s = preprocess(*v, o);
                CpuFourierRenderer cpu(s, 2);
                GpuFourierRenderer gpu;
                gpu.setSpectrum(s);
                for (VoxelModel model : {VoxelModel::Trilinear, VoxelModel::BSpline})
                    for (bool fuse : {true, false})
                        for (const auto& view : views)
                            for (int variant = 0; variant < 3; ++variant) {
                                gpu.setFuseSlice(fuse);
                                RenderParams p{
                                    view, {64, 0.4 * defaultPixelSize(v->dims, v->spacing, 64)}, k};
                                p.voxelModel = model;
                                p.depthCue = variant == 1 ? 0.7 : 0.0;
                                p.pixelAperture = variant == 2;
                                p.clipToVolume = p.nonNegative = variant == 2;
                                const auto c =
                                    fvr::test::compare(gpu.render(p).pixels, cpu.render(p).pixels);
                                EXPECT_GT(c.psnr, 90.0)
                                    << "N " << v->dims[0] << " " << transformName(t) << " "
                                    << kernelName(k) << " " << voxelModelName(model) << " fused "
                                    << fuse << " variant " << variant;
                            }
            }
}
