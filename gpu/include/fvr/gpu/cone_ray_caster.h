#pragma once
/** Cone-beam DRRs on the GPU: core::ConeProjector's line integrals (core/render/cone_projector.h)
 *  by an OpenGL 4.3 compute shader, one invocation per detector pixel
 *  and view (resources/shaders/cone/cone_ray.comp). The (mapped) volume is uploaded once as a 3D
 * float texture (R32F, zero border); each view passes 4 vectors: the ray vectors in voxel indices
 *  relative to the grid's centre, computed in double from the camera and
 *  core::indexToPatient's inverse. Models: box (exact path lengths, a cell walk), trilinear
 *  exact per cell (the walk and Simpson's rule, as the CPU's default) or sampled at a step. The
 *  trilinear values come from 8 texelFetches with float weights (TrilinearFetch::Manual, the
 *  default) or from the texture unit's GL_LINEAR filter (TrilinearFetch::Hardware: faster, its
 *  weights fixed point). No B-spline (CPU only). Needs a current OpenGL 4.3 context for every
 *  call, the one it was made in. */
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <fvr/core/geometry/camera.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/volume.h>

namespace fvr::gpu {

/** Which 8^3 blocks of the ray walk's cells hold a cell touching a non-zero voxel (the CPU's
 *  empty-space map): a box cell c is voxel c; a trilinear cell c (between voxel centres c - 1
 *  and c, support [-1, N]) has the corners c - 1 and c. */
struct BlockMap {
    BlockMap(const core::Dims3& dims, bool trilinear);
    /** Marks the blocks of the non-zero values among `slices` slices from z0 (x fastest). */
    void mark(const float* values, std::int64_t z0, std::int64_t slices);

    core::Dims3 dims;
    bool trilinear;
    std::int64_t blocks[3] = {0, 0, 0};
    std::vector<std::uint8_t> occupied; ///< per block, x fastest
};

/** Where trilinear values come from. */
enum class TrilinearFetch {
    Manual, ///< 8 texelFetches, float weights: the CPU's interpolant to float rounding
    Hardware ///< the texture unit's GL_LINEAR filter (fixed-point weights; 8 bits on NVIDIA)
};

const char* trilinearFetchName(TrilinearFetch f); ///< "manual", "hardware"

class ConeRayCaster {
public:
    /** Maps the values (options.mapping) and uploads them as a 3D R32F texture. options.model:
     *  Box or Trilinear (stepFraction 0: exact per cell; > 0: midpoint samples), BSpline is
     *  refused (SettingsError); pixelSubsamples 1..16; skipEmpty leaves out 8^3 blocks of
     *  zeros (BlockMap, as the CPU); threads does not apply.
     *  Throws SettingsError for bad options or a volume whose voxels do not match its dims,
     *  GlError without an OpenGL 4.3 context, GpuMemoryError naming the sizes when the volume
     *  exceeds GL_MAX_3D_TEXTURE_SIZE or (where the driver tells) the free GPU memory. The
     *  volume is not needed afterwards. */
    explicit ConeRayCaster(const core::Volume& volume, core::ConeProjectorOptions options = {},
                           TrilinearFetch fetch = TrilinearFetch::Manual);
    ~ConeRayCaster();
    ConeRayCaster(const ConeRayCaster&) = delete;
    ConeRayCaster& operator=(const ConeRayCaster&) = delete;

    const core::ConeProjectorOptions& options() const { return m_options; }
    TrilinearFetch fetch() const { return m_fetch; }
    /** The texture's size in bytes (4 per voxel). */
    std::size_t textureBytes() const { return m_textureBytes; }

    /** One view's line integrals, read back (core::validateConeView first: SettingsError). */
    core::DetectorImage project(const core::ConeCamera& camera);
    /** Several views of one detector size in one dispatch (small views alone leave a large GPU
     *  mostly idle), read back. SettingsError for cameras of different sizes; GpuMemoryError
     *  when the images exceed the largest storage buffer the driver allows. */
    std::vector<core::DetectorImage> projectMany(const std::vector<core::ConeCamera>& cameras);
    /** Renders the views into outputBuffer() without waiting or reading back (benches, and
     *  callers that keep the images on the GPU). Validates like projectMany(). */
    void projectToGpu(const std::vector<core::ConeCamera>& cameras);
    void projectToGpu(const core::ConeCamera& camera) {
        projectToGpu(std::vector<core::ConeCamera>{camera});
    }
    /** The shader storage buffer holding the last dispatch's images: W x H floats per view
     *  (row-major, row 0 the top), view after view; 0 before the first view. */
    unsigned outputBuffer() const { return m_output; }
    /** Reads back the last dispatch's images (waits for them), view after view. */
    std::vector<float> readBack() const;

    /** The shader variant's defines for these options (tests and logs). */
    std::vector<std::pair<std::string, std::string>> shaderDefines() const;

private:
    void upload(const core::Volume& volume);
    void uploadBlocks(const BlockMap& blocks);
    void setUniforms(int views) const;
    void uploadViews(const std::vector<core::ConeCamera>& cameras);

    core::Volume m_geometry; ///< the volume's dims, spacing, origin, directions: no voxels
    core::ConeProjectorOptions m_options;
    TrilinearFetch m_fetch;
    glm::dmat4 m_patientToIndex{1.0};
    glm::dmat3 m_indexToMm{1.0};
    unsigned m_texture = 0;
    unsigned m_occupancy = 0; ///< the BlockMap as an R8UI texture (skipEmpty)
    unsigned m_output = 0;
    unsigned m_views = 0; ///< the views' rays (ConeViews in the shader)
    unsigned m_program = 0;
    std::size_t m_textureBytes = 0;
    std::size_t m_outputBytes = 0;
    int m_width = 0, m_height = 0, m_viewCount = 0;
};

/** Words for logs and the bench: "GPU trilinear ray casting, exact per cell, manual fetch". */
std::string describeConeRayCaster(const core::ConeProjectorOptions& options, TrilinearFetch fetch);

} // namespace fvr::gpu
