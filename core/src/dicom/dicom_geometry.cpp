// Slice geometry of a DICOM series: order along the slice normal, spacing from positions, and
// the decisions for uneven gaps, missing slices, sheared (gantry-tilted) stacks and duplicate
// positions (see dicom.h for the policy).
#include "dicom_internal.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <sstream>

namespace fvr::core::dicom_detail {

namespace {

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    const std::size_t m = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
    double hi = v[m];
    if (v.size() % 2 == 1) return hi;
    const double lo = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m));
    return 0.5 * (lo + hi);
}

std::string vecText(const Vec3& v) {
    std::string s = "(";
    s.append(fmt(v[0], 4)).append(", ").append(fmt(v[1], 4)).append(", ").append(fmt(v[2], 4));
    s.append(")");
    return s;
}

/** Distinct values of `gaps` (within `tol`), as "4.002 mm (13x), 6.999 mm (13x)". */
std::string gapSummary(const std::vector<double>& gaps, double tol) {
    std::vector<double> s = gaps;
    std::sort(s.begin(), s.end());
    std::vector<std::pair<double, int>> groups; // mean, count
    double sum = 0;
    int count = 0;
    double first = 0;
    for (double g : s) {
        if (count > 0 && g - first > tol) {
            groups.emplace_back(sum / count, count);
            sum = 0;
            count = 0;
        }
        if (count == 0) first = g;
        sum += g;
        ++count;
    }
    if (count > 0) groups.emplace_back(sum / count, count);
    std::string out;
    const std::size_t shown = std::min<std::size_t>(groups.size(), 8);
    for (std::size_t i = 0; i < shown; ++i) {
        if (i) out += ", ";
        out += fmt(groups[i].first, 3) + " mm (" + std::to_string(groups[i].second) + "x)";
    }
    if (groups.size() > shown) out += ", ... (" + std::to_string(groups.size()) + " distinct gaps)";
    return out;
}

/** In-plane spacing: PixelSpacing is (row spacing, column spacing); index x runs along a row, so
 *  its spacing is the column spacing. Equal in every slice (within 0.1 %). */
std::pair<double, double> inPlaneSpacing(const std::vector<PlanSlice>& slices,
                                         const std::string& source, GeometryPlan& plan) {
    const FrameInfo& f0 = *slices[0].info;
    double sx = 1.0, sy = 1.0;
    if (f0.hasPixelSpacing) {
        sx = f0.colSpacing;
        sy = f0.rowSpacing;
    } else {
        plan.warnings.push_back("PixelSpacing (0028,0030) missing: 1 x 1 mm pixels assumed");
    }
    for (const PlanSlice& s : slices) {
        const FrameInfo& f = *s.info;
        const double dsx = std::abs((f.hasPixelSpacing ? f.colSpacing : 1.0) - sx);
        const double dsy = std::abs((f.hasPixelSpacing ? f.rowSpacing : 1.0) - sy);
        if (f.hasPixelSpacing != f0.hasPixelSpacing || dsx > 1e-3 * sx || dsy > 1e-3 * sy)
            fail(source, "PixelSpacing (0028,0030) differs within the series: " + slices[0].label +
                             " has " + fmt(sy, 4) + "\\" + fmt(sx, 4) + ", " + s.label + " has " +
                             (f.hasPixelSpacing ? fmt(f.rowSpacing, 4) + "\\" + fmt(f.colSpacing, 4)
                                                : std::string("none")));
    }
    return {sx, sy};
}

/** The mean of the slices' unit row and column cosines (every slice checked orthonormal). */
std::pair<Vec3, Vec3> meanCosines(const std::vector<PlanSlice>& slices, const std::string& source) {
    Vec3 rs{0, 0, 0}, cs{0, 0, 0};
    for (const PlanSlice& s : slices) {
        const auto& o = s.info->orientation;
        const Vec3 ri{o[0], o[1], o[2]}, ci{o[3], o[4], o[5]};
        const double nr = glm::length(ri), nc = glm::length(ci);
        if (std::abs(nr - 1.0) > 0.01 || std::abs(nc - 1.0) > 0.01 ||
            std::abs(glm::dot(ri, ci)) > 0.01 * nr * nc)
            fail(source, "ImageOrientationPatient (0020,0037) in " + s.label +
                             ": expected two orthogonal unit vectors, found row " + vecText(ri) +
                             ", column " + vecText(ci));
        rs += ri * (1.0 / nr);
        cs += ci * (1.0 / nc);
    }
    return {rs, cs};
}

/** The largest angle (radians) between a slice's row or column cosine and r or c. */
double orientationSpread(const std::vector<PlanSlice>& slices, const Vec3& r, const Vec3& c) {
    double spread = 0.0;
    for (const PlanSlice& s : slices) {
        const auto& o = s.info->orientation;
        spread = std::max(spread, std::acos(std::clamp(glm::dot(r, Vec3{o[0], o[1], o[2]}) /
                                                           glm::length(Vec3{o[0], o[1], o[2]}),
                                                       -1.0, 1.0)));
        spread = std::max(spread, std::acos(std::clamp(glm::dot(c, Vec3{o[3], o[4], o[5]}) /
                                                           glm::length(Vec3{o[3], o[4], o[5]}),
                                                       -1.0, 1.0)));
    }
    return spread;
}

/** Orientation: the mean of the slices' row and column cosines, made orthonormal. Returns the
 *  row and column directions. */
std::pair<Vec3, Vec3> meanOrientation(const std::vector<PlanSlice>& slices, bool allFromOneFile,
                                      const std::string& source, GeometryPlan& plan) {
    const std::size_t n = slices.size();
    std::size_t withOrientation = 0;
    for (const PlanSlice& s : slices) withOrientation += s.info->hasOrientation ? 1 : 0;
    if (withOrientation == 0) {
        if (n > 1 && !allFromOneFile)
            fail(source, "ImageOrientationPatient (0020,0037) missing in all " + std::to_string(n) +
                             " files: the slices cannot be oriented or ordered");
        plan.warnings.push_back(
            "ImageOrientationPatient (0020,0037) missing: rows along +x (L), columns along +y (P) "
            "assumed");
        return {Vec3{1, 0, 0}, Vec3{0, 1, 0}};
    }
    if (withOrientation != n) {
        for (const PlanSlice& s : slices)
            if (!s.info->hasOrientation)
                fail(source, "ImageOrientationPatient (0020,0037) missing in " + s.label +
                                 " but present in other slices of the series");
    }
    const auto [rs, cs] = meanCosines(slices, source);
    const Vec3 r = rs * (1.0 / glm::length(rs));
    Vec3 c = cs - r * glm::dot(cs, r);
    c = c * (1.0 / glm::length(c));
    const double spread = orientationSpread(slices, r, c);
    if (spread > 1e-4)
        plan.warnings.push_back("slice orientations differ by up to " +
                                fmt(spread * 180.0 / std::numbers::pi, 3) +
                                " deg; the mean orientation is used");
    return {r, c};
}

/** The slice spacing a stack without usable positions gets, and (in `from`) where it came from. */
double fallbackThickness(const FrameInfo& f0, std::string& from) {
    if (f0.spacingBetweenSlices > 0) {
        from = "SpacingBetweenSlices (0018,0088)";
        return f0.spacingBetweenSlices;
    }
    if (f0.sliceThickness > 0) {
        from = "SliceThickness (0018,0050)";
        return f0.sliceThickness;
    }
    from = "assumed: no SpacingBetweenSlices or SliceThickness";
    return 1.0;
}

/** One slice: its thickness is the only z spacing there is. */
void planSingleSlice(const FrameInfo& f0, std::int64_t cols, std::int64_t rows, double sx,
                     double sy, GeometryPlan& plan) {
    std::string from;
    const double dz = fallbackThickness(f0, from);
    if (f0.hasPosition)
        plan.origin = f0.position;
    else
        plan.warnings.push_back(
            "ImagePositionPatient (0020,0032) missing: origin (0, 0, 0) assumed");
    if (from.rfind("assumed", 0) == 0)
        plan.warnings.push_back("single slice without SliceThickness: 1 mm slab assumed");
    plan.dims = {cols, rows, 1};
    plan.spacing = {sx, sy, dz};
    plan.order = {0};
}

/** Frames of one multi-frame file without positions of their own: stacked in file order. */
void planFileOrderStack(const FrameInfo& f0, std::size_t n, std::int64_t cols, std::int64_t rows,
                        double sx, double sy, GeometryPlan& plan) {
    std::string from;
    const double dz = fallbackThickness(f0, from);
    if (f0.hasPosition) plan.origin = f0.position;
    plan.dims = {cols, rows, static_cast<std::int64_t>(n)};
    plan.spacing = {sx, sy, dz};
    plan.order.resize(n);
    std::iota(plan.order.begin(), plan.order.end(), 0);
    plan.warnings.push_back("no per-frame ImagePositionPatient: the " + std::to_string(n) +
                            " frames are stacked in file order at " + fmt(dz, 3) + " mm (" + from +
                            "); the slice geometry is not verified");
}

/** The slices sorted along the normal, with what decides between a plain stack and resampling. */
struct SortedStack {
    std::vector<double> t; ///< distance along the normal (mm), sorted
    std::vector<Vec3> p; ///< positions, sorted
    std::vector<double> gaps; ///< t[k+1] - t[k]
    double gm = 0.0; ///< median gap
    double gapTol = 0.0;
    bool uneven = false;
    std::vector<double> u, v; ///< in-plane offsets of each slice from the first (mm)
    double maxShift = 0.0;
    bool sheared = false;
};

/** Sorts along the normal (plan.order) and fills t and p. */
SortedStack sortAlongNormal(const std::vector<PlanSlice>& slices, const Vec3& nrm,
                            GeometryPlan& plan) {
    const std::size_t n = slices.size();
    std::vector<double> tAll(n);
    for (std::size_t i = 0; i < n; ++i) tAll[i] = glm::dot(slices[i].info->position, nrm);
    plan.order.resize(n);
    std::iota(plan.order.begin(), plan.order.end(), 0);
    std::stable_sort(plan.order.begin(), plan.order.end(), [&](int a, int b) {
        return tAll[static_cast<std::size_t>(a)] < tAll[static_cast<std::size_t>(b)];
    });
    SortedStack s;
    s.t.resize(n);
    s.p.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        s.t[k] = tAll[static_cast<std::size_t>(plan.order[k])];
        s.p[k] = slices[static_cast<std::size_t>(plan.order[k])].info->position;
    }
    return s;
}

/** Duplicate positions: two images of the same plane (several acquisitions, echoes or repeated
 *  scans mixed in one series). Never averaged or dropped silently. */
void rejectDuplicatePositions(const std::vector<PlanSlice>& slices, const SortedStack& s,
                              const GeometryPlan& plan, const std::string& source) {
    constexpr double kDuplicateTol = 0.01; // mm
    const std::size_t n = slices.size();
    std::size_t dups = 0;
    std::size_t firstDup = 0;
    for (std::size_t k = 0; k + 1 < n; ++k) {
        if (s.t[k + 1] - s.t[k] < kDuplicateTol) {
            if (dups == 0) firstDup = k;
            ++dups;
        }
    }
    if (dups > 0) {
        const auto& a = slices[static_cast<std::size_t>(plan.order[firstDup])];
        const auto& b = slices[static_cast<std::size_t>(plan.order[firstDup + 1])];
        fail(source, "duplicate slice positions: " + std::to_string(dups) + " of " +
                         std::to_string(n) + " slices repeat a position (e.g. " + a.label +
                         " and " + b.label + " both at " + fmt(s.t[firstDup], 3) +
                         " mm along the normal); the series mixes acquisitions that could "
                         "not be told apart, refusing to guess which slice belongs where");
    }
}

/** Gaps along the normal (median, evenness) and in-plane offsets (shear). */
void measureStack(SortedStack& s, const Vec3& r, const Vec3& c, double sx, double sy) {
    const std::size_t n = s.t.size();
    s.gaps.resize(n - 1);
    for (std::size_t k = 0; k + 1 < n; ++k) s.gaps[k] = s.t[k + 1] - s.t[k];
    s.gm = median(s.gaps);
    s.gapTol = std::max(0.01, 0.01 * s.gm);
    for (double g : s.gaps) s.uneven = s.uneven || std::abs(g - s.gm) > s.gapTol;

    // In-plane offsets of each slice from the first (mm): zero for a stack along the normal.
    s.u.resize(n);
    s.v.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        const Vec3 d = s.p[k] - s.p[0];
        s.u[k] = glm::dot(d, r);
        s.v[k] = glm::dot(d, c);
        s.maxShift = std::max({s.maxShift, std::abs(s.u[k]), std::abs(s.v[k])});
    }
    const double shiftTol = std::max(0.01, 0.05 * std::min(sx, sy));
    s.sheared = s.maxShift > shiftTol;
}

/** A hole of ten or more missing slices is not something to interpolate across. */
void rejectHugeGap(const std::vector<PlanSlice>& slices, const SortedStack& s,
                   const GeometryPlan& plan, const std::string& source) {
    const double maxGap = *std::max_element(s.gaps.begin(), s.gaps.end());
    if (maxGap > 10.0 * s.gm) {
        const auto k = std::size_t(std::max_element(s.gaps.begin(), s.gaps.end()) - s.gaps.begin());
        fail(source, "slice gap of " + fmt(maxGap, 3) + " mm between " +
                         slices[static_cast<std::size_t>(plan.order[k])].label + " and " +
                         slices[static_cast<std::size_t>(plan.order[k + 1])].label + " is " +
                         fmt(maxGap / s.gm, 1) + " times the median gap (" + fmt(s.gm, 3) +
                         " mm): too large to interpolate across (separate stacks in one "
                         "series?); refusing to load");
    }
}

/** Resample onto a regular, orthogonal grid: z along the normal at the median gap (adjusted so
 *  the first and last slices fall on the grid), x and y extended to cover every slice. */
void planResampling(const SortedStack& s, std::int64_t cols, std::int64_t rows, double sx,
                    double sy, const Vec3& r, const Vec3& c, const std::string& source,
                    GeometryPlan& plan) {
    const std::size_t n = s.t.size();
    const double range = s.t[n - 1] - s.t[0];
    plan.resample = true;
    std::int64_t m = static_cast<std::int64_t>(std::llround(range / s.gm)) + 1;
    if (m < 2) m = 2;
    if (m > kMaxDimPerAxis)
        fail(source, "resampling the uneven slices at the median gap of " + fmt(s.gm, 4) +
                         " mm would need " + std::to_string(m) + " slices (at most " +
                         std::to_string(kMaxDimPerAxis) + ")");
    const double dz = range / double(m - 1);
    const double umin = *std::min_element(s.u.begin(), s.u.end());
    const double umax = *std::max_element(s.u.begin(), s.u.end());
    const double vmin = *std::min_element(s.v.begin(), s.v.end());
    const double vmax = *std::max_element(s.v.begin(), s.v.end());
    const std::int64_t nx = cols + static_cast<std::int64_t>(std::ceil((umax - umin) / sx - 1e-6));
    const std::int64_t ny = rows + static_cast<std::int64_t>(std::ceil((vmax - vmin) / sy - 1e-6));
    if (nx > kMaxDimPerAxis || ny > kMaxDimPerAxis)
        fail(source, "the sheared stack would need " + std::to_string(nx) + " x " +
                         std::to_string(ny) + " pixels per slice (at most " +
                         std::to_string(kMaxDimPerAxis) + ")");
    const double inVoxels = double(cols) * double(rows) * double(n);
    const double outVoxels = double(nx) * double(ny) * double(m);
    if (outVoxels > std::max(16.0 * inVoxels, 64.0 * 1024 * 1024))
        fail(source, "resampling the " + std::to_string(n) +
                         " slices onto a regular grid would "
                         "need " +
                         std::to_string(nx) + " x " + std::to_string(ny) + " x " +
                         std::to_string(m) + " voxels (more than 16 times the input); refusing");
    plan.dims = {nx, ny, m};
    plan.spacing = {sx, sy, dz};
    plan.origin = s.p[0] + (r * umin + c * vmin);
    plan.z0 = 0.0;
    plan.t.resize(n);
    plan.du.resize(n);
    plan.dv.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        plan.t[k] = s.t[k] - s.t[0];
        plan.du[k] = (s.u[k] - umin) / sx;
        plan.dv[k] = (s.v[k] - vmin) / sy;
    }
}

/** The warning for uneven spacing: the gaps, the slices that seem missing, the resampling. */
std::string unevenWarning(const std::vector<PlanSlice>& slices, const SortedStack& s,
                          const GeometryPlan& plan) {
    const std::size_t n = s.t.size();
    std::string msg = "uneven slice spacing along the normal: gaps " +
                      gapSummary(s.gaps, s.gapTol) + " (median " + fmt(s.gm, 3) + " mm)";
    // Gaps close to a multiple of the median: slices are missing there.
    int missingTotal = 0;
    std::string where;
    for (std::size_t k = 0; k + 1 < n; ++k) {
        const double ratio = s.gaps[k] / s.gm;
        const double whole = std::round(ratio);
        if (whole >= 2 && std::abs(ratio - whole) < 0.1) {
            missingTotal += int(whole) - 1;
            if (where.empty())
                where = " (e.g. " + std::to_string(int(whole) - 1) + " between " +
                        slices[static_cast<std::size_t>(plan.order[k])].label + " and " +
                        slices[static_cast<std::size_t>(plan.order[k + 1])].label + ")";
        }
    }
    if (missingTotal > 0)
        msg += "; about " + std::to_string(missingTotal) + " slice(s) missing" + where;
    msg += "; resampled onto " + std::to_string(plan.dims[2]) + " slices at " +
           fmt(plan.spacing[2], 3) + " mm by linear interpolation between neighbouring slices";
    return msg;
}

/** The warning for a sheared stack: its angle against the normal from a least-squares line of
 *  the offsets. */
std::string shearWarning(const std::vector<PlanSlice>& slices, const SortedStack& s,
                         const GeometryPlan& plan) {
    const std::size_t n = s.t.size();
    double tm = 0, um = 0, vm = 0;
    for (std::size_t k = 0; k < n; ++k) {
        tm += s.t[k];
        um += s.u[k];
        vm += s.v[k];
    }
    tm /= double(n);
    um /= double(n);
    vm /= double(n);
    double stt = 0, stu = 0, stv = 0;
    for (std::size_t k = 0; k < n; ++k) {
        stt += (s.t[k] - tm) * (s.t[k] - tm);
        stu += (s.t[k] - tm) * (s.u[k] - um);
        stv += (s.t[k] - tm) * (s.v[k] - vm);
    }
    const double angle =
        stt > 0 ? std::atan(std::hypot(stu / stt, stv / stt)) * 180.0 / std::numbers::pi : 0.0;
    std::string msg = "gantry tilt / sheared stack: slice positions run at " + fmt(angle, 2) +
                      " deg to the slice normal";
    if (!slices[0].gantryTilt.empty())
        msg += " (GantryDetectorTilt (0018,1120): " + slices[0].gantryTilt + " deg)";
    msg += " (in-plane shift up to " + fmt(s.maxShift, 2) +
           " mm); resampled (de-sheared) onto an "
           "orthogonal grid of " +
           std::to_string(plan.dims[0]) + " x " + std::to_string(plan.dims[1]) + " x " +
           std::to_string(plan.dims[2]) +
           " voxels along the image rows, columns and normal, bilinear in "
           "plane; voxels outside every slice are set to the series minimum";
    return msg;
}

} // namespace

GeometryPlan planGeometry(const std::vector<PlanSlice>& slices, std::int64_t cols,
                          std::int64_t rows, const std::string& source) {
    GeometryPlan plan;
    const std::size_t n = slices.size();
    if (n == 0) fail(source, "no slices");
    const FrameInfo& f0 = *slices[0].info;
    const auto [sx, sy] = inPlaneSpacing(slices, source, plan);
    const bool allFromOneFile = std::all_of(slices.begin(), slices.end(), [&](const PlanSlice& s) {
        return s.fromMultiFrame && s.file == slices[0].file;
    });
    const auto [r, c] = meanOrientation(slices, allFromOneFile, source, plan);
    const Vec3 nrm = glm::cross(r, c);
    plan.direction = {r, c, nrm};

    std::size_t withPosition = 0;
    for (const PlanSlice& s : slices)
        withPosition += (s.info->hasPosition && !s.info->fileLevelPosition) ? 1 : 0;
    if (n == 1) {
        planSingleSlice(f0, cols, rows, sx, sy, plan);
        return plan;
    }
    if (withPosition == 0 && allFromOneFile) {
        planFileOrderStack(f0, n, cols, rows, sx, sy, plan);
        return plan;
    }
    if (withPosition != n) {
        for (const PlanSlice& s : slices)
            if (!s.info->hasPosition || s.info->fileLevelPosition)
                fail(source, "ImagePositionPatient (0020,0032) missing in " + s.label + ": the " +
                                 std::to_string(n) +
                                 " slices cannot be ordered by position (file names and "
                                 "InstanceNumber are not used for geometry)");
    }

    SortedStack stack = sortAlongNormal(slices, nrm, plan);
    rejectDuplicatePositions(slices, stack, plan, source);
    measureStack(stack, r, c, sx, sy);
    if (!stack.uneven && !stack.sheared) {
        plan.dims = {cols, rows, static_cast<std::int64_t>(n)};
        plan.spacing = {sx, sy, (stack.t[n - 1] - stack.t[0]) / double(n - 1)};
        plan.origin = stack.p[0];
        return plan;
    }
    rejectHugeGap(slices, stack, plan, source);
    planResampling(stack, cols, rows, sx, sy, r, c, source, plan);
    if (stack.uneven) plan.warnings.push_back(unevenWarning(slices, stack, plan));
    if (stack.sheared) plan.warnings.push_back(shearWarning(slices, stack, plan));
    return plan;
}

} // namespace fvr::core::dicom_detail
