#include <fvr/gpu/cone_ray_caster.h>

#include <fvr/core/text.h>

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <utility>

#include <glm/gtc/type_ptr.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/xray/xray.h>
#include <fvr/gpu/bindings.h>
#include <fvr/gpu/errors.h>
#include <fvr/gpu/gl_info.h>
#include <fvr/gpu/shader_program.h>
#include <fvr/gpu/shader_source.h>

namespace fvr::gpu {

using core::RayModel;
using core::SettingsError;

namespace {

std::string dimsText(const core::Dims3& d) {
    return std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" + std::to_string(d[2]);
}

/** SettingsError for what the GPU caster cannot do or a volume that is not one. */
void checkInput(const core::Volume& v, const core::ConeProjectorOptions& o) {
    if (o.model == RayModel::BSpline)
        throw SettingsError("GPU cone-beam ray caster: the B-spline model runs on the CPU only "
                            "(use trilinear or box)");
    if (o.model == RayModel::Trilinear && !(o.stepFraction >= 0.0 && o.stepFraction <= 4.0))
        throw SettingsError("GPU cone-beam ray caster: step " + core::formatNumber(o.stepFraction) +
                            " is not in 0..4 (a fraction of the smallest voxel spacing)");
    if (o.pixelSubsamples < 1 || o.pixelSubsamples > 16)
        throw SettingsError("GPU cone-beam ray caster: " + std::to_string(o.pixelSubsamples) +
                            " subsamples per pixel side, expected 1..16");
    for (int a = 0; a < 3; ++a) {
        if (v.dims[a] < 1)
            throw SettingsError("GPU cone-beam ray caster: volume '" + v.name + "' has dims " +
                                dimsText(v.dims));
        if (!(v.spacing[a] > 0.0) || !std::isfinite(v.spacing[a]))
            throw SettingsError("GPU cone-beam ray caster: volume '" + v.name +
                                "' has a spacing that is not > 0 and finite");
    }
    if (v.voxels.size() != std::size_t(v.voxelCount()))
        throw SettingsError("GPU cone-beam ray caster: volume '" + v.name + "' holds " +
                            std::to_string(v.voxels.size()) + " voxels, its dims " +
                            dimsText(v.dims) + " say " + std::to_string(v.voxelCount()));
}

/** GpuMemoryError when the texture exceeds the 3D texture limit or, where the driver reports
 *  it (NVIDIA, AMD), the free GPU memory. */
void checkTextureFits(const core::Dims3& dims, std::size_t bytes) {
    GLint max3d = 0;
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &max3d);
    if (dims[0] > max3d || dims[1] > max3d || dims[2] > max3d)
        throw GpuMemoryError("volume texture " + dimsText(dims) +
                             " exceeds the GPU's 3D texture limit of " + std::to_string(max3d) +
                             " per axis (the cone-beam ray caster needs the whole volume)");
    // Free memory where the driver tells (NVIDIA, AMD: currentGlInfo); else the upload's error.
    const GlInfo gl = currentGlInfo();
    const std::size_t freeBytes = gl.freeMemoryKiB > 0 ? std::size_t(gl.freeMemoryKiB) * 1024 : 0;
    if (freeBytes > 0 && bytes > freeBytes)
        throw GpuMemoryError("volume texture " + dimsText(dims) + " needs " +
                             std::to_string(bytes >> 20) + " MiB of GPU memory, " +
                             std::to_string(freeBytes >> 20) + " MiB are free");
}

/** The volume without its voxels (validateConeView needs only where it lies). */
core::Volume geometryOf(const core::Volume& v) {
    core::Volume g;
    g.dims = v.dims;
    g.spacing = v.spacing;
    g.origin = v.origin;
    g.direction = v.direction;
    g.units = v.units;
    g.orientationStated = v.orientationStated;
    g.name = v.name;
    return g;
}

} // namespace

BlockMap::BlockMap(const core::Dims3& d, bool tri) : dims(d), trilinear(tri) {
    for (int a = 0; a < 3; ++a) blocks[a] = (d[a] + (tri ? 1 : 0) + 7) / 8;
    occupied.assign(std::size_t(blocks[0] * blocks[1] * blocks[2]), 0);
}

void BlockMap::mark(const float* values, std::int64_t z0, std::int64_t slices) {
    const std::int64_t span = trilinear ? 2 : 1; // voxel x is a corner of cells x and x + 1
    for (std::int64_t z = 0; z < slices; ++z)
        for (std::int64_t y = 0; y < dims[1]; ++y) {
            const float* row = values + (z * dims[1] + y) * dims[0];
            for (std::int64_t x = 0; x < dims[0]; ++x) {
                if (row[x] == 0.0f) continue;
                for (std::int64_t dz = 0; dz < span; ++dz)
                    for (std::int64_t dy = 0; dy < span; ++dy)
                        for (std::int64_t dx = 0; dx < span; ++dx) {
                            const std::int64_t bx = (x + dx) / 8, by = (y + dy) / 8,
                                               bz = (z0 + z + dz) / 8;
                            occupied[std::size_t(bx + blocks[0] * (by + blocks[1] * bz))] = 1;
                        }
            }
        }
}

const char* trilinearFetchName(TrilinearFetch f) {
    return f == TrilinearFetch::Hardware ? "hardware" : "manual";
}

ConeRayCaster::ConeRayCaster(const core::Volume& volume, core::ConeProjectorOptions options,
                             TrilinearFetch fetch)
    : m_options(options), m_fetch(fetch) {
    checkInput(volume, options);
    if (!currentNativeContext())
        throw GlError("GPU cone-beam ray caster: no current OpenGL context");
    const int version = epoxy_gl_version();
    if (version < 43 || !epoxy_is_desktop_gl())
        throw GlError("GPU cone-beam ray caster: OpenGL 4.3 (compute shaders) needed, the "
                      "context offers " +
                      std::to_string(version / 10) + "." + std::to_string(version % 10));
    m_geometry = geometryOf(volume);
    const glm::dmat4 indexToPatient = core::indexToPatient(volume);
    m_patientToIndex = glm::inverse(indexToPatient);
    m_indexToMm = glm::dmat3(indexToPatient);
    upload(volume);
    try {
        m_program =
            compileComputeProgram(ShaderSource::assemble("cone/cone_ray.comp", shaderDefines(),
                                                         ShaderSource::defaultReader()),
                                  "cone/cone_ray.comp");
    } catch (...) {
        glDeleteTextures(1, &m_texture);
        if (m_occupancy) glDeleteTextures(1, &m_occupancy);
        throw;
    }
}

ConeRayCaster::~ConeRayCaster() {
    if (!currentNativeContext()) return; // the context is gone, and its objects with it
    if (m_program) glDeleteProgram(m_program);
    if (m_texture) glDeleteTextures(1, &m_texture);
    if (m_occupancy) glDeleteTextures(1, &m_occupancy);
    if (m_output) glDeleteBuffers(1, &m_output);
    if (m_views) glDeleteBuffers(1, &m_views);
}

std::vector<std::pair<std::string, std::string>> ConeRayCaster::shaderDefines() const {
    const int model = m_options.model == RayModel::Box ? 0 : m_options.stepFraction > 0 ? 2 : 1;
    return {{"MODEL", std::to_string(model)},
            {"HW_FILTER", model != 0 && m_fetch == TrilinearFetch::Hardware ? "1" : "0"},
            {"SUBSAMPLES", std::to_string(m_options.pixelSubsamples)},
            {"SKIP_EMPTY", m_options.skipEmpty ? "1" : "0"}};
}

void ConeRayCaster::upload(const core::Volume& volume) {
    const core::Dims3& d = volume.dims;
    m_textureBytes = std::size_t(volume.voxelCount()) * sizeof(float);
    checkTextureFits(d, m_textureBytes);
    glGenTextures(1, &m_texture);
    glBindTexture(GL_TEXTURE_3D, m_texture);
    glTexStorage3D(GL_TEXTURE_3D, 1, GL_R32F, GLsizei(d[0]), GLsizei(d[1]), GLsizei(d[2]));
    GLenum err = glGetError();
    // Slabs of mapped values: the mapping never copies the whole volume.
    const std::size_t slice = std::size_t(d[0] * d[1]);
    const std::int64_t slab = std::max<std::int64_t>(1, std::int64_t((16u << 20) / slice));
    std::vector<float> buf(std::size_t(std::min(slab, d[2])) * slice);
    BlockMap blocks(d, m_options.model == RayModel::Trilinear);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    for (std::int64_t z = 0; z < d[2] && err == GL_NO_ERROR; z += slab) {
        const std::int64_t n = std::min(slab, d[2] - z);
        const float* src = volume.voxels.data() + std::size_t(z) * slice;
        for (std::size_t i = 0; i < std::size_t(n) * slice; ++i)
            buf[i] = core::mapValue(m_options.mapping, src[i]);
        if (m_options.skipEmpty) blocks.mark(buf.data(), z, n);
        glTexSubImage3D(GL_TEXTURE_3D, 0, 0, 0, GLint(z), GLsizei(d[0]), GLsizei(d[1]), GLsizei(n),
                        GL_RED, GL_FLOAT, buf.data());
        err = glGetError();
    }
    if (err != GL_NO_ERROR) {
        glDeleteTextures(1, &m_texture);
        m_texture = 0;
        if (err == GL_OUT_OF_MEMORY)
            throw GpuMemoryError("volume texture " + dimsText(d) + " (" +
                                 std::to_string(m_textureBytes >> 20) +
                                 " MiB) does not fit in GPU memory");
        throw GlError("volume upload failed: GL error " + std::to_string(err));
    }
    // GL_LINEAR with a zero border: outside the grid the interpolant falls to 0 over one voxel,
    // the CPU model's "zero outside" (texelFetch, the manual path, ignores both).
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    for (GLenum wrap : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R})
        glTexParameteri(GL_TEXTURE_3D, wrap, GL_CLAMP_TO_BORDER);
    const float border[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    glTexParameterfv(GL_TEXTURE_3D, GL_TEXTURE_BORDER_COLOR, border);
    if (m_options.skipEmpty) uploadBlocks(blocks);
}

void ConeRayCaster::uploadBlocks(const BlockMap& blocks) {
    glGenTextures(1, &m_occupancy);
    glBindTexture(GL_TEXTURE_3D, m_occupancy);
    glTexStorage3D(GL_TEXTURE_3D, 1, GL_R8UI, GLsizei(blocks.blocks[0]), GLsizei(blocks.blocks[1]),
                   GLsizei(blocks.blocks[2]));
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexSubImage3D(GL_TEXTURE_3D, 0, 0, 0, 0, GLsizei(blocks.blocks[0]), GLsizei(blocks.blocks[1]),
                    GLsizei(blocks.blocks[2]), GL_RED_INTEGER, GL_UNSIGNED_BYTE,
                    blocks.occupied.data());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    if (const GLenum err = glGetError(); err != GL_NO_ERROR) {
        glDeleteTextures(1, &m_occupancy);
        m_occupancy = 0;
        glDeleteTextures(1, &m_texture);
        m_texture = 0;
        throw GlError("block map upload failed: GL error " + std::to_string(err));
    }
}

void ConeRayCaster::uploadViews(const std::vector<core::ConeCamera>& cameras) {
    // Voxel indices relative to the grid's centre, in double: float then holds the ray where
    // the samples are, whatever the volume's origin or the source's distance.
    const core::Dims3& n = m_geometry.dims;
    const glm::dvec3 centre((n[0] - 1) * 0.5, (n[1] - 1) * 0.5, (n[2] - 1) * 0.5);
    const glm::dmat3 toIndex(m_patientToIndex);
    std::vector<glm::vec4> rays;
    rays.reserve(cameras.size() * 4);
    for (const auto& c : cameras) {
        const glm::dvec3 source(m_patientToIndex * glm::dvec4(c.source, 1.0));
        rays.emplace_back(glm::vec3(source - centre), 0.0f);
        rays.emplace_back(glm::vec3(toIndex * (c.pixelCentre(0.0, 0.0) - c.source)), 0.0f);
        rays.emplace_back(glm::vec3(toIndex * (c.pitchU * c.u)), 0.0f);
        rays.emplace_back(glm::vec3(toIndex * (c.pitchV * c.v)), 0.0f);
    }
    if (!m_views) glGenBuffers(1, &m_views);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_views);
    glBufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(rays.size() * sizeof(glm::vec4)), rays.data(),
                 GL_STREAM_DRAW);
}

void ConeRayCaster::setUniforms(int views) const {
    const core::Dims3& n = m_geometry.dims;
    const glm::vec3 centre((n[0] - 1) * 0.5, (n[1] - 1) * 0.5, (n[2] - 1) * 0.5);
    auto loc = [&](const char* name) { return glGetUniformLocation(m_program, name); };
    glUniform3i(loc("uSize"), m_width, m_height, views);
    glUniform3i(loc("uDims"), GLint(n[0]), GLint(n[1]), GLint(n[2]));
    glUniform3fv(loc("uCentre"), 1, glm::value_ptr(centre));
    const glm::mat3 toMm(m_indexToMm); // GL takes floats, column-major as GLM stores them
    glUniformMatrix3fv(loc("uIndexToMm"), 1, GL_FALSE, glm::value_ptr(toMm));
    const double minSpacing =
        std::min({m_geometry.spacing[0], m_geometry.spacing[1], m_geometry.spacing[2]});
    glUniform1f(loc("uStep"), float(m_options.stepFraction * minSpacing));
}

namespace {
/** GpuMemoryError when `views` images of W x H floats exceed the largest storage block or the
 *  dispatch's work group count. */
void checkOutputFits(int width, int height, std::size_t views) {
    GLint64 maxBlock = 0;
    glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &maxBlock);
    GLint maxGroupsZ = 0;
    glGetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_COUNT, 2, &maxGroupsZ);
    const std::size_t bytes = std::size_t(width) * std::size_t(height) * views * sizeof(float);
    if (maxBlock > 0 && bytes > std::size_t(maxBlock))
        throw GpuMemoryError(std::to_string(views) + " views of " + std::to_string(width) + "x" +
                             std::to_string(height) + " need " + std::to_string(bytes >> 20) +
                             " MiB, more than the GPU's largest storage buffer (" +
                             std::to_string(maxBlock >> 20) + " MiB): render fewer at once");
    if (maxGroupsZ > 0 && views > std::size_t(maxGroupsZ))
        throw GpuMemoryError(std::to_string(views) + " views in one dispatch, the GPU allows " +
                             std::to_string(maxGroupsZ));
}
} // namespace

void ConeRayCaster::projectToGpu(const std::vector<core::ConeCamera>& cameras) {
    if (cameras.empty()) throw SettingsError("GPU cone-beam ray caster: no view to render");
    const int W = cameras.front().width, H = cameras.front().height;
    for (const auto& c : cameras) {
        if (c.width != W || c.height != H)
            throw SettingsError("GPU cone-beam ray caster: views of one dispatch must share a "
                                "detector size, found " +
                                std::to_string(W) + "x" + std::to_string(H) + " and " +
                                std::to_string(c.width) + "x" + std::to_string(c.height));
        core::validateConeView(c, m_geometry);
    }
    checkOutputFits(W, H, cameras.size());
    const std::size_t bytes = std::size_t(W) * std::size_t(H) * cameras.size() * sizeof(float);
    if (!m_output) glGenBuffers(1, &m_output);
    if (bytes > m_outputBytes) {
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_output);
        glBufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(bytes), nullptr, GL_DYNAMIC_COPY);
        m_outputBytes = bytes;
    }
    m_width = W;
    m_height = H;
    m_viewCount = int(cameras.size());
    uploadViews(cameras);
    glUseProgram(m_program);
    setUniforms(m_viewCount);
    glActiveTexture(GL_TEXTURE0 + point(TextureUnit::Volume));
    glBindTexture(GL_TEXTURE_3D, m_texture);
    if (m_occupancy) {
        glActiveTexture(GL_TEXTURE0 + point(TextureUnit::Occupancy));
        glBindTexture(GL_TEXTURE_3D, m_occupancy);
    }
    glActiveTexture(GL_TEXTURE0);
    bindStorage(Binding::PassInput, m_views);
    bindStorage(Binding::PassOutput, m_output);
    glDispatchCompute(GLuint((W + 15) / 16), GLuint((H + 15) / 16), GLuint(m_viewCount));
    if (const GLenum err = glGetError(); err != GL_NO_ERROR) {
        if (err == GL_OUT_OF_MEMORY)
            throw GpuMemoryError("GPU cone-beam views: out of GPU memory for " +
                                 std::to_string(m_viewCount) + " views of " + std::to_string(W) +
                                 "x" + std::to_string(H));
        throw GlError("GPU cone-beam view failed: GL error " + std::to_string(err));
    }
}

std::vector<float> ConeRayCaster::readBack() const {
    std::vector<float> out(std::size_t(m_width) * std::size_t(m_height) * std::size_t(m_viewCount));
    if (out.empty()) return out;
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_output);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(out.size() * sizeof(float)),
                       out.data());
    if (const GLenum err = glGetError(); err != GL_NO_ERROR)
        throw GlError("GPU cone-beam read-back failed: GL error " + std::to_string(err));
    return out;
}

std::vector<core::DetectorImage> ConeRayCaster::projectMany(
    const std::vector<core::ConeCamera>& cameras) {
    projectToGpu(cameras);
    const std::vector<float> all = readBack();
    const std::size_t pixels = std::size_t(m_width) * std::size_t(m_height);
    std::vector<core::DetectorImage> out(cameras.size());
    for (std::size_t i = 0; i < cameras.size(); ++i) {
        out[i].width = m_width;
        out[i].height = m_height;
        out[i].camera = cameras[i];
        out[i].mapping = m_options.mapping;
        out[i].pixels.assign(all.begin() + std::ptrdiff_t(i * pixels),
                             all.begin() + std::ptrdiff_t((i + 1) * pixels));
    }
    return out;
}

core::DetectorImage ConeRayCaster::project(const core::ConeCamera& camera) {
    return std::move(projectMany({camera}).front());
}

std::string describeConeRayCaster(const core::ConeProjectorOptions& options, TrilinearFetch fetch) {
    std::string s = "GPU ";
    if (options.model == RayModel::Box) {
        s += "box ray casting, exact path lengths";
    } else {
        s += "trilinear ray casting, ";
        s += options.stepFraction > 0
                 ? "step " + core::formatNumber(options.stepFraction) + " of the smallest spacing"
                 : std::string("exact per cell");
        s += std::string(", ") + trilinearFetchName(fetch) + " fetch";
    }
    if (options.pixelSubsamples > 1)
        s += ", " + std::to_string(options.pixelSubsamples) + "x" +
             std::to_string(options.pixelSubsamples) + " rays per pixel";
    if (!options.skipEmpty) s += ", no empty-space skipping";
    return s;
}

} // namespace fvr::gpu
