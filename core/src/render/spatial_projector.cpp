#include <fvr/core/render/spatial_projector.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <fvr/core/errors.h>
#include <fvr/core/xray/xray.h>

namespace fvr::core {

namespace {

/** Margin of the B-spline coefficient volume: the coefficients outside the voxels decay by
 *  |sqrt(3) - 2| = 0.268 per voxel, so 10 voxels leave 2e-6 of the boundary coefficient. */
constexpr int kSplineMargin = 10;

/** In-place recursive cubic B-spline prefilter of n values at stride `stride` that are zero
 *  before the first and after the last (Unser 1999, with the infinite-domain initial values). */
void prefilterLine(float* v, std::int64_t n, std::int64_t stride, std::vector<double>& cp) {
    const double z = std::sqrt(3.0) - 2.0;
    cp.resize(std::size_t(n));
    double prev = 0.0;
    for (std::int64_t i = 0; i < n; ++i) prev = cp[std::size_t(i)] = v[i * stride] + z * prev;
    double cm = z / (z * z - 1.0) * cp[std::size_t(n - 1)];
    v[(n - 1) * stride] = float(6.0 * cm);
    for (std::int64_t i = n - 2; i >= 0; --i) {
        cm = z * (cm - cp[std::size_t(i)]);
        v[i * stride] = float(6.0 * cm);
    }
}

} // namespace

std::vector<float> bsplineCoefficients(const std::vector<float>& voxels, const Dims3& dims,
                                       int margin) {
    const std::int64_t L[3] = {dims[0] + 2 * margin, dims[1] + 2 * margin, dims[2] + 2 * margin};
    std::vector<float> c(std::size_t(L[0] * L[1] * L[2]), 0.0f);
    for (std::int64_t z = 0; z < dims[2]; ++z)
        for (std::int64_t y = 0; y < dims[1]; ++y)
            std::copy_n(voxels.data() + (z * dims[1] + y) * dims[0], dims[0],
                        c.data() + ((z + margin) * L[1] + (y + margin)) * L[0] + margin);
    std::vector<double> cp;
    for (std::int64_t z = 0; z < L[2]; ++z)
        for (std::int64_t y = 0; y < L[1]; ++y)
            prefilterLine(c.data() + (z * L[1] + y) * L[0], L[0], 1, cp);
    for (std::int64_t z = 0; z < L[2]; ++z)
        for (std::int64_t x = 0; x < L[0]; ++x)
            prefilterLine(c.data() + z * L[1] * L[0] + x, L[1], L[0], cp);
    for (std::int64_t y = 0; y < L[1]; ++y)
        for (std::int64_t x = 0; x < L[0]; ++x)
            prefilterLine(c.data() + y * L[0] + x, L[2], L[0] * L[1], cp);
    return c;
}

SpatialProjectorOptions matchingProjectorOptions(const RenderParams& params, ValueMapping mapping,
                                                 int threads) {
    SpatialProjectorOptions o;
    o.stepFraction = 0.25;
    o.mapping = mapping;
    o.threads = threads;
    o.depthCue = params.depthCue;
    o.voxelModel =
        params.voxelModel == VoxelModel::BandLimited ? VoxelModel::Trilinear : params.voxelModel;
    o.pixelSubsamples = params.pixelAperture ? 3 : 1;
    return o;
}

std::string describeProjector(const SpatialProjectorOptions& o, VoxelModel rendered) {
    std::string s =
        std::string(voxelModelLabel(o.voxelModel)) + " ray casting (step s/" +
        std::to_string(int(std::lround(1.0 / o.stepFraction))) + ", " +
        (o.pixelSubsamples > 1 ? std::to_string(o.pixelSubsamples) + " x " +
                                     std::to_string(o.pixelSubsamples) + " rays per pixel"
                               : std::string("one ray per pixel")) +
        (o.depthCue > 0 ? ", depth-weighted" : "") + ")";
    if (rendered != o.voxelModel)
        s += "; the frame uses the " + std::string(voxelModelLabel(rendered)) +
             " voxel model, which has no ray caster: the difference includes that between the two "
             "models";
    return s;
}

SpatialProjector::SpatialProjector(const Volume& volume, SpatialProjectorOptions options)
    : m_volume(volume), m_options(options), m_pool(options.threads) {
    if (options.voxelModel == VoxelModel::BandLimited)
        throw SettingsError(
            "spatial projector: no ray caster for the band-limited voxel model (its sinc "
            "interpolant has infinite support); use trilinear or bspline");
    if (options.pixelSubsamples < 1 || options.pixelSubsamples > 16)
        throw SettingsError("spatial projector: pixel subsamples must be 1..16, found " +
                            std::to_string(options.pixelSubsamples));
    if (options.mapping != ValueMapping::Raw) {
        m_mapped.resize(volume.voxels.size());
        for (std::size_t i = 0; i < m_mapped.size(); ++i)
            m_mapped[i] = mapValue(options.mapping, volume.voxels[i]);
    }
    if (options.voxelModel == VoxelModel::BSpline)
        m_coefficients = bsplineCoefficients(m_mapped.empty() ? volume.voxels : m_mapped,
                                             volume.dims, kSplineMargin);
}

namespace {

/** Trilinear interpolation of the voxels, zero outside the voxel grid (support [-1, N]). */
struct TrilinearSampler {
    const float* vox;
    Dims3 N;

    double operator()(double x, double y, double z) const {
        const std::int64_t sx = 1, sy = N[0], sz = N[0] * N[1];
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
    }
};

/** The cubic B-spline through the voxels from its prefiltered coefficients (kSplineMargin
 *  voxels of margin per side, rows of L0, planes of L0 x L1). */
struct BSplineSampler {
    const float* coef;
    std::int64_t L0, L1;

    static void weights(double t, double* wt) {
        const double t2 = t * t, t3 = t2 * t, u = 1.0 - t;
        wt[0] = u * u * u / 6.0;
        wt[1] = (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0;
        wt[2] = (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0;
        wt[3] = t3 / 6.0;
    }
    double operator()(double x, double y, double z) const {
        const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
        double wx[4], wy[4], wz[4];
        weights(x - fx, wx);
        weights(y - fy, wy);
        weights(z - fz, wz);
        const std::int64_t ix = std::int64_t(fx) - 1 + kSplineMargin,
                           iy = std::int64_t(fy) - 1 + kSplineMargin,
                           iz = std::int64_t(fz) - 1 + kSplineMargin;
        double acc = 0.0;
        for (int cz = 0; cz < 4; ++cz)
            for (int cy = 0; cy < 4; ++cy) {
                const float* row = coef + ((iz + cz) * L1 + (iy + cy)) * L0 + ix;
                acc += wz[cz] * wy[cy] *
                       (wx[0] * row[0] + wx[1] * row[1] + wx[2] * row[2] + wx[3] * row[3]);
            }
        return acc;
    }
};

/** The rays of one view in index coordinates (x_idx = p / s + (N-1)/2 for p relative to the
 *  centre): direction, the image's right and down steps per pixel, the centre, and the model's
 *  support [lo, hi] per axis. */
struct RayGeometry {
    double dir[3], rgt[3], dwn[3], c[3];
    double lo[3], hi[3];

    RayGeometry(const ViewFrame& view, double d, const Dims3& N, const Vec3& s, bool spline) {
        for (int a = 0; a < 3; ++a) {
            dir[a] = view.d[a] / s[a];
            rgt[a] = view.r[a] * d / s[a];
            dwn[a] = -view.u[a] * d / s[a];
            c[a] = (N[a] - 1) / 2.0;
        }
        // The model's support in index coordinates: [-1, N] for trilinear; for the spline the
        // coefficient volume less one voxel below and two above, so that all 4 taps of every
        // sample, floor(x) - 1 .. floor(x) + 2, lie inside it even for a sample on the upper bound.
        for (int a = 0; a < 3; ++a) {
            lo[a] = spline ? -kSplineMargin + 1.0 : -1.0;
            hi[a] = spline ? double(N[a] + kSplineMargin - 3) : double(N[a]);
        }
    }
};

/** The depth-weighted line integral along D through o (index coordinates), midpoint rule with
 *  steps <= h, inside the model's support. */
template <class Sampler>
double integrateRay(const RayGeometry& g, const double* o, double h, const DepthCueWeights& w,
                    const Sampler& sample) {
    double t0 = -std::numeric_limits<double>::infinity();
    double t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (std::abs(g.dir[a]) < 1e-15) {
            if (o[a] <= g.lo[a] || o[a] >= g.hi[a]) return 0.0;
            continue;
        }
        double ta = (g.lo[a] - o[a]) / g.dir[a], tb = (g.hi[a] - o[a]) / g.dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    if (!(t1 > t0)) return 0.0;
    const std::int64_t n = std::max<std::int64_t>(1, std::int64_t(std::ceil((t1 - t0) / h)));
    const double step = (t1 - t0) / double(n);
    double sum = 0.0;
    for (std::int64_t i = 0; i < n; ++i) {
        const double t = t0 + (i + 0.5) * step;
        const double x = o[0] + t * g.dir[0], y = o[1] + t * g.dir[1], z = o[2] + t * g.dir[2];
        sum += (w.a + w.b * t) * sample(x, y, z);
    }
    return sum * step;
}

/** Every pixel's mean over sub x sub sub-rays spread evenly over it, (i + 1/2) / sub - 1/2. */
template <class Sampler>
void castRays(const RayGeometry& g, double h, const DepthCueWeights& w, const Sampler& sample,
              int sub, ProjectionImage& img, ThreadPool& pool) {
    const int W = img.width, H = img.height;
    pool.parallelFor(H, 2, [&](std::int64_t r0, std::int64_t r1) {
        for (std::int64_t row = r0; row < r1; ++row)
            for (int col = 0; col < W; ++col) {
                double sum = 0.0;
                for (int j = 0; j < sub; ++j)
                    for (int i = 0; i < sub; ++i) {
                        const double du = (i + 0.5) / sub - 0.5, dv = (j + 0.5) / sub - 0.5;
                        double o[3];
                        for (int a = 0; a < 3; ++a)
                            o[a] = g.c[a] + (col - W / 2 + du) * g.rgt[a] +
                                   (row - H / 2 + dv) * g.dwn[a];
                        sum += integrateRay(g, o, h, w, sample);
                    }
                img.pixels[std::size_t(row) * W + col] = float(sum / double(sub * sub));
            }
    });
}

} // namespace

ProjectionImage SpatialProjector::project(const ViewFrame& view, const ImageGeometry& image) {
    validateImageGeometry(image);
    const Volume& v = m_volume;
    const auto& N = v.dims;
    const auto& s = v.spacing;
    const double h = m_options.stepFraction * std::min({s[0], s[1], s[2]});
    const DepthCueWeights w = depthCueWeights(m_options.depthCue, N, s);
    const bool spline = m_options.voxelModel == VoxelModel::BSpline;

    ProjectionImage img;
    img.width = image.cols();
    img.height = image.rows();
    img.pixelSize = image.pixelSize;
    img.view = view;
    img.mapping = m_options.mapping;
    img.pixels.assign(std::size_t(img.width) * img.height, 0.0f);

    const RayGeometry g(view, image.pixelSize, N, s, spline);
    const int sub = m_options.pixelSubsamples;
    if (spline) {
        const BSplineSampler b{m_coefficients.data(), N[0] + 2 * kSplineMargin,
                               N[1] + 2 * kSplineMargin};
        castRays(g, h, w, b, sub, img, m_pool);
    } else {
        const TrilinearSampler t{m_mapped.empty() ? v.voxels.data() : m_mapped.data(), N};
        castRays(g, h, w, t, sub, img, m_pool);
    }
    return img;
}

} // namespace fvr::core
