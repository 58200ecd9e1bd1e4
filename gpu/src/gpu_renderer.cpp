#include <fvr/gpu/gpu_renderer.h>

#include <epoxy/gl.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <map>
#include <mutex>
#include <tuple>

#include <glm/gtc/type_ptr.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/render/fftw_planning.h>
#include <fvr/core/render/slice_filter.h>
#include <fvr/core/render/slice_params.h>
#include <fvr/gpu/bindings.h>
#include <fvr/gpu/errors.h>
#include <fvr/gpu/fft_plan.h>
#include <fvr/gpu/gl_info.h>
#include <fvr/gpu/shader_program.h>
#include <fvr/gpu/shader_source.h>

namespace fvr::gpu {

using core::Kernel;

namespace {
constexpr GLenum kGpuMemoryInfoAvailableNvx =
    0x9049; // GL_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX (KiB)
constexpr GLenum kTextureFreeMemoryAti = 0x87FC; // GL_TEXTURE_FREE_MEMORY_ATI (KiB)

/** Spectrum textures shared by the renderers of one share group (keyed by spectrum, precision
 *  and share group; the entry keeps the spectrum alive so its address cannot be reused). */
struct SharedTexture {
    GLuint id = 0;
    std::size_t bytes = 0;
    int refs = 0;
    std::shared_ptr<const core::Spectrum> spectrum;
};
using TextureKey = std::tuple<const void*, const void*, const void*>;
std::mutex& textureMutex() {
    static std::mutex m;
    return m;
}
std::map<TextureKey, SharedTexture>& textureCache() {
    static std::map<TextureKey, SharedTexture> cache;
    return cache;
}

int workGroupSize(int M) { return std::min(256, M / 2); }

std::string glErrorName(GLenum e) {
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    default: return "GL error " + std::to_string(e);
    }
}
} // namespace

GpuFourierRenderer::GpuFourierRenderer(const void* shareGroup) {
    const void* ctx = currentNativeContext();
    if (!ctx) throw GlError("GPU renderer: no current OpenGL context");
    const int version = epoxy_gl_version();
    if (version < 43 || !epoxy_is_desktop_gl())
        throw GlError("GPU renderer: OpenGL 4.3 (compute shaders) needed, the context offers " +
                      std::string(epoxy_is_desktop_gl() ? "" : "OpenGL ES ") +
                      std::to_string(version / 10) + "." + std::to_string(version % 10));
    m_gl = true;
    m_shareGroup = shareGroup ? shareGroup : ctx;
    for (Kernel k : core::allKernels()) m_tables.emplace(k, std::make_unique<core::KernelTable>(k));
    glGenQueries(4, m_queries);
}

GpuFourierRenderer::~GpuFourierRenderer() {
    if (currentNativeContext()) releaseGl();
}

void GpuFourierRenderer::releaseGl() {
    if (!m_gl) return;
    auto del = [&](unsigned& b) {
        if (b) glDeleteBuffers(1, &b);
        b = 0;
    };
    for (auto& [name, p] : m_programs) glDeleteProgram(p);
    m_programs.clear();
    for (auto& [k, b] : m_kernelBuffers) glDeleteBuffers(1, &b);
    m_kernelBuffers.clear();
    for (auto& [k, b] : m_kernelDerivativeBuffers) glDeleteBuffers(1, &b);
    m_kernelDerivativeBuffers.clear();
    del(m_twiddles);
    del(m_bufA);
    del(m_bufB);
    del(m_image);
    del(m_hartleyT);
    del(m_filterAxis);
    del(m_table);
    m_tableFor.reset();
    releaseTexture();
    if (m_display) glDeleteTextures(1, &m_display);
    m_display = 0;
    m_displayed.reset();
    if (m_queries[0]) glDeleteQueries(4, m_queries);
    std::fill(std::begin(m_queries), std::end(m_queries), 0u);
    m_size = 0;
    m_gl = false;
}

std::string GpuFourierRenderer::rendererInfo() const {
    auto str = [&](GLenum e) {
        const auto* s = reinterpret_cast<const char*>(glGetString(e));
        return s ? std::string(s) : std::string("?");
    };
    return str(GL_RENDERER) + " (" + str(GL_VERSION) + ")";
}

unsigned GpuFourierRenderer::program(
    const std::string& path, const std::vector<std::pair<std::string, std::string>>& defines) {
    std::string key = path;
    for (const auto& [n, v] : defines) key += "|" + n + "=" + v;
    if (auto it = m_programs.find(key); it != m_programs.end()) return it->second;
    const GLuint prog = compileComputeProgram(
        ShaderSource::assemble(path, defines, ShaderSource::defaultReader()), key);
    m_programs.emplace(key, prog);
    return prog;
}

void GpuFourierRenderer::releaseTexture() {
    if (!m_texture) return;
    std::lock_guard lock(textureMutex());
    auto& cache = textureCache();
    const TextureKey key{m_textureKey[0], m_textureKey[1], m_textureKey[2]};
    auto it = cache.find(key);
    if (it != cache.end() && it->second.id == m_texture) {
        if (--it->second.refs == 0) {
            glDeleteTextures(1, &it->second.id);
            cache.erase(it);
        }
    } else {
        glDeleteTextures(1, &m_texture);
    }
    m_texture = 0;
    m_textureBytes = 0;
    m_textureKey[0] = m_textureKey[1] = m_textureKey[2] = nullptr;
}

namespace {

/** The spectrum's 3D texture: RG (complex half spectrum) or R (Hartley), float32 or float16. */
struct TextureShape {
    GLint width = 0, height = 0, depth = 0;
    GLenum internal = 0, format = 0;
    std::size_t bytes = 0;
};

TextureShape textureShape(const core::Spectrum& s, SpectrumPrecision precision) {
    const bool fht = s.kind == core::TransformKind::Fht;
    const bool half = precision == SpectrumPrecision::Float16;
    TextureShape t;
    t.width = GLint(fht ? s.padded[0] : s.padded[0] / 2 + 1);
    t.height = GLint(s.padded[1]);
    t.depth = GLint(s.padded[2]);
    t.internal = fht ? (half ? GL_R16F : GL_R32F) : (half ? GL_RG16F : GL_RG32F);
    t.format = fht ? GL_RED : GL_RG;
    const std::size_t channels = fht ? 1 : 2;
    t.bytes = std::size_t(t.width) * t.height * t.depth * channels * (half ? 2 : 4);
    return t;
}

/** The texture another renderer of the share group uploaded for this key (one more reference),
 *  or 0. */
GLuint findSharedTexture(const TextureKey& key, std::size_t& bytes) {
    std::lock_guard lock(textureMutex());
    auto it = textureCache().find(key);
    if (it == textureCache().end()) return 0;
    ++it->second.refs;
    bytes = it->second.bytes;
    return it->second.id;
}

/** Throws GpuMemoryError when the texture exceeds the 3D texture limit or, where the driver
 *  reports it (NVIDIA, AMD), the free memory plus what the current texture frees. */
void checkTextureFits(const TextureShape& t, std::size_t currentBytes) {
    GLint max3d = 0;
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &max3d);
    if (t.width > max3d || t.height > max3d || t.depth > max3d)
        throw GpuMemoryError("spectrum texture " + std::to_string(t.width) + "x" +
                             std::to_string(t.height) + "x" + std::to_string(t.depth) +
                             " exceeds the GPU's 3D texture limit of " + std::to_string(max3d) +
                             " per axis");
    // Free memory where the driver tells (NVIDIA, AMD); otherwise the upload's GL_OUT_OF_MEMORY.
    GLint freeKiB[4] = {0, 0, 0, 0};
    if (epoxy_has_gl_extension("GL_NVX_gpu_memory_info"))
        glGetIntegerv(kGpuMemoryInfoAvailableNvx, freeKiB);
    else if (epoxy_has_gl_extension("GL_ATI_meminfo"))
        glGetIntegerv(kTextureFreeMemoryAti, freeKiB);
    while (glGetError() != GL_NO_ERROR) {}
    const std::size_t freeBytes = std::size_t(freeKiB[0]) * 1024;
    if (freeBytes > 0 && t.bytes > freeBytes + currentBytes)
        throw GpuMemoryError("spectrum needs " + std::to_string(t.bytes >> 20) +
                             " MiB of GPU memory, " +
                             std::to_string((freeBytes + currentBytes) >> 20) +
                             " MiB are free (try fp16 storage or a smaller oversampling)");
}

/** Allocates the bound 3D texture and uploads the spectrum in slabs; returns the first GL error. */
GLenum uploadSpectrum(const core::Spectrum& s, const TextureShape& t) {
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexStorage3D(GL_TEXTURE_3D, 1, t.internal, t.width, t.height, t.depth);
    GLenum err = glGetError();
    if (err != GL_NO_ERROR) return err;
    const bool fht = s.kind == core::TransformKind::Fht;
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, GLint(fht ? s.rowStride() : 0));
    // Upload in slabs so the driver never copies the whole volume at once.
    const GLint slab =
        std::max<GLint>(1, GLint((64 << 20) / (std::size_t(s.rowStride()) * t.height * 4)));
    for (GLint z = 0; z < t.depth && err == GL_NO_ERROR; z += slab) {
        const GLint n = std::min(slab, t.depth - z);
        const float* src = s.data.get() + std::size_t(z) * s.rowStride() * t.height;
        glTexSubImage3D(GL_TEXTURE_3D, 0, 0, 0, z, t.width, t.height, n, t.format, GL_FLOAT, src);
        err = glGetError();
    }
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    return err;
}

} // namespace

void GpuFourierRenderer::adoptTexture(unsigned id, std::size_t bytes, const void* const key[3]) {
    m_texture = id;
    m_textureBytes = bytes;
    for (int i = 0; i < 3; ++i) m_textureKey[i] = key[i];
}

void GpuFourierRenderer::setSpectrum(std::shared_ptr<const core::Spectrum> s,
                                     SpectrumPrecision precision) {
    if (!s || !s->data) throw GlError("GPU renderer: no spectrum");
    const void* group = m_shareGroup;
    const TextureKey key{s.get(), reinterpret_cast<const void*>(std::uintptr_t(precision) + 1),
                         group};
    const void* const keyParts[3] = {std::get<0>(key), std::get<1>(key), std::get<2>(key)};
    if (m_texture && TextureKey{m_textureKey[0], m_textureKey[1], m_textureKey[2]} == key) {
        m_spectrum = std::move(s);
        return; // already this texture
    }
    std::size_t sharedBytes = 0;
    if (const GLuint sharedId =
            findSharedTexture(key, sharedBytes)) { // another renderer uploaded it
        releaseTexture();
        adoptTexture(sharedId, sharedBytes, keyParts);
        m_spectrum = std::move(s);
        return;
    }
    const TextureShape shape = textureShape(*s, precision);
    checkTextureFits(shape, m_texture ? m_textureBytes : 0);
    releaseTexture();
    glGenTextures(1, &m_texture);
    glBindTexture(GL_TEXTURE_3D, m_texture);
    if (const GLenum err = uploadSpectrum(*s, shape); err != GL_NO_ERROR) {
        glDeleteTextures(1, &m_texture);
        m_texture = 0;
        m_spectrum.reset();
        if (err == GL_OUT_OF_MEMORY)
            throw GpuMemoryError(
                "spectrum texture of " + std::to_string(shape.bytes >> 20) +
                " MiB does not fit in GPU memory (try fp16 storage or a smaller oversampling)");
        throw GlError("spectrum upload failed: " + glErrorName(err));
    }
    {
        std::lock_guard lock(textureMutex());
        textureCache()[key] = SharedTexture{m_texture, shape.bytes, 1, s};
    }
    adoptTexture(m_texture, shape.bytes, keyParts);
    m_spectrum = std::move(s);
}

void GpuFourierRenderer::ensureSize(int M) {
    if (m_size == M) return;
    auto buffer = [&](unsigned& b, std::size_t bytes, const void* data = nullptr) {
        if (!b) glGenBuffers(1, &b);
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, b);
        glBufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(bytes), data, GL_DYNAMIC_COPY);
    };
    const FftPlan plan(M, +1);
    buffer(m_twiddles, plan.twiddles().size() * sizeof(float), plan.twiddles().data());
    const std::size_t n = std::size_t(M) * M;
    buffer(m_bufA, n * 8);
    buffer(m_bufB, n * 8);
    buffer(m_image, n * 4);
    buffer(m_hartleyT, n * 4);
    if (const GLenum err = glGetError(); err != GL_NO_ERROR)
        throw GlError("GPU buffers for M = " + std::to_string(M) + ": " + glErrorName(err));
    if (m_display) glDeleteTextures(1, &m_display);
    glGenTextures(1, &m_display);
    glBindTexture(GL_TEXTURE_2D, m_display);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA8, M, M);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    m_size = M;
}

void GpuFourierRenderer::bindKernel(unsigned prog, Kernel kernel, bool derivative) {
    // Kaiser-Bessel tables depend on the spectrum's oversampling: rebuild on a change.
    const double sigma = m_spectrum
                             ? core::kernelOversampling(m_spectrum->volumeDims, m_spectrum->padded)
                             : core::kDefaultKernelOversampling;
    auto it = m_kernelBuffers.find(kernel);
    if (m_tables.at(kernel)->oversampling() != sigma) {
        m_tables[kernel] = std::make_unique<core::KernelTable>(kernel, sigma);
        if (it != m_kernelBuffers.end()) {
            glDeleteBuffers(1, &it->second);
            m_kernelBuffers.erase(it);
            it = m_kernelBuffers.end();
        }
        if (auto d = m_kernelDerivativeBuffers.find(kernel); d != m_kernelDerivativeBuffers.end()) {
            glDeleteBuffers(1, &d->second);
            m_kernelDerivativeBuffers.erase(d);
        }
    }
    auto upload = [&](const std::vector<float>& t) {
        GLuint b = 0;
        glGenBuffers(1, &b);
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, b);
        glBufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(t.size() * sizeof(float)), t.data(),
                     GL_STATIC_DRAW);
        return b;
    };
    if (it == m_kernelBuffers.end())
        it = m_kernelBuffers.emplace(kernel, upload(m_tables.at(kernel)->table())).first;
    bindStorage(Binding::KernelTable, it->second);
    if (derivative) {
        auto d = m_kernelDerivativeBuffers.find(kernel);
        if (d == m_kernelDerivativeBuffers.end())
            d = m_kernelDerivativeBuffers
                    .emplace(kernel, upload(m_tables.at(kernel)->derivativeTable()))
                    .first;
        bindStorage(Binding::KernelDerivative, d->second);
    }
    glUniform1i(glGetUniformLocation(prog, "uKernelRes"), core::KernelTable::kResolution);
    glUniform1i(glGetUniformLocation(prog, "uKernelFirst"), m_tables.at(kernel)->firstTapOffset());
}

void GpuFourierRenderer::setSliceUniforms(unsigned prog, const core::RenderParams& p) {
    const core::Spectrum& s = *m_spectrum;
    const core::SliceParams sp = core::sliceParams(s, p);
    auto loc = [&](const char* n) { return glGetUniformLocation(prog, n); };
    auto vec3 = [&](const char* n, const double* v) {
        glUniform3f(loc(n), float(v[0]), float(v[1]), float(v[2]));
    };
    glUniform3i(loc("uPadded"), GLint(sp.padded[0]), GLint(sp.padded[1]), GLint(sp.padded[2]));
    // The band cut of the band-limited model with a tolerance for float rounding; the other
    // models read every frequency.
    float half[3];
    for (int a = 0; a < 3; ++a) half[a] = sp.banded ? float(sp.half[a] + 1e-4) : 1e30f;
    glUniform3f(loc("uHalf"), half[0], half[1], half[2]);
    glUniform1i(loc("uVoxelModel"),
                sp.banded ? 0 : (p.voxelModel == core::VoxelModel::Trilinear ? 1 : 2));
    glUniform3i(loc("uAnti"), GLint(sp.anti[0]), GLint(sp.anti[1]), GLint(sp.anti[2]));
    vec3("uInvP", sp.invP);
    vec3("uA", sp.A);
    vec3("uB", sp.B);
    glUniform1f(loc("uScale"), float(sp.scale));
    glActiveTexture(GL_TEXTURE0 + point(TextureUnit::Spectrum)); // uSpectrum's layout binding
    glBindTexture(GL_TEXTURE_3D, m_texture);
    if (sp.depth) {
        glUniform1f(loc("uDepthA"), float(sp.depthA));
        vec3("uDepthE", sp.E);
    }
    setFilterUniforms(prog, p);
    bindKernel(prog, p.kernel, sp.depth);
}

void GpuFourierRenderer::setFilterUniforms(unsigned prog, const core::RenderParams& p) {
    const core::SliceFilterTable filter(p.filter, p.pixelAperture, p.image.size, p.image.pixelSize);
    auto loc = [&](const char* n) { return glGetUniformLocation(prog, n); };
    glUniform1i(loc("uFilterOn"), filter.on ? 1 : 0);
    glUniform1f(loc("uSharpenAmount"), filter.amount);
    glUniform1f(loc("uBandInv2"), filter.invCut2);
    glUniform1i(loc("uAperture"), filter.aperture ? 1 : 0);
    if (!filter.on) return;
    // The per-axis table (blur, aperture) of core::SliceFilterTable: slice.glsl combines it.
    if (!m_filterAxis) glGenBuffers(1, &m_filterAxis);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_filterAxis);
    glBufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(filter.axis.size() * sizeof(float)),
                 filter.axis.data(), GL_DYNAMIC_DRAW);
    bindStorage(Binding::FilterAxis, m_filterAxis);
}

void GpuFourierRenderer::runRows(int M, bool fused, bool hartley, Kernel kernel,
                                 const core::RenderParams* params) {
    std::vector<std::pair<std::string, std::string>> defs{
        {"MAX_M", std::to_string(M)}, {"WG_SIZE", std::to_string(workGroupSize(M))}};
    if (fused) {
        defs.emplace_back("FUSED_SLICE", "1");
        defs.emplace_back("TAPS", std::to_string(core::sliceTaps(kernel, params->depthCue > 0.0)));
        if (m_spectrum->kind == core::TransformKind::Fht) defs.emplace_back("SPECTRUM_FHT", "1");
        if (params->depthCue > 0.0) defs.emplace_back("DEPTH_CUE", "1");
    }
    if (hartley) defs.emplace_back("HARTLEY_ROWS", "1");
    const GLuint prog = program("fft/rows.comp", defs);
    glUseProgram(prog);
    glUniform1i(glGetUniformLocation(prog, "uM"), M);
    if (fused) setSliceUniforms(prog, *params);
    bindStorage(Binding::PassInput, m_bufA); // read unless fused: the slice, or inverseFft2D's data
    bindStorage(Binding::PassOutput, m_bufB); // transposed
    bindStorage(Binding::Twiddles, m_twiddles);
    glDispatchCompute(GLuint(M), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
}

void GpuFourierRenderer::runCols(int M, const char* outputMode, const core::RenderParams* params,
                                 const core::DisplayWindow* display) {
    std::vector<std::pair<std::string, std::string>> defs{
        {"MAX_M", std::to_string(M)},
        {"WG_SIZE", std::to_string(workGroupSize(M))},
        {outputMode, "1"}};
    const bool real = std::strcmp(outputMode, "OUTPUT_REAL") == 0;
    if (display && !real)
        throw std::logic_error("runCols: the display mapping fuses into OUTPUT_REAL only");
    if (display) defs.emplace_back("FUSED_DISPLAY", "1");
    const GLuint prog = program("fft/cols.comp", defs);
    glUseProgram(prog);
    glUniform1i(glGetUniformLocation(prog, "uM"), M);
    if (real) setClipUniforms(prog, params);
    if (display) setDisplayUniforms(prog, *display);
    bindStorage(Binding::PassInput, m_bufB);
    const bool complexOut = std::strcmp(outputMode, "OUTPUT_COMPLEX") == 0;
    const bool hartleyOut = std::strcmp(outputMode, "OUTPUT_HARTLEY") == 0;
    bindStorage(Binding::PassOutput, complexOut ? m_bufA : (hartleyOut ? m_hartleyT : m_image));
    bindStorage(Binding::Twiddles, m_twiddles);
    glDispatchCompute(GLuint(M), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
}

void GpuFourierRenderer::setClipUniforms(unsigned prog, const core::RenderParams* p) {
    auto loc = [&](const char* n) { return glGetUniformLocation(prog, n); };
    const bool clip = p && p->clipToVolume && m_spectrum;
    glUniform1i(loc("uClip"), clip ? 1 : 0);
    glUniform1i(loc("uNonNegative"),
                p && p->nonNegative && m_spectrum && m_spectrum->nonNegative ? 1 : 0);
    if (!clip) return;
    const core::Spectrum& s = *m_spectrum;
    const core::Vec3 half =
        core::supportHalfExtents(s.volumeDims, s.spacing, core::voxelModelReach(p->voxelModel));
    // GL takes floats: each double vector is rounded once, here.
    auto vec3 = [&](const char* n, const core::Vec3& v) {
        glUniform3fv(loc(n), 1, glm::value_ptr(glm::vec3(v)));
    };
    vec3("uBoxHalf", half);
    vec3("uViewD", p->view.d);
    vec3("uViewR", p->view.r);
    vec3("uViewU", p->view.u);
    glUniform1f(loc("uPixel"), float(p->image.pixelSize));
}

void GpuFourierRenderer::setDisplayUniforms(unsigned prog, const core::DisplayWindow& w) {
    auto loc = [&](const char* n) { return glGetUniformLocation(prog, n); };
    glUniform1f(loc("uLow"), float(w.low));
    glUniform1f(loc("uHigh"), float(w.high > w.low ? w.high : w.low + 1.0));
    glUniform1i(loc("uInvert"), w.invert ? 1 : 0);
    glUniform1f(loc("uMuWater"),
                float(w.transmission.active() ? w.transmission.muWaterPerMm : 0.0));
    glUniform1f(loc("uExposure"), float(w.transmission.exposure));
    glBindImageTexture(point(ImageUnit::Display), m_display, 0, GL_FALSE, 0, GL_WRITE_ONLY,
                       GL_RGBA8);
}

void GpuFourierRenderer::runHartleyCorrection(int M, const core::RenderParams* params,
                                              const core::DisplayWindow* display) {
    const GLuint prog =
        program("fft/hartley_correct.comp",
                display ? std::vector<std::pair<std::string, std::string>>{{"FUSED_DISPLAY", "1"}}
                        : std::vector<std::pair<std::string, std::string>>{});
    glUseProgram(prog);
    glUniform1i(glGetUniformLocation(prog, "uM"), M);
    setClipUniforms(prog, params);
    if (display) setDisplayUniforms(prog, *display);
    bindStorage(Binding::PassInput, m_hartleyT);
    bindStorage(Binding::PassOutput, m_image);
    glDispatchCompute(GLuint((M + 15) / 16), GLuint((M + 15) / 16), 1);
    glMemoryBarrier(
        GL_SHADER_STORAGE_BARRIER_BIT |
        (display ? GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT : 0));
}

void GpuFourierRenderer::renderToGpu(const core::RenderParams& requested,
                                     const core::DisplayWindow* display) {
    const core::PlannerBusyScope busy; // the CPU's FFTW planner measures between frames only
    if (!m_spectrum) throw GlError("GPU renderer: no spectrum uploaded");
    core::validateRenderParams(requested, *m_spectrum);
    core::checkKernelMatchesSpectrum(*m_spectrum, requested.kernel);
    // The FFT passes need a power of two: a W x H image is the centred crop of the square of
    // the next one (readback() crops), at the same pixel size.
    core::RenderParams p = requested;
    p.image = {
        core::fourierSide(requested.image, m_spectrum->volumeDims, m_spectrum->spacing, true),
        requested.image.pixelSize};
    const int M = p.image.size;
    if (M > 4096) throw core::SettingsError("GPU slice size: at most 4096");
    ensureSize(M);
    const bool fht = m_spectrum->kind == core::TransformKind::Fht;
    glQueryCounter(m_queries[0], GL_TIMESTAMP);
    if (!m_fuse) {
        std::vector<std::pair<std::string, std::string>> defs{
            {"TAPS", std::to_string(core::sliceTaps(p.kernel, p.depthCue > 0.0))}};
        if (fht) defs.emplace_back("SPECTRUM_FHT", "1");
        if (p.depthCue > 0.0) defs.emplace_back("DEPTH_CUE", "1");
        const GLuint prog = program("slice/slice.comp", defs);
        glUseProgram(prog);
        glUniform1i(glGetUniformLocation(prog, "uM"), M);
        setSliceUniforms(prog, p);
        bindStorage(Binding::PassOutput, m_bufA);
        glDispatchCompute(GLuint((M + 15) / 16), GLuint((M + 15) / 16), 1);
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    }
    glQueryCounter(m_queries[1], GL_TIMESTAMP);
    runRows(M, m_fuse, fht, p.kernel, &p);
    if (!fht) {
        runCols(M, "OUTPUT_REAL", &p, display);
    } else {
        runCols(M, "OUTPUT_HARTLEY", &p);
        runHartleyCorrection(M, &p, display);
    }
    glQueryCounter(m_queries[2], GL_TIMESTAMP);
    if (const GLenum err = glGetError(); err != GL_NO_ERROR)
        throw GlError("GPU render failed: " + glErrorName(err));
    m_timesPending = true;
    m_displayTimed = false;
    m_last = p;
    m_lastWidth = requested.image.cols();
    m_lastHeight = requested.image.rows();
    m_displayed = display ? std::optional<core::DisplayWindow>(*display) : std::nullopt;
}

core::ProjectionImage GpuFourierRenderer::readback() const {
    if (!m_size) throw GlError("GPU renderer: nothing rendered yet");
    core::ProjectionImage img;
    img.width = img.height = m_last.image.size;
    img.pixelSize = m_last.image.pixelSize;
    img.view = m_last.view;
    img.mapping = m_spectrum->mapping;
    img.pixels.resize(std::size_t(img.width) * img.height);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_image);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(img.pixels.size() * 4),
                       img.pixels.data());
    return core::cropProjection(std::move(img), m_lastWidth, m_lastHeight);
}

core::ProjectionImage GpuFourierRenderer::render(const core::RenderParams& p,
                                                 core::StageTimes* times) {
    GpuStageTimes t;
    auto img = renderImage(p, times ? &t : nullptr);
    if (times) *times = {t.sliceMs, t.inverseMs + t.displayMs, t.totalMs};
    return img;
}

core::ProjectionImage GpuFourierRenderer::renderImage(const core::RenderParams& p,
                                                      GpuStageTimes* times) {
    renderToGpu(p);
    auto img = readback();
    if (times) *times = lastTimes();
    return img;
}

std::string GpuFourierRenderer::describe() const { return "GPU: " + rendererInfo(); }

namespace {
bool sameWindow(const core::DisplayWindow& a, const core::DisplayWindow& b) {
    return a.low == b.low && a.high == b.high && a.invert == b.invert &&
           a.transmission.muWaterPerMm == b.transmission.muWaterPerMm &&
           a.transmission.exposure == b.transmission.exposure;
}
} // namespace

unsigned GpuFourierRenderer::displayTexture(const core::DisplayWindow& w) {
    if (!m_size) throw GlError("GPU renderer: nothing rendered yet");
    if (m_displayed && sameWindow(*m_displayed, w)) return m_display; // fused into the render
    const int M = m_size;
    const GLuint prog = program("display/display.comp", {});
    glUseProgram(prog);
    glUniform1i(glGetUniformLocation(prog, "uM"), M);
    setDisplayUniforms(prog, w);
    bindStorage(Binding::PassInput, m_image);
    glDispatchCompute(GLuint((M + 15) / 16), GLuint((M + 15) / 16), 1);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
    glQueryCounter(m_queries[3], GL_TIMESTAMP);
    m_displayTimed = m_timesPending;
    m_displayed = w;
    return m_display;
}

GpuStageTimes GpuFourierRenderer::lastTimes() {
    if (!m_timesPending) return m_times;
    GLuint64 t[4] = {0, 0, 0, 0};
    const int n = m_displayTimed ? 4 : 3;
    for (int i = 0; i < n; ++i) glGetQueryObjectui64v(m_queries[i], GL_QUERY_RESULT, &t[i]);
    m_times.fused = m_fuse;
    m_times.displayFused = m_displayed.has_value() && !m_displayTimed;
    m_times.sliceMs = double(t[1] - t[0]) * 1e-6;
    m_times.inverseMs = double(t[2] - t[1]) * 1e-6;
    m_times.displayMs = m_displayTimed ? double(t[3] - t[2]) * 1e-6 : 0.0;
    m_times.totalMs = double(t[n - 1] - t[0]) * 1e-6;
    m_timesPending = false;
    return m_times;
}

std::vector<std::complex<float>> GpuFourierRenderer::inverseFft2D(
    const std::vector<std::complex<float>>& data, int M) {
    if (data.size() != std::size_t(M) * M)
        throw core::SettingsError("inverseFft2D: data size is not M*M");
    ensureSize(M);
    m_displayed.reset();
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_bufA);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(data.size() * 8), data.data());
    runRows(M, false, false, Kernel::Linear, nullptr);
    runCols(M, "OUTPUT_COMPLEX", nullptr);
    std::vector<std::complex<float>> out(data.size());
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_bufA);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(out.size() * 8), out.data());
    return out;
}

std::vector<float> GpuFourierRenderer::inverseFht2D(const std::vector<float>& data, int M) {
    if (data.size() != std::size_t(M) * M)
        throw core::SettingsError("inverseFht2D: data size is not M*M");
    ensureSize(M);
    m_displayed.reset();
    std::vector<std::complex<float>> in(data.begin(), data.end());
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_bufA);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(in.size() * 8), in.data());
    runRows(M, false, true, Kernel::Linear, nullptr);
    runCols(M, "OUTPUT_HARTLEY", nullptr);
    runHartleyCorrection(M, nullptr);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<float> out(data.size());
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_image);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(out.size() * 4), out.data());
    return out;
}

int GpuFourierRenderer::compileAll(int M) {
    const std::string mm = std::to_string(M), wg = std::to_string(workGroupSize(M));
    int count = 0;
    for (int taps : {1, 2, 3, 4, 6})
        for (bool fht : {false, true})
            for (bool depth : {false, true}) {
                if (depth != (taps == 3) && taps <= 3)
                    continue; // nearest: no derivative; linear + depth: 3 taps
                std::vector<std::pair<std::string, std::string>> d{{"TAPS", std::to_string(taps)}};
                if (fht) d.emplace_back("SPECTRUM_FHT", "1");
                if (depth) d.emplace_back("DEPTH_CUE", "1");
                program("slice/slice.comp", d), ++count;
                auto r = d;
                r.insert(r.begin(), {{"MAX_M", mm}, {"WG_SIZE", wg}});
                r.emplace_back("FUSED_SLICE", "1");
                if (fht) r.emplace_back("HARTLEY_ROWS", "1");
                program("fft/rows.comp", r), ++count;
            }
    for (bool hartley : {false, true}) {
        std::vector<std::pair<std::string, std::string>> r{{"MAX_M", mm}, {"WG_SIZE", wg}};
        if (hartley) r.emplace_back("HARTLEY_ROWS", "1");
        program("fft/rows.comp", r), ++count;
    }
    for (const char* mode : {"OUTPUT_REAL", "OUTPUT_HARTLEY", "OUTPUT_COMPLEX"})
        program("fft/cols.comp", {{"MAX_M", mm}, {"WG_SIZE", wg}, {mode, "1"}}), ++count;
    program("fft/cols.comp",
            {{"MAX_M", mm}, {"WG_SIZE", wg}, {"OUTPUT_REAL", "1"}, {"FUSED_DISPLAY", "1"}}),
        ++count;
    program("fft/hartley_correct.comp", {}), ++count;
    program("fft/hartley_correct.comp", {{"FUSED_DISPLAY", "1"}}), ++count;
    program("display/display.comp", {}), ++count;
    for (const char* k : {"1", "2", "3", "4", "5"})
        program("xray/spectral_sum.comp", {{"MATERIALS", k}}), ++count;
    return count;
}

} // namespace fvr::gpu
