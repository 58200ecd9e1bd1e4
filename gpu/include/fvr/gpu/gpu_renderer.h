#pragma once
/** Fourier volume rendering on the GPU (OpenGL 4.3 compute shaders). Renders into whatever
 *  context is current: the workstation's QOpenGLWidget, an EGL context for fvr-render and
 *  the tests. Computes exactly what fvr::core::CpuFourierRenderer computes. */
#include <complex>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fvr/core/io/image_io.h>
#include <fvr/core/render/renderer.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/xray/polychromatic.h>

namespace fvr::gpu {

/** Storage of the spectrum texture: float32 (4 bytes per voxel) or float16 (2 bytes). */
enum class SpectrumPrecision { Float32, Float16 };

/** GPU time per stage (timer queries), ms. When the slice is fused into the row FFT pass, the
 *  slice time is 0 and `inverseMs` holds both; when the display mapping is fused into the last
 *  pass (render() with a window), `displayMs` is 0 and `inverseMs` holds it too. */
struct GpuStageTimes {
    double sliceMs = 0.0;
    double inverseMs = 0.0;
    double displayMs = 0.0;
    double totalMs = 0.0;
    bool fused = false;
    bool displayFused = false;
};

class GpuFourierRenderer final : public core::Renderer {
public:
    /** Needs a current OpenGL >= 4.3 context; throws GlError otherwise. All later calls need the
     *  same context current; releaseGl() (or the destructor) frees the GL objects. `shareGroup`
     *  identifies the OpenGL share group of that context (the workstation passes its Qt share
     *  group, so its views share spectrum textures); nullptr: the current native context alone.
     */
    explicit GpuFourierRenderer(const void* shareGroup = nullptr);
    ~GpuFourierRenderer();
    GpuFourierRenderer(const GpuFourierRenderer&) = delete;
    GpuFourierRenderer& operator=(const GpuFourierRenderer&) = delete;

    /** Uploads the spectrum as a 3D texture (RG for the half spectrum, R for Hartley). Checks the
     *  texture size limit and, where the driver reports it, free GPU memory first; throws
     *  GpuMemoryError with the sizes when it does not fit. */
    void setSpectrum(std::shared_ptr<const core::Spectrum> spectrum,
                     SpectrumPrecision precision = SpectrumPrecision::Float32);
    bool hasSpectrum() const { return bool(m_spectrum); }
    std::size_t spectrumTextureBytes() const { return m_textureBytes; }
    /** The spectrum's 3D texture. Renderers in one OpenGL share group (the workstation's views)
     *  share one texture per spectrum and precision, so comparing 4 views costs 1 upload. */
    unsigned spectrumTexture() const { return m_texture; }

    /** Slice the spectrum inside the first (row) FFT pass instead of a separate pass (faster;
     *  the per-stage times then merge slice and inverse). Default on. */
    void setFuseSlice(bool fuse) { m_fuse = fuse; }

    /** Renders into GPU buffers (no readback). With a window, the last pass of the inverse
     *  transform also maps the projection through it into the display texture (no display pass:
     *  displayTexture() with the same window then returns at once). Throws SettingsError, GlError.
     */
    void renderToGpu(const core::RenderParams& params,
                     const core::DisplayWindow* display = nullptr);
    /** The last render's float line integrals (row 0 at the top): the W x H the parameters asked
     *  for, cropped from the power-of-two square the FFT passes ran on. */
    core::ProjectionImage readback() const;
    /** renderToGpu() + readback() with the GPU's per-stage times. */
    core::ProjectionImage renderImage(const core::RenderParams& params,
                                      GpuStageTimes* times = nullptr);
    /** core::Renderer: renderImage() with the times as core::StageTimes (display in inverse). */
    core::ProjectionImage render(const core::RenderParams& params,
                                 core::StageTimes* times = nullptr) override;
    std::string describe() const override;
    bool isGpu() const override { return true; }
    /** The last render mapped through the window (Beer-Lambert transmission first when the window
     *  has one) as an RGBA8 M x M texture: runs the display pass unless the render already fused
     *  this window. */
    unsigned displayTexture(const core::DisplayWindow& window);
    /** What spectralSum() writes per pixel. */
    enum class SpectralOutput { Transmission, NegativeLog, Material };
    /** The polychromatic spectral sum on the GPU, as this renderer's frame: reads the
     *  last frames of `materials` (one renderer per material of `response`, same size; this one
     *  may be among them) where they lie, evaluates the response's table in one compute pass
     *  (SpectralResponse::lookup: same layout and interpolation) and writes I/I0, -ln(I/I0) or
     *  material `show`'s rhoL (g/cm^2, unclamped) into this renderer's image: readback() and
     *  displayTexture() then show it. No read-back per material. Throws SettingsError. */
    void spectralSum(const std::vector<const GpuFourierRenderer*>& materials,
                     const std::shared_ptr<const core::SpectralResponse>& response,
                     SpectralOutput output = SpectralOutput::Transmission, int show = 0);

    /** Stage times of the last render (and display pass, if any); waits for the GPU. */
    GpuStageTimes lastTimes();

    /** Inverse 2D FFT (unnormalised, FFTW_BACKWARD) of a row-major complex M x M array with the
     *  renderer's row and column passes: for tests against FFTW. */
    std::vector<std::complex<float>> inverseFft2D(const std::vector<std::complex<float>>& data,
                                                  int size);
    /** Inverse 2D FHT (separable passes + eq. 4) of a real M x M array (tests). */
    std::vector<float> inverseFht2D(const std::vector<float>& data, int size);

    /** Compiles every shader variant for size M (tests: every shader compiles). Returns the
     *  number of programs built. */
    int compileAll(int size);
    std::string rendererInfo() const;
    void releaseGl();

private:
    struct Program;
    unsigned program(const std::string& path,
                     const std::vector<std::pair<std::string, std::string>>& defines);
    void ensureSize(int size);
    void bindKernel(unsigned prog, core::Kernel kernel, bool derivative);
    void setSliceUniforms(unsigned prog, const core::RenderParams& params);
    /** The slice filter's uniforms and its per-axis table (Binding::FilterAxis), from
     *  core::SliceFilterTable. */
    void setFilterUniforms(unsigned prog, const core::RenderParams& params);
    void runRows(int M, bool fused, bool hartley, core::Kernel kernel,
                 const core::RenderParams* params);
    void runCols(int M, const char* outputMode, const core::RenderParams* params,
                 const core::DisplayWindow* display = nullptr);
    void runHartleyCorrection(int M, const core::RenderParams* params,
                              const core::DisplayWindow* display = nullptr);
    void setClipUniforms(unsigned prog, const core::RenderParams* params);
    void setDisplayUniforms(unsigned prog, const core::DisplayWindow& window);
    void releaseTexture();
    /** Holds the texture `id` of `bytes` under the cache key (spectrum, precision, share group). */
    void adoptTexture(unsigned id, std::size_t bytes, const void* const key[3]);

    bool m_gl = false; ///< GL objects live (constructed, not yet released)
    const void* m_shareGroup = nullptr;
    std::shared_ptr<const core::Spectrum> m_spectrum;
    std::size_t m_textureBytes = 0;
    unsigned m_texture = 0;
    const void* m_textureKey[3] = {nullptr, nullptr, nullptr}; // spectrum, precision, share group
    bool m_fuse = true;
    std::map<std::string, unsigned> m_programs;
    std::map<core::Kernel, unsigned> m_kernelBuffers;
    std::map<core::Kernel, unsigned> m_kernelDerivativeBuffers;
    std::map<core::Kernel, std::unique_ptr<core::KernelTable>> m_tables;
    int m_size = 0;
    unsigned m_twiddles = 0, m_bufA = 0, m_bufB = 0, m_image = 0, m_hartleyT = 0, m_display = 0;
    unsigned m_filterAxis = 0; ///< the slice filter's per-axis table (SliceFilterTable::axis)
    unsigned m_table = 0; ///< spectralSum(): the response's table
    std::shared_ptr<const core::SpectralResponse> m_tableFor; ///< the response m_table holds
    unsigned m_queries[4] = {0, 0, 0, 0};
    bool m_timesPending = false, m_displayTimed = false;
    GpuStageTimes m_times;
    core::RenderParams m_last; ///< the square transform the last render ran
    int m_lastWidth = 0, m_lastHeight = 0; ///< the image it asked for (readback() crops)
    std::optional<core::DisplayWindow>
        m_displayed; ///< the window the display texture holds the last render in
};

} // namespace fvr::gpu
