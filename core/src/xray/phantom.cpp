#include <fvr/core/xray/phantom.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fvr/core/errors.h>
#include <fvr/core/thread_pool.h>
#include <fvr/core/xray/xray.h>

namespace fvr::core {

namespace {
Vec3 toLocal(const Ellipsoid& e, const Vec3& v) {
    // Coordinates along the ellipsoid's axes, scaled by the semi-axes (unit sphere frame).
    return {dot(e.axes[0], v) / e.semiAxes[0], dot(e.axes[1], v) / e.semiAxes[1],
            dot(e.axes[2], v) / e.semiAxes[2]};
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
} // namespace

bool Ellipsoid::interval(const Vec3& o, const Vec3& dir, double& t0, double& t1) const {
    const Vec3 a = toLocal(*this, dir);
    const Vec3 b = toLocal(*this, sub(o, centre));
    const double aa = dot(a, a), ab = dot(a, b), bb = dot(b, b);
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
    const Vec3 q = toLocal(*this, sub(p, centre));
    return dot(q, q) <= 1.0;
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
    Volume v;
    v.dims = dims;
    v.spacing = spacing;
    v.units = ValueUnits::HounsfieldUnits;
    v.name = "phantom";
    v.origin = {-(dims[0] - 1) / 2.0 * spacing[0], -(dims[1] - 1) / 2.0 * spacing[1],
                -(dims[2] - 1) / 2.0 * spacing[2]};
    std::vector<float> mu(std::size_t(v.voxelCount()), 0.0f);
    const int S = std::max(1, supersample);
    const double halfDiag = 0.5 * std::sqrt(dot(spacing, spacing));
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
                        const Vec3 q = toLocal(e, sub(p, e.centre));
                        const double r = std::sqrt(dot(q, q));
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
                        mu[v.index(x, y, z)] += dens * frac;
                    }
        });
    }
    v.voxels.resize(mu.size());
    for (std::size_t i = 0; i < mu.size(); ++i) v.voxels[i] = 1000.0f * (mu[i] - 1.0f);
    return v;
}

ProjectionImage EllipsoidPhantom::project(const ViewFrame& view, const ImageGeometry& image,
                                          ValueMapping mapping, const Dims3& dims,
                                          const Vec3& spacing, double depthCue) const {
    validateImageGeometry(image);
    if (mapping == ValueMapping::MuBone)
        throw SettingsError(
            "phantom projection: the bone-enhanced mapping has no analytic projection");
    const DepthCueWeights w = depthCueWeights(depthCue, dims, spacing);
    const int M = image.size;
    const double d = image.pixelSize;
    ProjectionImage img;
    img.size = M;
    img.pixelSize = d;
    img.view = view;
    img.mapping = mapping;
    img.pixels.resize(std::size_t(M) * M);
    const Vec3 half{dims[0] * spacing[0] / 2, dims[1] * spacing[1] / 2, dims[2] * spacing[2] / 2};
    for (int row = 0; row < M; ++row)
        for (int col = 0; col < M; ++col) {
            Vec3 o;
            for (int a = 0; a < 3; ++a)
                o[a] = (col - M / 2) * d * view.r[a] - (row - M / 2) * d * view.u[a];
            double mu = 0.0, t0, t1;
            for (const Ellipsoid& e : ellipsoids)
                if (e.interval(o, view.d, t0, t1))
                    mu += e.density * weightedLength(t0, t1, w.a, w.b);
            double box = 0.0;
            if (mapping != ValueMapping::Mu && boxInterval(o, view.d, half, t0, t1))
                box = weightedLength(t0, t1, w.a, w.b);
            const double v = mapping == ValueMapping::Mu ? mu : 1000.0 * mu - 1000.0 * box;
            img.pixels[std::size_t(row) * M + col] = float(v);
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

} // namespace fvr::core
