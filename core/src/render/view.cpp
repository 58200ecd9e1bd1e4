#include <fvr/core/render/view.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include <glm/ext/matrix_transform.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/render/voxel_model.h>

namespace fvr::core {

ViewFrame ViewFrame::fromDirUp(const Vec3& dir, const Vec3& up) {
    const double nd = glm::length(dir);
    if (!(nd > 1e-12) || !std::isfinite(nd))
        throw SettingsError("view direction: expected a non-zero finite vector");
    ViewFrame f;
    f.d = dir * (1.0 / nd);
    const Vec3 upOrtho = up - f.d * glm::dot(up, f.d);
    const double nu = glm::length(upOrtho);
    if (!(nu > 1e-9 * std::max(1.0, glm::length(up))) || !std::isfinite(nu))
        throw SettingsError("view up vector: expected a vector not parallel to the direction");
    f.u = upOrtho * (1.0 / nu);
    f.r = glm::cross(f.d, f.u);
    return f;
}

ViewFrame ViewFrame::rotated(const Vec3& axis, double angleRad) const {
    const double n = glm::length(axis);
    if (!(n > 1e-12)) throw SettingsError("rotation axis: expected a non-zero vector");
    // GLM's rotation about the axis (right-handed; it normalises the axis itself).
    const glm::dmat3 rotation(glm::rotate(glm::dmat4(1.0), angleRad, axis));
    ViewFrame f = fromDirUp(rotation * d, rotation * u);
    if (glm::dot(r, glm::cross(d, u)) < 0) f.r = -f.r; // keep a mirrored frame mirrored
    return f;
}

double defaultPixelSize(const Dims3& dims, const Vec3& spacing, int size) {
    double diag2 = 0.0;
    for (int a = 0; a < 3; ++a)
        diag2 += double(dims[a]) * spacing[a] * double(dims[a]) * spacing[a];
    return std::sqrt(diag2) / size;
}

namespace {
/** The smallest allowed side (fourierSide) of at least `need` pixels, at most 4096. */
int sideOfAtLeast(int need, bool powerOfTwo) {
    need = std::clamp(need, 16, 4096);
    int M = 16;
    if (powerOfTwo) {
        while (M < need) M *= 2;
        return M;
    }
    for (M = need + need % 2;; M += 2) { // even: the half spectrum's Nyquist column exists
        int rest = M;
        for (int p : {2, 3, 5, 7})
            while (rest % p == 0) rest /= p;
        if (rest == 1) return M;
    }
}
} // namespace

int fourierSide(int width, int height, bool powerOfTwo) {
    return sideOfAtLeast(std::max(width, height), powerOfTwo);
}

int fourierSide(const ImageGeometry& image, const Dims3& dims, const Vec3& spacing,
                bool powerOfTwo) {
    const int W = image.cols(), H = image.rows();
    if (W == H && fourierSide(W, H, powerOfTwo) == W) return W; // a square as it always was
    // The diagonal over the pixel size, less a rounding tolerance (the default pixel size gives
    // min(W, H) exactly).
    const double period = defaultPixelSize(dims, spacing, 1) / image.pixelSize - 1e-6;
    const double need = std::max({double(W), double(H), std::min(4096.0, std::ceil(period))});
    return sideOfAtLeast(int(need), powerOfTwo);
}

void validateImageGeometry(const ImageGeometry& g) {
    for (const auto& [what, n] : {std::pair{"width", g.cols()}, std::pair{"height", g.rows()}})
        if (n < 16 || n > 4096)
            throw SettingsError(std::string("image ") + what +
                                ": expected 16..4096 pixels, found " + std::to_string(n));
    if (!(g.pixelSize > 0.0) || !std::isfinite(g.pixelSize))
        throw SettingsError("pixel size: expected a positive number of mm, found " +
                            std::to_string(g.pixelSize));
}

PixelSizeRange pixelSizeRange(const Dims3& dims, const Vec3& spacing, int size) {
    const double diagonal = defaultPixelSize(dims, spacing, 1);
    const double largestSpacing = std::max({spacing[0], spacing[1], spacing[2]});
    // The slice's highest frequency (slice_params.h) is at most
    // (M/2 + 1) / (M d) * sqrt(2) * s_a cycles per voxel along axis a, whatever the view.
    const double finest = (size / 2.0 + 1.0) / size * std::sqrt(2.0) * largestSpacing /
                          TransferTable::kMaxCyclesPerVoxel;
    return {std::max(diagonal / kFieldOfViewFactor / size, finest),
            diagonal * kFieldOfViewFactor / size};
}

void validateImageGeometry(const ImageGeometry& g, const Dims3& dims, const Vec3& spacing) {
    validateImageGeometry(g);
    // The larger side bounds the finest pixel, the smaller side the coarsest (the span rule
    // holds both ways).
    const int longSide = std::max(g.cols(), g.rows()), shortSide = std::min(g.cols(), g.rows());
    const PixelSizeRange r{pixelSizeRange(dims, spacing, longSide).min,
                           pixelSizeRange(dims, spacing, shortSide).max};
    if (g.pixelSize >= r.min && g.pixelSize <= r.max) return;
    const double diagonal = defaultPixelSize(dims, spacing, 1);
    const std::string shape =
        g.square() ? std::to_string(g.cols()) + "-pixel"
                   : std::to_string(g.cols()) + "x" + std::to_string(g.rows()) + "-pixel";
    char msg[640];
    std::snprintf(msg, sizeof msg,
                  "pixel size %g mm: the %s image would span %g mm of a volume whose "
                  "diagonal is %g mm; expected a pixel size from %g to %g mm at this size (the "
                  "image spans 1/%g to %g times the volume's diagonal, and a pixel is at least "
                  "1/%.0f of the largest voxel spacing, %g mm)",
                  g.pixelSize, shape.c_str(), g.pixelSize * longSide, diagonal, r.min, r.max,
                  kFieldOfViewFactor, kFieldOfViewFactor,
                  TransferTable::kMaxCyclesPerVoxel / std::sqrt(2.0) * 2.0,
                  std::max({spacing[0], spacing[1], spacing[2]}));
    throw SettingsError(msg);
}

Vec3 supportHalfExtents(const Dims3& dims, const Vec3& spacing, double reach) {
    Vec3 h;
    for (int a = 0; a < 3; ++a) h[a] = ((double(dims[a]) - 1.0) / 2.0 + reach) * spacing[a];
    return h;
}

bool rayMissesVolume(const ViewFrame& view, const Vec3& half, int M, double d, int col, int row) {
    double t0 = -1e300, t1 = 1e300;
    for (int a = 0; a < 3; ++a) {
        const double h = half[a];
        const double o = (col - M / 2) * d * view.r[a] - (row - M / 2) * d * view.u[a];
        if (std::abs(view.d[a]) < 1e-9) {
            if (std::abs(o) >= h) return true;
            continue;
        }
        const double ta = (-h - o) / view.d[a], tb = (h - o) / view.d[a];
        t0 = std::max(t0, std::min(ta, tb));
        t1 = std::min(t1, std::max(ta, tb));
    }
    return !(t1 > t0);
}

ColumnRange volumeShadowColumns(const ViewFrame& view, const Vec3& half, int M, double d, int row) {
    // The pixel ray x R + y (-U) + t D, y fixed by the row, hits the grown box where
    // |x R_a - y U_a + t D_a| <= h_a for every axis: a convex polygon in (x, t). Its extent in x
    // comes from its vertices (pairwise intersections of the 6 boundary lines that satisfy all
    // constraints); the exact per-pixel test then settles the columns at either end.
    const double y = (row - M / 2) * d;
    double A[6], B[6], C[6];
    for (int a = 0; a < 3; ++a) {
        const double h = half[a];
        for (int s = 0; s < 2; ++s) {
            const double sg = s ? -1.0 : 1.0;
            A[2 * a + s] = sg * view.r[a];
            B[2 * a + s] = sg * view.d[a];
            C[2 * a + s] = h + sg * y * view.u[a];
        }
    }
    double xmin = 1e300, xmax = -1e300;
    for (int i = 0; i < 6; ++i)
        for (int j = i + 1; j < 6; ++j) {
            const double det = A[i] * B[j] - A[j] * B[i];
            if (std::abs(det) < 1e-12) continue;
            const double x = (C[i] * B[j] - C[j] * B[i]) / det,
                         t = (A[i] * C[j] - A[j] * C[i]) / det;
            bool inside = true;
            for (int k = 0; k < 6 && inside; ++k)
                inside = A[k] * x + B[k] * t <= C[k] + 1e-9 * (1.0 + std::abs(C[k]));
            if (inside) {
                xmin = std::min(xmin, x);
                xmax = std::max(xmax, x);
            }
        }
    auto misses = [&](int col) { return rayMissesVolume(view, half, M, d, col, row); };
    ColumnRange r;
    if (xmin > xmax) { // no vertex: empty; confirm at the centre column
        if (misses(M / 2)) return r;
        xmin = xmax = 0.0;
    }
    r.first = std::clamp(int(std::ceil(xmin / d)) + M / 2, 0, M - 1);
    r.last = std::clamp(int(std::floor(xmax / d)) + M / 2, 0, M - 1);
    if (r.first > r.last)
        r.first = r.last = std::clamp(int(std::lround((xmin + xmax) / 2 / d)) + M / 2, 0, M - 1);
    // Settle the ends with the exact test (the estimate is within rounding of them).
    while (r.first > 0 && !misses(r.first - 1)) --r.first;
    while (r.first <= r.last && misses(r.first)) ++r.first;
    while (r.last < M - 1 && !misses(r.last + 1)) ++r.last;
    while (r.last >= r.first && misses(r.last)) --r.last;
    if (r.first > r.last) return ColumnRange{};
    return r;
}

} // namespace fvr::core
