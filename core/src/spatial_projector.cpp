#include <fvr/core/spatial_projector.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <fvr/core/xray.h>

namespace fvr::core {

SpatialProjector::SpatialProjector(const Volume& volume, SpatialProjectorOptions options)
    : m_volume(volume), m_options(options), m_pool(options.threads) {
    if (options.mapping != ValueMapping::Raw) {
        m_mapped.resize(volume.voxels.size());
        for (std::size_t i = 0; i < m_mapped.size(); ++i) m_mapped[i] = mapValue(options.mapping, volume.voxels[i]);
    }
}

ProjectionImage SpatialProjector::project(const ViewFrame& view, const ImageGeometry& image) {
    validateImageGeometry(image);
    const Volume& v = m_volume;
    const float* vox = m_mapped.empty() ? v.voxels.data() : m_mapped.data();
    const int M = image.size;
    const double d = image.pixelSize;
    const auto& N = v.dims;
    const auto& s = v.spacing;
    const double h = m_options.stepFraction * std::min({s[0], s[1], s[2]});
    const DepthCueWeights w = depthCueWeights(m_options.depthCue, N, s);

    ProjectionImage img;
    img.size = M;
    img.pixelSize = d;
    img.view = view;
    img.mapping = m_options.mapping;
    img.pixels.assign(std::size_t(M) * M, 0.0f);

    // Work in index coordinates: x_idx = p / s + (N-1)/2 for p relative to the centre.
    double dir[3], rgt[3], dwn[3], c[3];
    for (int a = 0; a < 3; ++a) {
        dir[a] = view.d[a] / s[a];
        rgt[a] = view.r[a] * d / s[a];
        dwn[a] = -view.u[a] * d / s[a];
        c[a] = (N[a] - 1) / 2.0;
    }
    const std::int64_t sx = 1, sy = N[0], sz = N[0] * N[1];
    auto sample = [&](double x, double y, double z) -> double {
        // Trilinear, zero outside the voxel grid (support [-1, N]).
        const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
        const std::int64_t ix = std::int64_t(fx), iy = std::int64_t(fy), iz = std::int64_t(fz);
        const double tx = x - fx, ty = y - fy, tz = z - fz;
        double acc = 0.0;
        for (int cz = 0; cz < 2; ++cz) {
            const std::int64_t zz = iz + cz;
            if (zz < 0 || zz >= N[2]) continue;
            const double wz = cz ? tz : 1 - tz;
            for (int cy = 0; cy < 2; ++cy) {
                const std::int64_t yy = iy + cy;
                if (yy < 0 || yy >= N[1]) continue;
                const double wy = (cy ? ty : 1 - ty) * wz;
                const std::int64_t base = yy * sy + zz * sz;
                if (ix >= 0 && ix < N[0]) acc += (1 - tx) * wy * vox[base + ix * sx];
                if (ix + 1 >= 0 && ix + 1 < N[0]) acc += tx * wy * vox[base + (ix + 1) * sx];
            }
        }
        return acc;
    };

    m_pool.parallelFor(M, 2, [&](std::int64_t r0, std::int64_t r1) {
        for (std::int64_t row = r0; row < r1; ++row)
            for (int col = 0; col < M; ++col) {
                double o[3];
                for (int a = 0; a < 3; ++a)
                    o[a] = c[a] + (col - M / 2) * rgt[a] + (row - M / 2) * dwn[a];
                // Clip the ray (in mm along D) to the support box [-1, N] per axis.
                double t0 = -std::numeric_limits<double>::infinity();
                double t1 = std::numeric_limits<double>::infinity();
                bool miss = false;
                for (int a = 0; a < 3; ++a) {
                    if (std::abs(dir[a]) < 1e-15) {
                        if (o[a] <= -1.0 || o[a] >= double(N[a])) miss = true;
                        continue;
                    }
                    double ta = (-1.0 - o[a]) / dir[a], tb = (double(N[a]) - o[a]) / dir[a];
                    if (ta > tb) std::swap(ta, tb);
                    t0 = std::max(t0, ta);
                    t1 = std::min(t1, tb);
                }
                if (miss || !(t1 > t0)) continue;
                // Midpoint rule with steps of at most h.
                const std::int64_t n = std::max<std::int64_t>(1, std::int64_t(std::ceil((t1 - t0) / h)));
                const double step = (t1 - t0) / double(n);
                double sum = 0.0;
                for (std::int64_t i = 0; i < n; ++i) {
                    const double t = t0 + (i + 0.5) * step;
                    sum += (w.a + w.b * t) * sample(o[0] + t * dir[0], o[1] + t * dir[1], o[2] + t * dir[2]);
                }
                img.pixels[std::size_t(row) * M + col] = float(sum * step);
            }
    });
    return img;
}

} // namespace fvr::core
