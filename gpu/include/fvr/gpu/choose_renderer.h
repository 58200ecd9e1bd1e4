#pragma once
/** The one rule for which renderer a front end runs on, and the words for why it is the CPU.
 *  A hardware GPU is taken whenever one is allowed; a software OpenGL (llvmpipe …) only when
 *  asked for, because the CPU renderer is faster there; any failure of the GPU (no context, no
 *  OpenGL 4.3, a shader, the spectrum too large) falls back to the CPU, saying why. fvr-render
 *  (its own headless EGL context) and the workstation (the context of its QOpenGLWidget) both
 *  choose through chooseRenderer(); they make the CPU renderer themselves, as each needs it. */
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <fvr/core/render/spectrum.h>
#include <fvr/gpu/gl_info.h>
#include <fvr/gpu/gpu_renderer.h>

namespace fvr::gpu {

/** Which renderers a caller allows. */
enum class GpuUse {
    Never, ///< the CPU renderer (fvr-render --backend cpu)
    Hardware, ///< a hardware GPU, else the CPU (fvr-render's default, the workstation's)
    Any, ///< any GPU, a software one too (--backend gpu, View ▸ Use a software GPU)
};

/** What the caller asks for. */
struct RendererRequest {
    GpuUse use = GpuUse::Hardware;
    /** Creates the OpenGL context and makes it current (fvr-render's EGL context), inside the
     *  rule's fallback: its errors become the reason. Empty: the context current now. */
    std::function<void()> makeContext;
    /** The OpenGL share group of the context (GpuFourierRenderer's constructor). */
    const void* shareGroup = nullptr;
    /** One GPU renderer per spectrum, each uploaded. None: one renderer without a spectrum
     *  (the workstation uploads later, through uploadSpectrum()). */
    std::vector<std::shared_ptr<const core::Spectrum>> spectra;
    SpectrumPrecision precision = SpectrumPrecision::Float32;
};

/** Why the choice is the CPU renderer. */
enum class CpuReason {
    None, ///< it is the GPU
    Asked, ///< GpuUse::Never
    SoftwareGl, ///< a software OpenGL that was not allowed
    GpuFailed, ///< the GPU failed: no context, no OpenGL 4.3, a shader, memory
};

struct RendererChoice {
    /** The GPU renderers (one per requested spectrum, or one without a spectrum); empty: render
     *  on the CPU. */
    std::vector<std::unique_ptr<GpuFourierRenderer>> gpu;
    CpuReason why = CpuReason::None;
    /** Why the CPU, in words (fallbackReason() or softwareGlReason()); empty for the GPU and
     *  for GpuUse::Never. */
    std::string reason;
    /** The context's OpenGL (empty where none was current). */
    GlInfo gl;

    bool onGpu() const { return !gpu.empty(); }
};

/** The rule: GpuUse::Never gives the CPU; otherwise the context is made (makeContext) and
 *  examined, a software OpenGL gives the CPU unless GpuUse::Any, and the GPU renderers are made
 *  and given their spectra; any exception on the way gives the CPU with fallbackReason(). Never
 *  throws for a GPU failure. The context stays current on return. */
RendererChoice chooseRenderer(const RendererRequest& request);

/** Uploads `spectrum` to `gpu` (the context current). On failure `gpu` is released and the
 *  result is fallbackReason() (the caller renders on the CPU); empty on success. */
std::string uploadSpectrum(std::unique_ptr<GpuFourierRenderer>& gpu,
                           std::shared_ptr<const core::Spectrum> spectrum,
                           SpectrumPrecision precision = SpectrumPrecision::Float32);

/** "GPU backend unavailable (<what>): rendering on the CPU" */
std::string fallbackReason(std::string_view what);
/** "the GPU is a software renderer (<GL_RENDERER>): rendering on the CPU, which is faster here"
 */
std::string softwareGlReason(const GlInfo& gl);

} // namespace fvr::gpu
