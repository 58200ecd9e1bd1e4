#include <fvr/core/xray/phantom.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fvr/core/errors.h>
#include <fvr/core/memory_budget.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/xray/xray.h>

namespace fvr::core {

namespace {
Vec3 toLocal(const Ellipsoid& e, const Vec3& v) {
    // Coordinates along the ellipsoid's axes, scaled by the semi-axes (unit sphere frame).
    return (v * e.axes) / e.semiAxes; // v * axes: transpose(axes) v
}

/** Where the line o + t dir crosses the axis-aligned box [-h, h]; false if it misses. */
bool boxInterval(const Vec3& o, const Vec3& dir, const Vec3& h, double& t0, double& t1) {
    t0 = -1e300;
    t1 = 1e300;
    for (int a = 0; a < 3; ++a) {
        if (std::abs(dir[a]) < 1e-15) {
            if (std::abs(o[a]) >= h[a]) return false;
            continue;
        }
        double ta = (-h[a] - o[a]) / dir[a], tb = (h[a] - o[a]) / dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t1 > t0;
}

/** Integral of a + b t over [t0, t1]. */
double weightedLength(double t0, double t1, double a, double b) {
    return a * (t1 - t0) + b * 0.5 * (t1 * t1 - t0 * t0);
}

/** A piece of a line with one density: t in [t0, t1]. */
struct Segment {
    double t0, t1, density;
};

/**
 * The painted density along o + t dir for t in [tMin, tMax]: the line's pieces between the
 * points where it crosses ellipsoid surfaces, each with the density of the last of `candidates`
 * (indices into `all`, in painting order) that holds it; pieces in no ellipsoid are left out.
 */
void paintedSegments(const std::vector<Ellipsoid>& all, const std::vector<int>& candidates,
                     const Vec3& o, const Vec3& dir, double tMin, double tMax,
                     std::vector<Segment>& hits, std::vector<double>& cuts,
                     std::vector<Segment>& out) {
    hits.clear();
    cuts.clear();
    out.clear();
    for (int i : candidates) {
        double t0, t1;
        if (!all[std::size_t(i)].interval(o, dir, t0, t1)) continue;
        t0 = std::max(t0, tMin);
        t1 = std::min(t1, tMax);
        if (t1 <= t0) continue;
        hits.push_back({t0, t1, all[std::size_t(i)].density});
        cuts.push_back(t0);
        cuts.push_back(t1);
    }
    std::sort(cuts.begin(), cuts.end());
    for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
        const double a = cuts[k], b = cuts[k + 1];
        if (b <= a) continue;
        const double mid = 0.5 * (a + b);
        for (auto h = hits.rbegin(); h != hits.rend(); ++h)
            if (h->t0 <= mid && mid <= h->t1) {
                out.push_back({a, b, h->density});
                break;
            }
    }
}

/** Axis-aligned half-extents of an ellipsoid (exact bounding box). */
Vec3 boundingHalfExtent(const Ellipsoid& e) {
    Vec3 h;
    for (int k = 0; k < 3; ++k) {
        double s = 0;
        for (int i = 0; i < 3; ++i) s += std::pow(e.semiAxes[i] * e.axes[i][k], 2);
        h[k] = std::sqrt(s);
    }
    return h;
}

/** Voxel-centre coordinate (mm from the centre) of index i on an axis of n voxels. */
double voxelCentre(std::int64_t i, std::int64_t n, double s) {
    return (double(i) - double(n - 1) / 2.0) * s;
}

/** Paint-composition voxel values (mu) of one row (y, z) of voxels: the mean over S x S lines
 *  along x through the row, each integrated exactly over every voxel's length. */
void paintRow(const std::vector<Ellipsoid>& all, const std::vector<int>& candidates,
              const Dims3& dims, const Vec3& spacing, std::int64_t y, std::int64_t z, int S,
              std::vector<double>& row) {
    std::vector<Segment> hits, segs;
    std::vector<double> cuts;
    const double x0 = -dims[0] * spacing[0] / 2.0, sx = spacing[0];
    std::fill(row.begin(), row.end(), 0.0);
    const double weight = 1.0 / (double(S) * S * sx);
    for (int j = 0; j < S; ++j)
        for (int k = 0; k < S; ++k) {
            const Vec3 o{0.0,
                         voxelCentre(y, dims[1], spacing[1]) + ((j + 0.5) / S - 0.5) * spacing[1],
                         voxelCentre(z, dims[2], spacing[2]) + ((k + 0.5) / S - 0.5) * spacing[2]};
            paintedSegments(all, candidates, o, {1, 0, 0}, x0, -x0, hits, cuts, segs);
            for (const Segment& sg : segs) {
                const auto first = std::int64_t(std::floor((sg.t0 - x0) / sx));
                const auto last = std::min<std::int64_t>(
                    std::int64_t(std::floor((sg.t1 - x0) / sx)), dims[0] - 1);
                for (std::int64_t x = std::max<std::int64_t>(first, 0); x <= last; ++x) {
                    const double a = std::max(sg.t0, x0 + double(x) * sx);
                    const double b = std::min(sg.t1, x0 + double(x + 1) * sx);
                    if (b > a) row[std::size_t(x)] += sg.density * (b - a) * weight;
                }
            }
        }
}

/** Paint composition: see EllipsoidPhantom::voxelize. Returns mu per voxel. */
std::vector<float> voxelizePainted(const std::vector<Ellipsoid>& all, const Dims3& dims,
                                   const Vec3& spacing, int S) {
    std::vector<float> mu(std::size_t(dims[0] * dims[1] * dims[2]), 0.0f);
    std::vector<Vec3> lo(all.size()), hi(all.size());
    for (std::size_t i = 0; i < all.size(); ++i) {
        const Vec3 h = boundingHalfExtent(all[i]);
        lo[i] = all[i].centre - h;
        hi[i] = all[i].centre + h;
    }
    ThreadPool pool;
    pool.parallelFor(dims[2], 1, [&](std::int64_t z0, std::int64_t z1) {
        std::vector<double> row(static_cast<std::size_t>(dims[0]));
        std::vector<int> inSlice, inRow;
        for (std::int64_t z = z0; z < z1; ++z) {
            const double zc = voxelCentre(z, dims[2], spacing[2]), hz = spacing[2] / 2;
            inSlice.clear();
            for (std::size_t i = 0; i < all.size(); ++i)
                if (lo[i][2] < zc + hz && hi[i][2] > zc - hz) inSlice.push_back(int(i));
            for (std::int64_t y = 0; y < dims[1]; ++y) {
                const double yc = voxelCentre(y, dims[1], spacing[1]), hy = spacing[1] / 2;
                inRow.clear();
                for (int i : inSlice)
                    if (lo[std::size_t(i)][1] < yc + hy && hi[std::size_t(i)][1] > yc - hy)
                        inRow.push_back(i);
                paintRow(all, inRow, dims, spacing, y, z, S, row);
                float* out = mu.data() + std::size_t(dims[0] * (y + dims[1] * z));
                for (std::int64_t x = 0; x < dims[0]; ++x) out[x] = float(row[std::size_t(x)]);
            }
        }
    });
    return mu;
}

std::vector<float> voxelizeSum(const std::vector<Ellipsoid>& ellipsoids, const Dims3& dims,
                               const Vec3& spacing, int S);
} // namespace

bool Ellipsoid::interval(const Vec3& o, const Vec3& dir, double& t0, double& t1) const {
    const Vec3 a = toLocal(*this, dir);
    const Vec3 b = toLocal(*this, o - centre);
    const double aa = glm::dot(a, a), ab = glm::dot(a, b), bb = glm::dot(b, b);
    const double disc = ab * ab - aa * (bb - 1.0);
    if (disc <= 0.0) return false;
    const double r = std::sqrt(disc);
    t0 = (-ab - r) / aa;
    t1 = (-ab + r) / aa;
    return true;
}

double Ellipsoid::chord(const Vec3& o, const Vec3& dir) const {
    double t0, t1;
    return interval(o, dir, t0, t1) ? t1 - t0 : 0.0;
}

bool Ellipsoid::contains(const Vec3& p) const {
    const Vec3 q = toLocal(*this, p - centre);
    return glm::dot(q, q) <= 1.0;
}

EllipsoidPhantom EllipsoidPhantom::sheppLogan3D(double fieldMm) {
    // density, a, b, c, x0, y0, z0, phi (deg, about z), psi (deg, tilt about x)
    static const double table[10][9] = {
        {2.00, .6900, .920, .810, 0, 0, 0, 0, 0},
        {-.98, .6624, .874, .780, 0, -.0184, 0, 0, 0},
        {-.02, .1100, .310, .220, .22, 0, 0, -18, 10},
        {-.02, .1600, .410, .280, -.22, 0, 0, 18, 10},
        {.01, .2100, .250, .410, 0, .35, -.15, 0, 0},
        {.01, .0460, .046, .050, 0, .1, .25, 0, 0},
        {.01, .0460, .046, .050, 0, -.1, .25, 0, 0},
        {.01, .0460, .023, .050, -.08, -.605, 0, 0, 0},
        {.01, .0230, .023, .020, 0, -.606, 0, 0, 0},
        {.01, .0230, .046, .020, .06, -.605, 0, 0, 0},
    };
    const double u = fieldMm / 2.0;
    EllipsoidPhantom p;
    for (const auto& t : table) {
        Ellipsoid e;
        e.density = t[0];
        e.semiAxes = {t[1] * u, t[2] * u, t[3] * u};
        // The classic figure has +y up; the volume's +y (row) points down in the default view.
        e.centre = {t[4] * u, -t[5] * u, t[6] * u};
        const double phi = t[7] * std::numbers::pi / 180.0, psi = t[8] * std::numbers::pi / 180.0;
        // Axes in the classic frame: Rz(phi) * Rx(psi) applied to the unit axes; then y -> -y.
        const double cp = std::cos(phi), sp = std::sin(phi), cs = std::cos(psi), ss = std::sin(psi);
        const Vec3 ax0{cp, sp, 0};
        const Vec3 ax1{-sp * cs, cp * cs, ss};
        const Vec3 ax2{sp * ss, -cp * ss, cs};
        e.axes = {Vec3{ax0[0], -ax0[1], ax0[2]}, Vec3{ax1[0], -ax1[1], ax1[2]},
                  Vec3{ax2[0], -ax2[1], ax2[2]}};
        p.ellipsoids.push_back(e);
    }
    return p;
}

Volume EllipsoidPhantom::voxelize(const Dims3& dims, const Vec3& spacing, int supersample) const {
    validateGeometry(dims, spacing, "phantom");
    checkMemoryFor(std::uint64_t(dims[0] * dims[1] * dims[2]) * sizeof(float), "phantom",
                   std::to_string(dims[0]) + " x " + std::to_string(dims[1]) + " x " +
                       std::to_string(dims[2]) + " voxels as float");
    Volume v;
    v.dims = dims;
    v.spacing = spacing;
    v.units = ValueUnits::HounsfieldUnits;
    v.name = "phantom";
    v.origin = {-(dims[0] - 1) / 2.0 * spacing[0], -(dims[1] - 1) / 2.0 * spacing[1],
                -(dims[2] - 1) / 2.0 * spacing[2]};
    const int S = std::max(1, supersample);
    // mu becomes HU in place: one volume in memory, not two (0.5 GiB more at 512^3).
    v.voxels = composition == Composition::Paint ? voxelizePainted(ellipsoids, dims, spacing, S)
                                                 : voxelizeSum(ellipsoids, dims, spacing, S);
    for (float& x : v.voxels) x = 1000.0f * (x - 1.0f);
    return v;
}

namespace {
std::vector<float> voxelizeSum(const std::vector<Ellipsoid>& ellipsoids, const Dims3& dims,
                               const Vec3& spacing, int S) {
    std::vector<float> mu(std::size_t(dims[0] * dims[1] * dims[2]), 0.0f);
    const double halfDiag = 0.5 * std::sqrt(glm::dot(spacing, spacing));
    ThreadPool pool;
    for (const Ellipsoid& e : ellipsoids) {
        const double minAxis = std::min({e.semiAxes[0], e.semiAxes[1], e.semiAxes[2]});
        const double maxAxis = std::max({e.semiAxes[0], e.semiAxes[1], e.semiAxes[2]});
        std::int64_t lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
            const double c = e.centre[a] / spacing[a] + (dims[a] - 1) / 2.0;
            const double r = maxAxis / spacing[a] + 1.0;
            lo[a] = std::clamp<std::int64_t>(std::int64_t(std::floor(c - r)), 0, dims[a] - 1);
            hi[a] = std::clamp<std::int64_t>(std::int64_t(std::ceil(c + r)), 0, dims[a] - 1);
        }
        const float dens = float(e.density);
        pool.parallelFor(hi[2] - lo[2] + 1, 1, [&](std::int64_t z0, std::int64_t z1) {
            for (std::int64_t z = lo[2] + z0; z < lo[2] + z1; ++z)
                for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
                    for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
                        const Vec3 p{(x - (dims[0] - 1) / 2.0) * spacing[0],
                                     (y - (dims[1] - 1) / 2.0) * spacing[1],
                                     (z - (dims[2] - 1) / 2.0) * spacing[2]};
                        const Vec3 q = toLocal(e, p - e.centre);
                        const double r = std::sqrt(glm::dot(q, q));
                        const double margin = halfDiag / minAxis;
                        float frac;
                        if (r + margin < 1.0)
                            frac = 1.0f;
                        else if (r - margin > 1.0)
                            continue;
                        else {
                            int inside = 0;
                            for (int k = 0; k < S; ++k)
                                for (int j = 0; j < S; ++j)
                                    for (int i = 0; i < S; ++i) {
                                        const Vec3 ps{p[0] + ((i + 0.5) / S - 0.5) * spacing[0],
                                                      p[1] + ((j + 0.5) / S - 0.5) * spacing[1],
                                                      p[2] + ((k + 0.5) / S - 0.5) * spacing[2]};
                                        inside += e.contains(ps);
                                    }
                            frac = float(inside) / float(S * S * S);
                        }
                        mu[std::size_t(x + dims[0] * (y + dims[1] * z))] += dens * frac;
                    }
        });
    }
    return mu;
}
} // namespace

ProjectionImage EllipsoidPhantom::project(const ViewFrame& view, const ImageGeometry& image,
                                          ValueMapping mapping, const Dims3& dims,
                                          const Vec3& spacing, double depthCue) const {
    validateImageGeometry(image);
    if (mapping == ValueMapping::MuBone)
        throw SettingsError(
            "phantom projection: the bone-enhanced mapping has no analytic projection");
    const DepthCueWeights w = depthCueWeights(depthCue, dims, spacing);
    const int W = image.cols(), H = image.rows();
    const double d = image.pixelSize;
    ProjectionImage img;
    img.width = W;
    img.height = H;
    img.pixelSize = d;
    img.view = view;
    img.mapping = mapping;
    img.pixels.assign(std::size_t(W) * H, 0.0f);
    std::vector<int> everyone(ellipsoids.size());
    for (std::size_t i = 0; i < everyone.size(); ++i) everyone[i] = int(i);
    std::vector<Segment> hits, segs;
    std::vector<double> cuts;
    // The phantom's integral along the ray inside the volume's box [b0, b1].
    auto lineIntegral = [&](const Vec3& o, double b0, double b1) {
        double mu = 0.0;
        if (composition == Composition::Paint) {
            paintedSegments(ellipsoids, everyone, o, view.d, b0, b1, hits, cuts, segs);
            for (const Segment& sg : segs)
                mu += sg.density * weightedLength(sg.t0, sg.t1, w.a, w.b);
            return mu;
        }
        double t0, t1;
        for (const Ellipsoid& e : ellipsoids)
            if (e.interval(o, view.d, t0, t1) && std::min(t1, b1) > std::max(t0, b0))
                mu += e.density * weightedLength(std::max(t0, b0), std::min(t1, b1), w.a, w.b);
        return mu;
    };
    const Vec3 half{dims[0] * spacing[0] / 2, dims[1] * spacing[1] / 2, dims[2] * spacing[2] / 2};
    for (int row = 0; row < H; ++row)
        for (int col = 0; col < W; ++col) {
            Vec3 o;
            for (int a = 0; a < 3; ++a)
                o[a] = (col - W / 2) * d * view.r[a] - (row - H / 2) * d * view.u[a];
            double b0, b1;
            if (!boxInterval(o, view.d, half, b0, b1)) continue; // the ray misses the volume
            const double mu = lineIntegral(o, b0, b1);
            const double box = weightedLength(b0, b1, w.a, w.b);
            const double v = mapping == ValueMapping::Mu ? mu : 1000.0 * mu - 1000.0 * box;
            img.pixels[std::size_t(row) * W + col] = float(v);
        }
    return img;
}

Volume makeSheppLoganVolume(int n) {
    if (n < 8 || n > 1024)
        throw SettingsError("phantom size: expected 8..1024, found " + std::to_string(n));
    const double field = 256.0;
    Volume v = EllipsoidPhantom::sheppLogan3D(field).voxelize({n, n, n},
                                                              {field / n, field / n, field / n});
    v.name = "shepp-logan-" + std::to_string(n);
    return v;
}

Volume makeChestPhantomVolume(int n) {
    if (n < 8 || n > 1024)
        throw SettingsError("phantom size: expected 8..1024, found " + std::to_string(n));
    const double field = 420.0;
    Volume v =
        EllipsoidPhantom::chest(field).voxelize({n, n, n}, {field / n, field / n, field / n});
    v.name = "chest-phantom-" + std::to_string(n);
    return v;
}

} // namespace fvr::core
