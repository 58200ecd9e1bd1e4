// The registration's levels: the CT's and the X-rays' block means, the coverage mask, and the
// CPU DRR renderer (registration/registration.h).
#include <algorithm>
#include <cmath>
#include <limits>

#include <fvr/core/errors.h>
#include <fvr/core/registration/registration.h>

namespace fvr::core {

namespace {

class CpuDrrRenderer final : public DrrRenderer {
public:
    CpuDrrRenderer(const Volume& volume, const ConeProjectorOptions& options)
        : m_projector(volume, options) {}
    std::vector<DetectorImage> render(const std::vector<ConeCamera>& cameras) override {
        std::vector<DetectorImage> out;
        out.reserve(cameras.size());
        for (const ConeCamera& c : cameras) out.push_back(m_projector.project(c));
        return out;
    }
    std::string describe() const override {
        return "CPU " + describeConeProjector(m_projector.options());
    }

private:
    ConeProjector m_projector;
};

/** Block means of one z range of the output (x fastest), factors f per axis, the blocks
 *  starting at voxel `first`. */
void blockMeans(const Volume& in, Volume& out, const Dims3& f, const Dims3& first) {
    const double norm = 1.0 / double(f[0] * f[1] * f[2]);
    for (std::int64_t z = 0; z < out.dims[2]; ++z)
        for (std::int64_t y = 0; y < out.dims[1]; ++y)
            for (std::int64_t x = 0; x < out.dims[0]; ++x) {
                double sum = 0.0;
                for (std::int64_t c = 0; c < f[2]; ++c)
                    for (std::int64_t b = 0; b < f[1]; ++b) {
                        const float* row = &in.voxels[in.index(
                            first[0] + x * f[0], first[1] + y * f[1] + b, first[2] + z * f[2] + c)];
                        for (std::int64_t a = 0; a < f[0]; ++a) sum += row[a];
                    }
                out.voxels[out.index(x, y, z)] = float(sum * norm);
            }
}

} // namespace

std::unique_ptr<DrrRenderer> cpuDrrRenderer(const Volume& volume,
                                            const ConeProjectorOptions& options) {
    return std::make_unique<CpuDrrRenderer>(volume, options);
}

int levelImageFactor(int width, int height, int imagePixels) {
    if (imagePixels <= 0) return 1;
    return std::max(1, int(std::lround(double(std::max(width, height)) / imagePixels)));
}

Dims3 volumeBlockFactors(const Volume& volume, double voxelMm) {
    Dims3 f{1, 1, 1};
    if (voxelMm > 0.0)
        for (int a = 0; a < 3; ++a)
            f[a] = std::clamp<std::int64_t>(std::llround(voxelMm / volume.spacing[a]), 1,
                                            std::max<std::int64_t>(1, volume.dims[a]));
    return f;
}

Volume downsampleVolume(const Volume& volume, double voxelMm) {
    const Dims3 f = volumeBlockFactors(volume, voxelMm);
    Dims3 first{0, 0, 0};
    Volume out;
    for (int a = 0; a < 3; ++a) {
        out.dims[a] = volume.dims[a] / f[a];
        // The voxels left over split between the two ends: the grid's centre moves by at most
        // half an input voxel.
        first[a] = (volume.dims[a] - out.dims[a] * f[a]) / 2;
        out.spacing[a] = volume.spacing[a] * double(f[a]);
    }
    if (f[0] == 1 && f[1] == 1 && f[2] == 1) return volume;
    out.direction = volume.direction;
    out.units = volume.units;
    out.orientationStated = volume.orientationStated;
    out.name = volume.name;
    // The first block's centre: input index first + (f - 1) / 2.
    glm::dvec3 o = volume.origin;
    for (int a = 0; a < 3; ++a)
        o += volume.direction[a] * (volume.spacing[a] * (double(first[a]) + (f[a] - 1) / 2.0));
    out.origin = o;
    out.voxels.assign(std::size_t(out.voxelCount()), 0.0f);
    blockMeans(volume, out, f, first);
    return out;
}

namespace {

/** Where a ray s + t d meets the box [lo, hi] per axis: the entry and exit parameters and the
 *  axes whose planes it crosses there; false when it misses. */
bool clipToBox(const glm::dvec3& s, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi,
               int& entryAxis, int& exitAxis) {
    double tIn = -std::numeric_limits<double>::infinity();
    double tOut = std::numeric_limits<double>::infinity();
    entryAxis = exitAxis = -1;
    for (int a = 0; a < 3; ++a) {
        if (std::abs(d[a]) < 1e-15) {
            if (s[a] < lo[a] || s[a] > hi[a]) return false;
            continue;
        }
        double t0 = (lo[a] - s[a]) / d[a], t1 = (hi[a] - s[a]) / d[a];
        if (t0 > t1) std::swap(t0, t1);
        if (t0 > tIn) tIn = t0, entryAxis = a;
        if (t1 < tOut) tOut = t1, exitAxis = a;
    }
    return tOut > std::max(tIn, 0.0);
}

} // namespace

std::vector<std::uint8_t> coverageMask(const Volume& ct, const ConeCamera& camera,
                                       const glm::dmat4& T) {
    // In the CT's voxel index frame: the box [-1/2, N - 1/2] per axis, axis 2 the slice axis.
    const ConeCamera c = posedCamera(camera, T);
    const glm::dmat4 toIndex = glm::inverse(indexToPatient(ct));
    const glm::dvec3 s = glm::dvec3(toIndex * glm::dvec4(c.source, 1.0));
    const glm::dvec3 lo(-0.5), hi(ct.dims[0] - 0.5, ct.dims[1] - 0.5, ct.dims[2] - 0.5);
    const glm::dvec3 principal =
        glm::normalize(glm::dvec3(toIndex * glm::dvec4(c.detectorCentre - c.source, 0.0)) *
                       glm::dvec3(ct.spacing[0], ct.spacing[1], ct.spacing[2]));
    const bool alongSlices = std::abs(principal.z) > std::sqrt(0.5);
    std::vector<std::uint8_t> mask(std::size_t(c.width) * c.height, 0);
    for (int row = 0; row < c.height; ++row)
        for (int col = 0; col < c.width; ++col) {
            const glm::dvec3 p = glm::dvec3(toIndex * glm::dvec4(c.pixelCentre(col, row), 1.0));
            int in = -1, out = -1;
            if (!clipToBox(s, p - s, lo, hi, in, out)) continue;
            if (!alongSlices && (in == 2 || out == 2)) continue;
            mask[std::size_t(row) * c.width + col] = 1;
        }
    return mask;
}

} // namespace fvr::core
