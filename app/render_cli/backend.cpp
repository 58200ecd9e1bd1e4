// fvr-render's renderer factory: the only FVR_HAVE_GPU branches of the program.
#include "backend.h"

#include <chrono>

#include <cstdio>

#include <fvr/core/render/cpu_batch.h>
#include <fvr/core/thread_pool.h>
#ifdef FVR_HAVE_GPU
#include <fvr/gpu/choose_renderer.h>
#include <fvr/gpu/cone_ray_caster.h>
#include <fvr/gpu/egl_context.h>
#include <fvr/gpu/gl_info.h>
#include <fvr/gpu/gpu_renderer.h>
#endif

namespace fvr::cli {

BenchFrames RenderBackend::timeFrames(const core::RenderParams& warmUp,
                                      const std::function<core::RenderParams(int)>& paramsAt,
                                      int count) {
    BenchFrames b;
    renderer().render(warmUp); // warm-up: plans and buffers
    for (int i = 0; i < count; ++i) {
        core::StageTimes t;
        renderer().render(paramsAt(i), &t);
        b.slice.push_back(t.sliceMs);
        b.inverse.push_back(t.inverseMs);
        b.total.push_back(t.totalMs);
    }
    return b;
}

std::vector<core::ProjectionImage> RenderBackend::renderBatch(
    const std::vector<core::RenderParams>& params) {
    std::vector<core::ProjectionImage> images;
    for (const auto& p : params) images.push_back(renderer().render(p));
    return images;
}

namespace {

#ifndef FVR_HAVE_GPU
void sayBuiltWithoutGpu() {
    std::fprintf(stderr, "fvr-render: built without the GPU renderer; rendering on the CPU\n");
}
#endif

class CpuBackend final : public RenderBackend {
public:
    CpuBackend(std::shared_ptr<const core::Spectrum> spectrum, int threads)
        : m_batch(std::move(spectrum), threads) {}
    core::Renderer& renderer() override { return m_batch.renderer(); }
    std::string name() const override { return "cpu"; }
    int batchWidth() const override { return m_batch.width(); }
    std::vector<core::ProjectionImage> renderBatch(
        const std::vector<core::RenderParams>& params) override {
        return m_batch.renderBatch(params);
    }

private:
    core::CpuBatchRenderer m_batch; // the batch rule: one view per thread
};

#ifdef FVR_HAVE_GPU
/** What gpu::chooseRenderer gets from the options: the GPU's use (--backend), a headless EGL
 *  context made into `context`, the spectra and their precision (--fp16). */
template <class ContextPtr>
fvr::gpu::RendererRequest gpuRequest(const Options& o, ContextPtr& context,
                                     std::vector<std::shared_ptr<const core::Spectrum>> spectra) {
    fvr::gpu::RendererRequest r;
    r.use = o.backend == Options::Backend::Gpu ? fvr::gpu::GpuUse::Any : fvr::gpu::GpuUse::Hardware;
    r.makeContext = [&context] { context.reset(new fvr::gpu::EglContext); };
    r.spectra = std::move(spectra);
    r.precision =
        o.fp16 ? fvr::gpu::SpectrumPrecision::Float16 : fvr::gpu::SpectrumPrecision::Float32;
    return r;
}

/** Says on stderr why the CPU renders, where the GPU was allowed. */
void sayWhyCpu(const fvr::gpu::RendererChoice& choice) {
    if (choice.reason.empty()) return;
    std::fprintf(stderr, "fvr-render: %s%s\n", choice.reason.c_str(),
                 choice.why == fvr::gpu::CpuReason::SoftwareGl ? " (--backend gpu uses it anyway)"
                                                               : "");
}

/** A headless EGL OpenGL 4.3 context (no X server, no Qt) and the GPU renderer on it. */
class GpuBackend final : public RenderBackend {
public:
    GpuBackend(std::unique_ptr<fvr::gpu::EglContext> context,
               std::unique_ptr<fvr::gpu::GpuFourierRenderer> renderer, bool fp16)
        : m_fp16(fp16), m_context(std::move(context)), m_renderer(std::move(renderer)) {}
    ~GpuBackend() override {
        if (m_renderer && m_context) {
            m_context->makeCurrent();
            m_renderer.reset();
        }
        m_context.reset();
    }
    core::Renderer& renderer() override { return *m_renderer; }
    std::string name() const override {
        return "gpu: " + m_renderer->rendererInfo() + (m_fp16 ? ", fp16" : "");
    }
    BenchFrames timeFrames(const core::RenderParams& warmUp,
                           const std::function<core::RenderParams(int)>& paramsAt,
                           int count) override;

private:
    bool m_fp16 = false;
    std::unique_ptr<fvr::gpu::EglContext> m_context;
    std::unique_ptr<fvr::gpu::GpuFourierRenderer> m_renderer;
};

BenchFrames GpuBackend::timeFrames(const core::RenderParams& warmUp,
                                   const std::function<core::RenderParams(int)>& paramsAt,
                                   int count) {
    BenchFrames b;
    auto& r = *m_renderer;
    // Fused as the workstation renders a frame: slice in the row pass, display mapping
    // (line integrals to an 8-bit texture) in the last pass.
    const core::DisplayWindow window{0.0, 1.0, false, {}};
    for (bool fuse : {false, true}) {
        r.setFuseSlice(fuse);
        r.renderToGpu(warmUp, fuse ? &window : nullptr); // warm-up: shader compilation, buffers
        r.lastTimes();
        for (int i = 0; i < count; ++i) {
            r.renderToGpu(paramsAt(i), fuse ? &window : nullptr);
            const auto t = r.lastTimes(); // GPU timer queries
            if (fuse) {
                b.fusedTotal.push_back(t.totalMs);
            } else {
                b.slice.push_back(t.sliceMs);
                b.inverse.push_back(t.inverseMs);
                b.total.push_back(t.totalMs);
            }
        }
    }
    return b;
}
#endif

} // namespace

std::unique_ptr<RenderBackend> makeRenderBackend(const Options& o,
                                                 std::shared_ptr<const core::Spectrum> spectrum) {
    if (o.backend != Options::Backend::Cpu) {
#ifdef FVR_HAVE_GPU
        std::unique_ptr<fvr::gpu::EglContext> context;
        auto choice = fvr::gpu::chooseRenderer(gpuRequest(o, context, {spectrum}));
        if (choice.onGpu())
            return std::make_unique<GpuBackend>(std::move(context), std::move(choice.gpu.front()),
                                                o.fp16);
        sayWhyCpu(choice);
#else
        sayBuiltWithoutGpu();
#endif
    }
    return std::make_unique<CpuBackend>(std::move(spectrum), o.threads);
}

namespace {

#ifdef FVR_HAVE_GPU
/** A GPU renderer on a context shared with the other materials' renderers (kept alive and made
 *  current to release the GL objects). */
class SharedContextRenderer final : public core::Renderer {
public:
    SharedContextRenderer(std::shared_ptr<fvr::gpu::EglContext> context,
                          std::unique_ptr<fvr::gpu::GpuFourierRenderer> renderer)
        : m_context(std::move(context)), m_renderer(std::move(renderer)) {}
    ~SharedContextRenderer() override {
        m_context->makeCurrent();
        m_renderer.reset();
    }
    core::ProjectionImage render(const core::RenderParams& params,
                                 core::StageTimes* times) override {
        return m_renderer->render(params, times);
    }
    std::string describe() const override { return m_renderer->describe(); }
    bool isGpu() const override { return true; }
    fvr::gpu::GpuFourierRenderer& gpu() { return *m_renderer; }

private:
    std::shared_ptr<fvr::gpu::EglContext> m_context;
    std::unique_ptr<fvr::gpu::GpuFourierRenderer> m_renderer;
};

/** The GPU renderers of the materials on one context, or none (saying why) where the CPU is to
 *  be used. */
std::vector<std::unique_ptr<core::Renderer>> gpuMaterialRenderers(
    const Options& o, const std::vector<std::shared_ptr<const core::Spectrum>>& spectra,
    std::string& name) {
    std::shared_ptr<fvr::gpu::EglContext> context;
    auto choice = fvr::gpu::chooseRenderer(gpuRequest(o, context, spectra));
    std::vector<std::unique_ptr<core::Renderer>> out;
    for (auto& gpu : choice.gpu)
        out.push_back(std::make_unique<SharedContextRenderer>(context, std::move(gpu)));
    if (out.empty())
        sayWhyCpu(choice);
    else
        name = "gpu: " + choice.gl.renderer + (o.fp16 ? ", fp16" : "");
    return out;
}
#endif

} // namespace

std::vector<std::unique_ptr<core::Renderer>> makeMaterialRenderers(
    const Options& o, const std::vector<std::shared_ptr<const core::Spectrum>>& spectra,
    std::string& name) {
    if (o.backend != Options::Backend::Cpu && !spectra.empty()) {
#ifdef FVR_HAVE_GPU
        auto gpu = gpuMaterialRenderers(o, spectra, name);
        if (!gpu.empty()) return gpu;
#else
        sayBuiltWithoutGpu();
#endif
    }
    std::vector<std::unique_ptr<core::Renderer>> out;
    for (const auto& s : spectra)
        out.push_back(std::make_unique<core::CpuFourierRenderer>(s, o.threads));
    name = "cpu";
    return out;
}

PolychromaticFrameFn gpuPolychromaticFrames(
    [[maybe_unused]] const std::vector<std::unique_ptr<core::Renderer>>& renderers,
    [[maybe_unused]] std::shared_ptr<const core::SpectralResponse> response) {
#ifdef FVR_HAVE_GPU
    std::vector<fvr::gpu::GpuFourierRenderer*> gpus;
    for (const auto& r : renderers)
        if (auto* g = dynamic_cast<SharedContextRenderer*>(r.get())) gpus.push_back(&g->gpu());
    if (gpus.empty() || gpus.size() != renderers.size()) return {};
    return [gpus, response](const core::RenderParams& p, const core::NoiseModel& noise,
                            bool materials) {
        core::PolychromaticFrame f;
        for (auto* g : gpus) g->renderToGpu(p);
        if (materials)
            for (auto* g : gpus) {
                f.massThickness.push_back(g->readback());
                for (float& v : f.massThickness.back().pixels) v *= 0.1f; // -> g/cm^2
            }
        gpus.back()->lastTimes(); // waits for the material frames
        const auto t0 = std::chrono::steady_clock::now();
        gpus.front()->spectralSum({gpus.begin(), gpus.end()}, response);
        f.transmission = gpus.front()->readback();
        f.spectralSumMs =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count(); // with the read-back of I/I0
        if (noise.active()) {
            core::NoiseModel n = noise;
            n.pixelAreaMm2 = p.image.pixelSize * p.image.pixelSize;
            core::applyQuantumNoise(f.transmission.pixels, core::unattenuatedQuanta(*response, n),
                                    n);
        }
        return f;
    };
#else
    return {};
#endif
}

nlohmann::json gpuInfoJson() {
    nlohmann::json j;
#ifdef FVR_HAVE_GPU
    j["eglClientExtensions"] = fvr::gpu::EglContext::clientExtensions();
    j["devices"] = nlohmann::json::array();
    for (const auto& d : fvr::gpu::EglContext::devices())
        j["devices"].push_back({{"index", d.index},
                                {"name", d.name},
                                {"drmFile", d.drmFile},
                                {"software", d.software},
                                {"nvidia", d.nvidia},
                                {"extensions", d.extensions}});
    try {
        const fvr::gpu::EglContext context;
        const auto gl = fvr::gpu::currentGlInfo();
        j["available"] = true;
        j["chosen"] = {{"device", context.deviceIndex()},
                       {"description", context.description()},
                       {"egl", context.eglVersion()}};
        j["gl"] = {{"vendor", gl.vendor},
                   {"renderer", gl.renderer},
                   {"version", gl.version},
                   {"major", gl.major},
                   {"minor", gl.minor},
                   {"coreProfile", gl.coreProfile},
                   {"software", gl.software()}, // --backend auto does not take it
                   {"max3dTextureSize", gl.max3dTextureSize},
                   {"freeMemoryMiB", gl.freeMemoryKiB < 0
                                         ? nlohmann::json()
                                         : nlohmann::json(gl.freeMemoryKiB / 1024)}};
    } catch (const std::exception& e) {
        j["available"] = false;
        j["reason"] = e.what();
    }
#else
    j["available"] = false;
    j["reason"] = "built without the GPU renderer";
#endif
    return j;
}

namespace {

class CpuConeCaster final : public ConeCaster {
public:
    CpuConeCaster(const core::Volume& volume, const core::ConeProjectorOptions& o)
        : m_projector(volume, o) {}
    core::DetectorImage project(const core::ConeCamera& c) override {
        return m_projector.project(c);
    }
    const core::ConeProjectorOptions& options() const override { return m_projector.options(); }
    std::string name() const override { return "cpu"; }
    std::string description() const override {
        return core::describeConeProjector(m_projector.options());
    }

private:
    core::ConeProjector m_projector;
};

#ifdef FVR_HAVE_GPU
class GpuConeCaster final : public ConeCaster {
public:
    GpuConeCaster(std::unique_ptr<fvr::gpu::EglContext> context, const core::Volume& volume,
                  const core::ConeProjectorOptions& o)
        : m_context(std::move(context)), m_caster(volume, o) {}
    core::DetectorImage project(const core::ConeCamera& c) override {
        m_context->makeCurrent(); // several casters (one per --kvp material) take turns
        return m_caster.project(c);
    }
    const core::ConeProjectorOptions& options() const override { return m_caster.options(); }
    std::string name() const override { return "gpu: " + m_context->description(); }
    std::string description() const override {
        return fvr::gpu::describeConeRayCaster(m_caster.options(), m_caster.fetch());
    }

private:
    std::unique_ptr<fvr::gpu::EglContext> m_context; // declared first: destroyed last
    fvr::gpu::ConeRayCaster m_caster;
};

/** The GPU's caster where --backend allows it, else null (the reason on stderr when the GPU
 *  was asked for or is hardware). */
std::unique_ptr<ConeCaster> gpuConeCaster(const Options& o, const core::Volume& volume,
                                          const core::ConeProjectorOptions& po) {
    const bool asked = o.backend == Options::Backend::Gpu;
    if (po.model == core::RayModel::BSpline) {
        if (asked)
            std::fprintf(stderr, "fvr-render: the B-spline ray model runs on the CPU only\n");
        return nullptr;
    }
    bool hardware = false;
    try {
        auto context = std::make_unique<fvr::gpu::EglContext>();
        hardware = !fvr::gpu::currentGlInfo().software();
        if (!asked && !hardware) return nullptr; // auto: a software GL is slower than the CPU
        return std::make_unique<GpuConeCaster>(std::move(context), volume, po);
    } catch (const std::exception& e) {
        if (asked || hardware)
            std::fprintf(stderr,
                         "fvr-render: the GPU cannot cast the cone beam (%s); the CPU does\n",
                         e.what());
        return nullptr;
    }
}
#endif

} // namespace

std::unique_ptr<ConeCaster> makeConeCaster(const Options& o, const core::Volume& volume,
                                           const core::ConeProjectorOptions& po) {
#ifdef FVR_HAVE_GPU
    if (o.backend != Options::Backend::Cpu)
        if (auto gpu = gpuConeCaster(o, volume, po)) return gpu;
#else
    if (o.backend == Options::Backend::Gpu) sayBuiltWithoutGpu();
#endif
    return std::make_unique<CpuConeCaster>(volume, po);
}

} // namespace fvr::cli
