// Cone-beam ray casting through the voxel models (cone_projector.h): a two-level grid walk
// (8^3 blocks, then cells) that skips empty blocks and visits each cell a ray crosses with
// the parameters where it enters and leaves it.
#include <fvr/core/render/cone_projector.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <glm/gtc/matrix_inverse.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/core/text.h>
#include <fvr/core/xray/xray.h>

#include "cone_packet.h"

namespace fvr::core {

const char* rayModelName(RayModel m) {
    switch (m) {
    case RayModel::Trilinear: return "trilinear";
    case RayModel::BSpline: return "bspline";
    case RayModel::Box: return "box";
    }
    return "?";
}

RayModel parseRayModel(const std::string& name) {
    const std::string s = asciiLower(name);
    if (s == "trilinear" || s == "linear") return RayModel::Trilinear;
    if (s == "bspline" || s == "b-spline" || s == "cubic") return RayModel::BSpline;
    if (s == "box" || s == "exact" || s == "siddon") return RayModel::Box;
    throw SettingsError("ray model: expected box, trilinear or bspline, found '" + name + "'");
}

glm::dmat4 indexToPatient(const Volume& v) {
    glm::dmat4 m(1.0);
    for (int a = 0; a < 3; ++a)
        m[a] = glm::dvec4(v.direction[a][0] * v.spacing[a], v.direction[a][1] * v.spacing[a],
                          v.direction[a][2] * v.spacing[a], 0.0);
    m[3] = glm::dvec4(v.origin[0], v.origin[1], v.origin[2], 1.0);
    return m;
}

glm::dvec3 volumeCentre(const Volume& v) {
    const glm::dvec4 c((v.dims[0] - 1) / 2.0, (v.dims[1] - 1) / 2.0, (v.dims[2] - 1) / 2.0, 1.0);
    return glm::dvec3(indexToPatient(v) * c);
}

double framingPitch(const Volume& v, double sid, double sod, int width, int height) {
    const Vec3 e = v.extent();
    const double diagonal = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    return diagonal * (sid / sod) / double(std::max(1, std::min(width, height)));
}

namespace {

/** An LPS direction in the volume's index frame (components along the direction cosines). */
Vec3 toIndexFrame(const Volume& v, const glm::dvec3& x) { return x * v.direction; }

glm::dvec3 toPatient(const Volume& v, const Vec3& x) { return v.direction * x; }

} // namespace

ViewFrame cArmViewFrame(const Volume& volume, double primaryDeg, double secondaryDeg) {
    const ConeCamera c = cArmCamera({primaryDeg, secondaryDeg, 2.0, 1.0}, 16, 16, 1.0, 1.0);
    const glm::dvec3 d = glm::normalize(c.detectorCentre - c.source);
    ViewFrame f;
    f.d = toIndexFrame(volume, -d);
    f.u = toIndexFrame(volume, -c.v);
    f.r = toIndexFrame(volume, c.u);
    return f;
}

CArmAngles cArmAngles(const Volume& volume, const ViewFrame& frame) {
    const glm::dvec3 d = -glm::normalize(toPatient(volume, frame.d));
    CArmAngles a;
    a.secondaryDeg = std::asin(std::clamp(d.z, -1.0, 1.0)) * 180.0 / std::numbers::pi;
    const glm::dvec3 r = toPatient(volume, frame.r);
    a.primaryDeg = std::hypot(d.x, d.y) > 1e-9 ? std::atan2(d.x, -d.y) * 180.0 / std::numbers::pi
                                               : std::atan2(r.y, r.x) * 180.0 / std::numbers::pi;
    if (a.primaryDeg <= -180.0) a.primaryDeg += 360.0;
    return a;
}

std::string cArmLabel(double primaryDeg, double secondaryDeg) {
    const long p = std::lround(primaryDeg), s = std::lround(secondaryDeg);
    return std::string(p < 0 ? "RAO " : "LAO ") + std::to_string(std::labs(p)) + "\u00b0 " +
           (s < 0 ? "CAUD " : "CRAN ") + std::to_string(std::labs(s)) + "\u00b0";
}

ConeCamera cArmCameraForView(const Volume& volume, const ViewFrame& frame, double sid, double sod,
                             int size) {
    const CArmAngles a = cArmAngles(volume, frame);
    const double pitch = framingPitch(volume, sid, sod, size, size);
    return cArmCamera({a.primaryDeg, a.secondaryDeg, sid, sod, volumeCentre(volume)}, size, size,
                      pitch, pitch);
}

namespace {

/** The corners of the voxel cells' box, [-1/2, N - 1/2] per index axis, in LPS. */
std::array<glm::dvec3, 8> boxCorners(const Volume& v) {
    const glm::dmat4 m = indexToPatient(v);
    std::array<glm::dvec3, 8> c;
    for (int k = 0; k < 8; ++k) {
        const glm::dvec4 idx((k & 1) ? v.dims[0] - 0.5 : -0.5, (k & 2) ? v.dims[1] - 0.5 : -0.5,
                             (k & 4) ? v.dims[2] - 0.5 : -0.5, 1.0);
        c[std::size_t(k)] = glm::dvec3(m * idx);
    }
    return c;
}

} // namespace

void validateConeView(const ConeCamera& camera, const Volume& volume) {
    camera.validate();
    const glm::dmat4 toIndex = glm::inverse(indexToPatient(volume));
    const glm::dvec3 s = glm::dvec3(toIndex * glm::dvec4(camera.source, 1.0));
    bool inside = true;
    for (int a = 0; a < 3; ++a) inside = inside && s[a] > -0.5 && s[a] < volume.dims[a] - 0.5;
    if (inside)
        throw SettingsError("camera: the source lies inside the volume (move it out: a larger "
                            "source-to-isocentre distance)");
    const ProjectionMatrix p = camera.matrix();
    const double sid = camera.sourceToDetector();
    bool allBehind = true, allBeyond = true;
    for (const glm::dvec3& x : boxCorners(volume)) {
        const double w = p.apply(x).z;
        allBehind = allBehind && w <= 0.0;
        allBeyond = allBeyond && w >= sid;
    }
    if (allBehind)
        throw SettingsError("camera: the volume lies behind the source (the detector faces away "
                            "from it)");
    if (allBeyond)
        throw SettingsError("camera: the volume lies beyond the detector (no ray from the source "
                            "to the detector crosses it)");
}

std::vector<float> detectorFlatField(const ConeCamera& c) {
    std::vector<float> f(std::size_t(c.width) * std::size_t(c.height));
    const double sid = c.sourceToDetector();
    for (int row = 0; row < c.height; ++row)
        for (int col = 0; col < c.width; ++col) {
            const double r = glm::length(c.pixelCentre(col, row) - c.source);
            const double q = sid / r;
            f[std::size_t(row) * c.width + col] = float(q * q * q);
        }
    return f;
}

std::string describeConeProjector(const ConeProjectorOptions& o) {
    std::string s = std::string(rayModelName(o.model)) + " ray casting, ";
    switch (o.model) {
    case RayModel::Box: s += "exact path lengths"; break;
    case RayModel::Trilinear:
        s += o.stepFraction > 0 ? "step s x " + formatNumber(o.stepFraction) : "exact per cell";
        break;
    case RayModel::BSpline:
        s += "step s x " + formatNumber(o.stepFraction > 0 ? o.stepFraction : 0.25);
        break;
    }
    if (o.pixelSubsamples > 1)
        s += ", " + std::to_string(o.pixelSubsamples) + " x " + std::to_string(o.pixelSubsamples) +
             " rays per pixel";
    return s;
}

// ---- the model's data ---------------------------------------------------------------------------

namespace {

constexpr int kBlock = 8;
/** The B-spline coefficients' margin (as the parallel reference projector's). */
constexpr int kSplineMargin = 10;

/** A grid of cells walked by a ray: `cells` per axis in the walk's coordinates q (cell c
 *  spans [c, c + 1)), and per 8^3 block whether anything in it is non-zero. */
struct CellGrid {
    std::int64_t cells[3] = {0, 0, 0};
    std::int64_t blocks[3] = {0, 0, 0};
    std::vector<std::uint8_t> occupied; ///< per block; empty: every block is walked

    bool blockOccupied(std::int64_t bx, std::int64_t by, std::int64_t bz) const {
        return occupied.empty() || occupied[std::size_t(bx + blocks[0] * (by + blocks[1] * bz))];
    }
};

} // namespace

struct ConeProjector::Data {
    /** Box and trilinear: the mapped voxels with a zero border, lo voxel below and hi above
     *  per axis (x fastest). BSpline: the coefficients with kSplineMargin on every side. */
    std::vector<float> values;
    std::int64_t L[3] = {0, 0, 0};
    int lo = 0;
    CellGrid grid;
    /** Box and trilinear with skipEmpty: the box of the walk's cells that touch a non-zero
     *  voxel (each ray's exact integral is clipped to it: the air around a body is not walked);
     *  else the whole grid. Empty (lo > hi) for a volume of zeros. */
    glm::dvec3 occupiedLo{0.0}, occupiedHi{0.0};
};

namespace {

/** Marks each block of the walk's cells that may hold a cell touching a non-zero voxel. A box
 *  cell c is voxel c, so its blocks are the voxels' blocks; a trilinear cell c (q = index + 1)
 *  has the corners c - 1 and c, so its block b touches voxel blocks b - 1 and b per axis: it is
 *  marked when any of those holds a non-zero voxel (a block marked without need is only walked;
 *  one left unmarked would lose values, which this never does). */
void markBlocks(const Volume& v, const std::vector<float>& mapped, CellGrid& g, bool trilinear) {
    const auto& N = v.dims;
    std::int64_t vb[3];
    for (int a = 0; a < 3; ++a) vb[a] = (N[a] + kBlock - 1) / kBlock;
    std::vector<std::uint8_t> voxelBlocks(std::size_t(vb[0] * vb[1] * vb[2]), 0);
    for (std::int64_t z = 0; z < N[2]; ++z)
        for (std::int64_t y = 0; y < N[1]; ++y) {
            const float* row = mapped.data() + (z * N[1] + y) * N[0];
            std::uint8_t* flags = voxelBlocks.data() + (z / kBlock * vb[1] + y / kBlock) * vb[0];
            for (std::int64_t x = 0; x < N[0]; ++x)
                if (row[x] != 0.0f) flags[x / kBlock] = 1;
        }
    for (int a = 0; a < 3; ++a) g.blocks[a] = (g.cells[a] + kBlock - 1) / kBlock;
    g.occupied.assign(std::size_t(g.blocks[0] * g.blocks[1] * g.blocks[2]), 0);
    const std::int64_t reach = trilinear ? 1 : 0;
    std::int64_t used = 0;
    for (std::int64_t bz = 0; bz < g.blocks[2]; ++bz)
        for (std::int64_t by = 0; by < g.blocks[1]; ++by)
            for (std::int64_t bx = 0; bx < g.blocks[0]; ++bx) {
                bool any = false;
                for (std::int64_t z = std::max<std::int64_t>(bz - reach, 0);
                     z <= std::min(bz, vb[2] - 1) && !any; ++z)
                    for (std::int64_t y = std::max<std::int64_t>(by - reach, 0);
                         y <= std::min(by, vb[1] - 1) && !any; ++y)
                        for (std::int64_t x = std::max<std::int64_t>(bx - reach, 0);
                             x <= std::min(bx, vb[0] - 1) && !any; ++x)
                            any = voxelBlocks[std::size_t(x + vb[0] * (y + vb[1] * z))] != 0;
                g.occupied[std::size_t(bx + g.blocks[0] * (by + g.blocks[1] * bz))] = any;
                used += any;
            }
    // Where most blocks hold something (a CT's noisy air is not 0) the block walk costs more than
    // it skips: walk every cell then.
    if (double(used) > 0.5 * double(g.occupied.size())) g.occupied.clear();
}

/** The cells of the walk that touch a non-zero voxel, as a box in its coordinates: voxel x is
 *  cell x of the box model and cells x, x + 1 of the trilinear one (`extra` 1); the whole grid
 *  without `skip`. */
void occupiedBox(const Volume& v, const std::vector<float>& mapped, bool skip, int extra,
                 ConeProjector::Data& d) {
    const auto& N = v.dims;
    std::int64_t lo[3] = {N[0], N[1], N[2]}, hi[3] = {-1, -1, -1};
    if (!skip) {
        lo[0] = lo[1] = lo[2] = 0;
        for (int a = 0; a < 3; ++a) hi[a] = N[a] - 1;
    } else {
        for (std::int64_t z = 0; z < N[2]; ++z)
            for (std::int64_t y = 0; y < N[1]; ++y) {
                const float* row = mapped.data() + (z * N[1] + y) * N[0];
                std::int64_t first = -1, last = -1;
                for (std::int64_t x = 0; x < N[0]; ++x)
                    if (row[x] != 0.0f) {
                        if (first < 0) first = x;
                        last = x;
                    }
                if (first < 0) continue;
                lo[0] = std::min(lo[0], first);
                hi[0] = std::max(hi[0], last);
                lo[1] = std::min(lo[1], y);
                hi[1] = std::max(hi[1], y);
                lo[2] = std::min(lo[2], z);
                hi[2] = std::max(hi[2], z);
            }
    }
    for (int a = 0; a < 3; ++a) {
        d.occupiedLo[a] = double(lo[a]);
        d.occupiedHi[a] = double(hi[a] + 1 + extra);
    }
}

/** The voxels with lo zeros below and hi zeros above each axis. */
std::vector<float> padded(const std::vector<float>& vox, const Dims3& N, int lo, int hi,
                          std::int64_t L[3]) {
    for (int a = 0; a < 3; ++a) L[a] = N[a] + lo + hi;
    std::vector<float> p(std::size_t(L[0] * L[1] * L[2]), 0.0f);
    for (std::int64_t z = 0; z < N[2]; ++z)
        for (std::int64_t y = 0; y < N[1]; ++y)
            std::copy_n(vox.data() + (z * N[1] + y) * N[0], N[0],
                        p.data() + ((z + lo) * L[1] + (y + lo)) * L[0] + lo);
    return p;
}

} // namespace

ConeProjector::ConeProjector(const Volume& volume, ConeProjectorOptions options)
    : m_volume(volume), m_options(options), m_data(std::make_unique<Data>()),
      m_pool(options.threads) {
    if (options.pixelSubsamples < 1 || options.pixelSubsamples > 16)
        throw SettingsError("ray caster: pixel subsamples must be 1..16, found " +
                            std::to_string(options.pixelSubsamples));
    if (!(options.stepFraction >= 0.0) || options.stepFraction > 4.0)
        throw SettingsError("ray caster: the step must be 0..4 voxel spacings, found " +
                            formatNumber(options.stepFraction));
    validateGeometry(volume.dims, volume.spacing, volume.name);
    std::vector<float> mapped(volume.voxels.size());
    m_pool.parallelFor(std::int64_t(mapped.size()), 1 << 20, [&](std::int64_t i0, std::int64_t i1) {
        for (std::int64_t i = i0; i < i1; ++i)
            mapped[std::size_t(i)] = mapValue(options.mapping, volume.voxels[std::size_t(i)]);
    });
    Data& d = *m_data;
    const auto& N = volume.dims;
    switch (options.model) {
    case RayModel::Box:
        d.lo = 1;
        d.values = padded(mapped, N, 1, 2, d.L);
        for (int a = 0; a < 3; ++a) d.grid.cells[a] = N[a];
        if (options.skipEmpty) markBlocks(volume, mapped, d.grid, false);
        occupiedBox(volume, mapped, options.skipEmpty, 0, d);
        break;
    case RayModel::Trilinear:
        // Two zero voxels below (a cell -1 that rounding reaches at the exit has its corners
        // there), two above.
        d.lo = 2;
        d.values = padded(mapped, N, 2, 2, d.L);
        for (int a = 0; a < 3; ++a) d.grid.cells[a] = N[a] + 1;
        if (options.skipEmpty) markBlocks(volume, mapped, d.grid, true);
        occupiedBox(volume, mapped, options.skipEmpty, 1, d);
        break;
    case RayModel::BSpline:
        d.lo = kSplineMargin;
        d.values = bsplineCoefficients(mapped, N, kSplineMargin);
        for (int a = 0; a < 3; ++a) d.L[a] = N[a] + 2 * kSplineMargin;
        break;
    }
}

ConeProjector::~ConeProjector() = default;

// ---- the ray walk
// ---------------------------------------------------------------------------------

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/** A ray o + t dir in the walk's coordinates, t in [0, 1] from the source to the pixel. */
struct Ray {
    glm::dvec3 o, dir;
};

/** Clips [t0, t1] to the box [lo, hi] per axis; false when nothing is left. */
bool clipToBox(const Ray& r, const glm::dvec3& lo, const glm::dvec3& hi, double& t0, double& t1) {
    for (int a = 0; a < 3; ++a) {
        if (r.dir[a] == 0.0) {
            if (r.o[a] < lo[a] || r.o[a] > hi[a]) return false;
            continue;
        }
        double ta = (lo[a] - r.o[a]) / r.dir[a], tb = (hi[a] - r.o[a]) / r.dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t1 > t0;
}

/** Amanatides and Woo's walk over cells of size 1/scale, indices [lo, hi) per axis, from t0 to
 *  t1: fn(cell, tEnter, tLeave) for each cell crossed, in order. */
template <class Fn>
inline void walk(const Ray& r, double scale, const std::int64_t lo[3], const std::int64_t hi[3],
                 double t0, double t1, Fn&& fn) {
    std::int64_t c[3], step[3];
    double tNext[3], tDelta[3];
    for (int a = 0; a < 3; ++a) {
        const double p = (r.o[a] + t0 * r.dir[a]) * scale;
        c[a] = std::clamp(std::int64_t(std::floor(p)), lo[a], hi[a] - 1);
        if (r.dir[a] > 0.0) {
            step[a] = 1;
            tDelta[a] = 1.0 / (r.dir[a] * scale);
            tNext[a] = (double(c[a] + 1) / scale - r.o[a]) / r.dir[a];
        } else if (r.dir[a] < 0.0) {
            step[a] = -1;
            tDelta[a] = -1.0 / (r.dir[a] * scale);
            tNext[a] = (double(c[a]) / scale - r.o[a]) / r.dir[a];
        } else {
            step[a] = 0;
            tDelta[a] = tNext[a] = kInf;
        }
    }
    double t = t0;
    for (;;) {
        const int a =
            tNext[0] < tNext[1] ? (tNext[0] < tNext[2] ? 0 : 2) : (tNext[1] < tNext[2] ? 1 : 2);
        const double tn = std::min(tNext[a], t1);
        if (tn > t) fn(c, t, tn);
        t = tn;
        if (t >= t1) return;
        c[a] += step[a];
        if (c[a] < lo[a] || c[a] >= hi[a]) return;
        tNext[a] += tDelta[a];
    }
}

/** The same walk over unit cells [lo, hi) for the inner loop, in scalars: fn(index, x, y, z,
 *  tEnter, tLeave) with index = x + y sy + z sz. It takes as many steps as the entry and the
 *  exit cell are apart (Siddon's count), so no bounds are checked per step: where rounding
 *  takes a step across the grid's edge near the exit, the cell visited lies in the zero border
 *  the data carry, for a rounding-sized length. */
template <class Fn>
inline void walkCells(const Ray& r, const std::int64_t lo[3], const std::int64_t hi[3], double t0,
                      double t1, std::int64_t sy, std::int64_t sz, Fn&& fn) {
    std::int64_t c[3], step[3], n = 0;
    double tNext[3], tDelta[3];
    for (int a = 0; a < 3; ++a) {
        const double p0 = r.o[a] + t0 * r.dir[a], p1 = r.o[a] + t1 * r.dir[a];
        c[a] = std::clamp(std::int64_t(std::floor(p0)), lo[a], hi[a] - 1);
        std::int64_t e = std::clamp(std::int64_t(std::floor(p1)), lo[a], hi[a] - 1);
        if (r.dir[a] > 0.0) {
            step[a] = 1;
            tDelta[a] = 1.0 / r.dir[a];
            tNext[a] = (double(c[a] + 1) - r.o[a]) / r.dir[a];
            e = std::max(e, c[a]);
        } else if (r.dir[a] < 0.0) {
            step[a] = -1;
            tDelta[a] = -1.0 / r.dir[a];
            tNext[a] = (double(c[a]) - r.o[a]) / r.dir[a];
            e = std::min(e, c[a]);
        } else {
            step[a] = 0;
            tDelta[a] = tNext[a] = kInf;
            e = c[a];
        }
        n += e > c[a] ? e - c[a] : c[a] - e;
    }
    std::int64_t x = c[0], y = c[1], z = c[2];
    std::int64_t index = x + y * sy + z * sz;
    const std::int64_t dy = step[1] * sy, dz = step[2] * sz;
    double tx = tNext[0], ty = tNext[1], tz = tNext[2], t = t0;
    for (std::int64_t i = 0; i < n; ++i) {
        if (tx <= ty && tx <= tz) {
            fn(index, x, y, z, t, tx);
            t = tx;
            tx += tDelta[0];
            x += step[0];
            index += step[0];
        } else if (ty <= tz) {
            fn(index, x, y, z, t, ty);
            t = ty;
            ty += tDelta[1];
            y += step[1];
            index += dy;
        } else {
            fn(index, x, y, z, t, tz);
            t = tz;
            tz += tDelta[2];
            z += step[2];
            index += dz;
        }
    }
    if (t1 > t) fn(index, x, y, z, t, t1);
}

/** fn(index, x, y, z, tEnter, tLeave) for every cell of `g` the ray crosses within [t0, t1],
 *  blocks of zeros left out when the grid has an occupancy map. */
template <class Fn>
void walkOccupied(const Ray& r, const CellGrid& g, double t0, double t1, std::int64_t sy,
                  std::int64_t sz, Fn&& fn) {
    if (g.occupied.empty()) {
        const std::int64_t lo[3] = {0, 0, 0};
        walkCells(r, lo, g.cells, t0, t1, sy, sz, fn);
        return;
    }
    const std::int64_t zero[3] = {0, 0, 0};
    walk(r, 1.0 / kBlock, zero, g.blocks, t0, t1,
         [&](const std::int64_t* b, double tb0, double tb1) {
             if (!g.blockOccupied(b[0], b[1], b[2])) return;
             std::int64_t lo[3], hi[3];
             for (int a = 0; a < 3; ++a) {
                 lo[a] = b[a] * kBlock;
                 hi[a] = std::min(lo[a] + kBlock, g.cells[a]);
             }
             walkCells(r, lo, hi, tb0, tb1, sy, sz, fn);
         });
}

/** The trilinear interpolant inside one cell from its 8 corners c[z][y][x] at local (x, y, z)
 *  in [0, 1] (float: the voxels are float, and each ray's sum is kept in double). */
inline float trilinear(const float* c, float x, float y, float z) {
    const float c00 = c[0] + x * (c[1] - c[0]), c10 = c[2] + x * (c[3] - c[2]);
    const float c01 = c[4] + x * (c[5] - c[4]), c11 = c[6] + x * (c[7] - c[6]);
    const float c0 = c00 + y * (c10 - c00), c1 = c01 + y * (c11 - c01);
    return c0 + z * (c1 - c0);
}

/** floor(q) for the sampled models' q >= 0 (their clip boxes start at 0 or above; a rounding
 *  -1e-16 gives cell 0 and a fraction of -1e-16): a conversion, not a libm call. */
inline double cellOf(double q) { return double(std::int64_t(q)); }

/** What one ray needs: the model's data and the per-view step. */
struct Caster {
    const ConeProjector::Data& d;
    RayModel model;
    double stepT = 0.0; ///< sampled models: the step in t (fraction of the ray's length)
    std::int64_t sy = 0, sz = 0; ///< strides of the padded values

    /** Box: sum of path length x value over the voxels crossed (t units). */
    double box(const Ray& r, double t0, double t1) const {
        double sum = 0.0;
        const float* v = d.values.data() + d.lo * (1 + sy + sz);
        walkOccupied(r, d.grid, t0, t1, sy, sz,
                     [&](std::int64_t i, std::int64_t, std::int64_t, std::int64_t, double ta,
                         double tb) { sum += (tb - ta) * v[i]; });
        return sum;
    }

    /** The trilinear model's cell c (q = index + 1: between voxels c - 1 and c) has its
     *  corner (0, 0, 0) at this + c (voxel c - 1 lies at padded c - 1 + lo). */
    const float* trilinearCorners() const { return d.values.data() + (d.lo - 1) * (1 + sy + sz); }

    /** Trilinear, exact: Simpson's rule per cell (the interpolant is a cubic along the ray). */
    double trilinearExact(const Ray& r, double t0, double t1) const {
        double sum = 0.0;
        const float* v = trilinearCorners();
        // The value where a cell is left is where the next is entered (the interpolant is
        // continuous): two evaluations per cell.
        double fa = 0.0, tLast = -1.0;
        walkOccupied(
            r, d.grid, t0, t1, sy, sz,
            [&](std::int64_t i, std::int64_t x, std::int64_t y, std::int64_t z, double ta,
                double tb) {
                const float* b = v + i;
                const float k[8] = {b[0],      b[1],      b[sy],      b[sy + 1],
                                    b[sz + 0], b[sz + 1], b[sz + sy], b[sz + sy + 1]};
                const double ox = r.o.x - double(x), oy = r.o.y - double(y), oz = r.o.z - double(z);
                auto at = [&](double t) {
                    return trilinear(k, ox + t * r.dir.x, oy + t * r.dir.y, oz + t * r.dir.z);
                };
                if (ta != tLast) fa = at(ta); // a skipped block or the first cell
                const double fb = at(tb);
                sum += (tb - ta) * (fa + 4.0 * at(0.5 * (ta + tb)) + fb);
                fa = fb;
                tLast = tb;
            });
        sum /= 6.0;
        return sum;
    }

    /** The trilinear interpolant at q (q = index + 1, inside [0, N + 1]). */
    double trilinearAt(double x, double y, double z) const {
        const double fx = cellOf(x), fy = cellOf(y), fz = cellOf(z);
        const float* b =
            trilinearCorners() + std::int64_t(fx) + std::int64_t(fy) * sy + std::int64_t(fz) * sz;
        const float k[8] = {b[0],      b[1],      b[sy],      b[sy + 1],
                            b[sz + 0], b[sz + 1], b[sz + sy], b[sz + sy + 1]};
        return double(trilinear(k, float(x - fx), float(y - fy), float(z - fz)));
    }

    /** The cubic B-spline at q (q = index + kSplineMargin). */
    double bsplineAt(double x, double y, double z) const {
        const double fx = cellOf(x), fy = cellOf(y), fz = cellOf(z);
        double wx[4], wy[4], wz[4];
        auto weights = [](double t, double* w) {
            const double t2 = t * t, t3 = t2 * t, u = 1.0 - t;
            w[0] = u * u * u / 6.0;
            w[1] = (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0;
            w[2] = (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0;
            w[3] = t3 / 6.0;
        };
        weights(x - fx, wx);
        weights(y - fy, wy);
        weights(z - fz, wz);
        const float* b = d.values.data() + (std::int64_t(fx) - 1) + (std::int64_t(fy) - 1) * sy +
                         (std::int64_t(fz) - 1) * sz;
        double acc = 0.0;
        for (int cz = 0; cz < 4; ++cz)
            for (int cy = 0; cy < 4; ++cy) {
                const float* row = b + cz * sz + cy * sy;
                acc += wz[cz] * wy[cy] *
                       (wx[0] * row[0] + wx[1] * row[1] + wx[2] * row[2] + wx[3] * row[3]);
            }
        return acc;
    }

    /** Midpoint samples t0 + (k + 1/2) h, h <= stepT, over [t0, t1]; blocks of zeros skipped
     *  (their samples are 0) for the trilinear model. */
    template <class Sample>
    double sampled(const Ray& r, double t0, double t1, bool skip, const Sample& sample) const {
        const std::int64_t n =
            std::max<std::int64_t>(1, std::int64_t(std::ceil((t1 - t0) / stepT)));
        const double h = (t1 - t0) / double(n);
        double sum = 0.0;
        auto run = [&](std::int64_t k0, std::int64_t k1) {
            for (std::int64_t k = std::max<std::int64_t>(k0, 0); k < std::min(k1, n); ++k) {
                const double t = t0 + (double(k) + 0.5) * h;
                sum += sample(r.o.x + t * r.dir.x, r.o.y + t * r.dir.y, r.o.z + t * r.dir.z);
            }
        };
        if (!skip) {
            run(0, n);
        } else {
            // The samples in [tb0, tb1): k with t0 + (k + 1/2) h in it, the same rule for
            // every block, so that each sample is taken once.
            auto first = [&](double t) { return std::int64_t(std::ceil((t - t0) / h - 0.5)); };
            const std::int64_t zero[3] = {0, 0, 0};
            walk(r, 1.0 / kBlock, zero, d.grid.blocks, t0, t1,
                 [&](const std::int64_t* b, double tb0, double tb1) {
                     if (d.grid.blockOccupied(b[0], b[1], b[2])) run(first(tb0), first(tb1));
                 });
        }
        return sum * h;
    }

    /** The integral over t in [0, 1] of the model along r (the walk's coordinates). */
    double integrate(const Ray& r) const {
        double t0 = 0.0, t1 = 1.0;
        switch (model) {
        case RayModel::Box:
            if (d.occupiedLo.x >= d.occupiedHi.x) return 0.0; // only zeros
            return clipToBox(r, d.occupiedLo, d.occupiedHi, t0, t1) ? box(r, t0, t1) : 0.0;
        case RayModel::Trilinear: {
            if (stepT <= 0.0) {
                if (d.occupiedLo.x >= d.occupiedHi.x) return 0.0;
                return clipToBox(r, d.occupiedLo, d.occupiedHi, t0, t1) ? trilinearExact(r, t0, t1)
                                                                        : 0.0;
            }
            // The sampled model keeps the whole grid's clip: its samples stay where they are.
            const glm::dvec3 hi(d.grid.cells[0], d.grid.cells[1], d.grid.cells[2]);
            if (!clipToBox(r, glm::dvec3(0.0), hi, t0, t1)) return 0.0;
            return sampled(r, t0, t1, !d.grid.occupied.empty(),
                           [&](double x, double y, double z) { return trilinearAt(x, y, z); });
        }
        case RayModel::BSpline: {
            // All 4 taps of a sample, floor(q) - 1 .. floor(q) + 2, inside the coefficients.
            const glm::dvec3 lo(1.0),
                hi(double(d.L[0] - 3), double(d.L[1] - 3), double(d.L[2] - 3));
            if (!clipToBox(r, lo, hi, t0, t1)) return 0.0;
            return sampled(r, t0, t1, false,
                           [&](double x, double y, double z) { return bsplineAt(x, y, z); });
        }
        }
        return 0.0;
    }
};

/** The exact models' integrals of the four rays of pixels (col .. col + 3, row) into out, by
 *  the AVX2 walk of four rays at once (each clipped to the occupied box); false where it
 *  declines (rays of different major axes), for the walk of one ray at a time. */
bool castPacket(const ConeProjector::Data& d, bool box, const detail::CellData& cells,
                const ConeCamera& camera, const glm::dvec3& src, const glm::dvec3& p00,
                const glm::dvec3& du, const glm::dvec3& dv, int col, std::int64_t row, float* out) {
    detail::RayPacket p;
    double length[4];
    for (int k = 0; k < 4; ++k) {
        const glm::dvec3 end = p00 + double(col + k) * du + double(row) * dv;
        length[k] = glm::length(camera.pixelCentre(col + k, double(row)) - camera.source);
        const Ray ray{src, end - src};
        p.t0[k] = 0.0;
        p.t1[k] = 1.0;
        if (!clipToBox(ray, d.occupiedLo, d.occupiedHi, p.t0[k], p.t1[k])) p.t0[k] = p.t1[k] = 0.0;
        for (int a = 0; a < 3; ++a) {
            p.o[k][a] = ray.o[a];
            p.dir[k][a] = ray.dir[a];
        }
    }
    double sums[4];
    if (!(box ? detail::boxPacketAvx2(cells, p, sums)
              : detail::trilinearPacketAvx2(cells, p, sums)))
        return false;
    for (int k = 0; k < 4; ++k) out[k] = float(length[k] * sums[k]);
    return true;
}

} // namespace

DetectorImage ConeProjector::project(const ConeCamera& camera) {
    validateConeView(camera, m_volume);
    DetectorImage img;
    img.width = camera.width;
    img.height = camera.height;
    img.camera = camera;
    img.mapping = m_options.mapping;
    img.pixels.assign(std::size_t(img.width) * std::size_t(img.height), 0.0f);

    const Data& d = *m_data;
    // The walk's coordinates: voxel index + lo for the sampled models, + 1/2 for the box's cells
    // (cell c = voxel c spans [c, c + 1)) and + 1 for the trilinear cells (between voxel
    // centres c - 1 and c).
    const double offset = m_options.model == RayModel::Box         ? 0.5
                          : m_options.model == RayModel::Trilinear ? 1.0
                                                                   : double(d.lo);
    const glm::dmat4 toIndex = glm::inverse(indexToPatient(m_volume));
    auto walkPoint = [&](const glm::dvec3& x) {
        return glm::dvec3(toIndex * glm::dvec4(x, 1.0)) + glm::dvec3(offset);
    };
    const glm::dvec3 src = walkPoint(camera.source);
    const glm::dvec3 p00 = walkPoint(camera.pixelCentre(0, 0));
    const glm::dvec3 du = walkPoint(camera.pixelCentre(1, 0)) - p00;
    const glm::dvec3 dv = walkPoint(camera.pixelCentre(0, 1)) - p00;
    const auto& s = m_volume.spacing;
    const double stepMm = std::min({s[0], s[1], s[2]}) *
                          (m_options.model == RayModel::BSpline && m_options.stepFraction <= 0
                               ? 0.25
                               : m_options.stepFraction);
    Caster caster{d, m_options.model, 0.0, d.L[0], d.L[0] * d.L[1]};
    const int sub = m_options.pixelSubsamples;
    const int W = img.width;
    // The exact models (box, trilinear) with one ray per pixel walk four neighbouring pixels'
    // rays at once where the CPU has AVX2 (every cell of the occupied box: no block skipping).
    const bool box = m_options.model == RayModel::Box;
    const bool packets =
        (box || (m_options.model == RayModel::Trilinear && m_options.stepFraction <= 0.0)) &&
        sub == 1 && detail::coneAvx2() && d.occupiedLo.x < d.occupiedHi.x;
    detail::CellData cells;
    cells.v =
        box ? d.values.data() + d.lo * (1 + d.L[0] + d.L[0] * d.L[1]) : caster.trilinearCorners();
    cells.stride[1] = d.L[0];
    cells.stride[2] = d.L[0] * d.L[1];
    for (int a = 0; a < 3; ++a) cells.cells[a] = d.grid.cells[a];
    m_pool.parallelFor(img.height, 1, [&](std::int64_t r0, std::int64_t r1) {
        Caster c = caster;
        for (std::int64_t row = r0; row < r1; ++row)
            for (int col = 0; col < W; ++col) {
                if (packets && col + 4 <= W &&
                    castPacket(d, box, cells, camera, src, p00, du, dv, col, row,
                               img.pixels.data() + std::size_t(row) * W + col)) {
                    col += 3;
                    continue;
                }
                double sum = 0.0;
                for (int j = 0; j < sub; ++j)
                    for (int i = 0; i < sub; ++i) {
                        const double fu = col + (i + 0.5) / sub - 0.5;
                        const double fv = double(row) + (j + 0.5) / sub - 0.5;
                        const glm::dvec3 end = p00 + fu * du + fv * dv;
                        const double length =
                            glm::length(camera.pixelCentre(fu, fv) - camera.source);
                        c.stepT = stepMm > 0 ? stepMm / length : 0.0;
                        sum += length * c.integrate(Ray{src, end - src});
                    }
                img.pixels[std::size_t(row) * W + col] = float(sum / double(sub * sub));
            }
    });
    return img;
}

} // namespace fvr::core
