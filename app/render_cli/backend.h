#pragma once
/** The renderer fvr-render runs on: the CPU renderer, or the GPU renderer with the headless EGL
 *  context that it needs. The only place that knows whether the GPU renderer is built in. */
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <fvr/core/render/cone_projector.h>
#include <fvr/core/render/renderer.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/xray/polychromatic_render.h>

#include "options.h"

namespace fvr::cli {

/** Stage times of the frames of --bench, in ms. */
struct BenchFrames {
    std::vector<double> slice, inverse, total;
    /** GPU only: frames rendered as the workstation renders them (slice fused into the row
     *  pass, display mapping fused into the last pass); empty on the CPU. */
    std::vector<double> fusedTotal;
};

class RenderBackend {
public:
    virtual ~RenderBackend() = default;
    virtual core::Renderer& renderer() = 0;
    /** "cpu", or "gpu: <GL renderer>" (", fp16" with a float16 spectrum). */
    virtual std::string name() const = 0;
    /** Renders `warmUp` once (plans, buffers, shaders), then times frames 0..count-1 with the
     *  parameters of paramsAt(i). */
    virtual BenchFrames timeFrames(const core::RenderParams& warmUp,
                                   const std::function<core::RenderParams(int)>& paramsAt,
                                   int count);
    /** How many views renderBatch() renders at once (1: one after the other). */
    virtual int batchWidth() const { return 1; }
    /** The views of `params` (at most batchWidth()), in order: the batches of --sweep and
     *  --views. The CPU renders one view per thread, each on a single-threaded renderer over the
     *  shared spectrum (no synchronisation inside a frame: more views per second than all threads
     *  on one frame); the GPU renders them in turn. */
    virtual std::vector<core::ProjectionImage> renderBatch(
        const std::vector<core::RenderParams>& params);
};

/** The renderer of --backend holding `spectrum`, chosen by gpu::chooseRenderer's rule (auto: a
 *  hardware GPU only; gpu: a software one too). The GPU falls back to the CPU, saying why on
 *  stderr, where no GPU is usable or the program is built without the GPU renderer. */
std::unique_ptr<RenderBackend> makeRenderBackend(const Options& o,
                                                 std::shared_ptr<const core::Spectrum> spectrum);

/** The renderers of --kvp, one per material spectrum: GPU renderers sharing one headless EGL
 *  context where --backend picks the GPU (gpu::chooseRenderer, as makeRenderBackend),
 *  else single CPU renderers with o.threads. `name` gets the backend's name. */
std::vector<std::unique_ptr<core::Renderer>> makeMaterialRenderers(
    const Options& o, const std::vector<std::shared_ptr<const core::Spectrum>>& spectra,
    std::string& name);

/** A polychromatic frame: I/I0 (noise applied) and, with `materials`, the rhoL images. */
using PolychromaticFrameFn = std::function<core::PolychromaticFrame(
    const core::RenderParams&, const core::NoiseModel&, bool materials)>;
/** Where the material renderers are GPU ones (makeMaterialRenderers): frames whose spectral sum
 *  runs on the GPU over the material frames where they lie (one read-back of I/I0; the
 *  materials read back only when asked). Empty for CPU renderers. */
PolychromaticFrameFn gpuPolychromaticFrames(
    const std::vector<std::unique_ptr<core::Renderer>>& renderers,
    std::shared_ptr<const core::SpectralResponse> response);

/** --gpu-info: {"available", "reason" (when not), "eglClientExtensions", "devices": [{"index",
 *  "name", "drmFile", "software", "nvidia", "extensions"}], "chosen": {"device" (-1:
 *  surfaceless), "description", "egl"}, "gl": {"vendor", "renderer", "version", "major",
 *  "minor", "coreProfile", "max3dTextureSize", "freeMemoryMiB" (null where not reported)}}. */
nlohmann::json gpuInfoJson();

/** The cone-beam ray caster fvr-render runs: core::ConeProjector, or gpu::ConeRayCaster on a
 *  headless EGL context (the same models and images to float rounding). */
class ConeCaster {
public:
    virtual ~ConeCaster() = default;
    virtual core::DetectorImage project(const core::ConeCamera& camera) = 0;
    virtual const core::ConeProjectorOptions& options() const = 0;
    /** "cpu", or "gpu: <EGL device>". */
    virtual std::string name() const = 0;
    /** The models in words (core::describeConeProjector, or the GPU's with its fetch). */
    virtual std::string description() const = 0;
};

/** The ray caster of --backend: gpu takes the GPU (a software one too), auto a hardware GPU
 *  only, cpu the CPU. The B-spline model and whatever the GPU refuses (a volume beyond its 3D
 *  texture size or memory, no EGL) run on the CPU, saying why on stderr where the GPU was asked
 *  for or is hardware. */
std::unique_ptr<ConeCaster> makeConeCaster(const Options& o, const core::Volume& volume,
                                           const core::ConeProjectorOptions& po);

} // namespace fvr::cli
