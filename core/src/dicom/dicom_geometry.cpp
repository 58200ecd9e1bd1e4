// Slice geometry of a DICOM series: order along the slice normal, spacing from positions, and
// the decisions for uneven gaps, missing slices, sheared (gantry-tilted) stacks and duplicate
// positions (see dicom.h for the policy).
#include "dicom_internal.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>

namespace fvr::core::dicom_detail {

namespace {

constexpr double kPi = 3.14159265358979323846;

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 add(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 scale(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }

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

[[noreturn]] void failGeom(const std::string& source, const std::string& detail) {
    throw DicomError(source + ": " + detail);
}

} // namespace

GeometryPlan planGeometry(const std::vector<PlanSlice>& slices, std::int64_t cols, std::int64_t rows,
                          const std::string& source) {
    GeometryPlan plan;
    const std::size_t n = slices.size();
    if (n == 0) failGeom(source, "no slices");
    const FrameInfo& f0 = *slices[0].info;

    // In-plane spacing: PixelSpacing is (row spacing, column spacing); index x runs along a row,
    // so its spacing is the column spacing.
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
            failGeom(source, "PixelSpacing (0028,0030) differs within the series: " + slices[0].label +
                                 " has " + fmt(sy, 4) + "\\" + fmt(sx, 4) + ", " + s.label + " has " +
                                 (f.hasPixelSpacing ? fmt(f.rowSpacing, 4) + "\\" + fmt(f.colSpacing, 4)
                                                    : std::string("none")));
    }

    // Orientation: the mean of the slices' row and column cosines, made orthonormal.
    Vec3 r{1, 0, 0}, c{0, 1, 0};
    std::size_t withOrientation = 0;
    for (const PlanSlice& s : slices) withOrientation += s.info->hasOrientation ? 1 : 0;
    const bool allFromOneFile = std::all_of(slices.begin(), slices.end(), [&](const PlanSlice& s) {
        return s.fromMultiFrame && s.file == slices[0].file;
    });
    if (withOrientation == 0) {
        if (n > 1 && !allFromOneFile)
            failGeom(source, "ImageOrientationPatient (0020,0037) missing in all " + std::to_string(n) +
                                 " files: the slices cannot be oriented or ordered");
        plan.warnings.push_back(
            "ImageOrientationPatient (0020,0037) missing: rows along +x (L), columns along +y (P) "
            "assumed");
    } else {
        if (withOrientation != n) {
            for (const PlanSlice& s : slices)
                if (!s.info->hasOrientation)
                    failGeom(source, "ImageOrientationPatient (0020,0037) missing in " + s.label +
                                         " but present in other slices of the series");
        }
        Vec3 rs{0, 0, 0}, cs{0, 0, 0};
        for (const PlanSlice& s : slices) {
            const auto& o = s.info->orientation;
            const Vec3 ri{o[0], o[1], o[2]}, ci{o[3], o[4], o[5]};
            const double nr = norm(ri), nc = norm(ci);
            if (std::abs(nr - 1.0) > 0.01 || std::abs(nc - 1.0) > 0.01 ||
                std::abs(dot(ri, ci)) > 0.01 * nr * nc)
                failGeom(source, "ImageOrientationPatient (0020,0037) in " + s.label +
                                     ": expected two orthogonal unit vectors, found row " +
                                     vecText(ri) + ", column " + vecText(ci));
            rs = add(rs, scale(ri, 1.0 / nr));
            cs = add(cs, scale(ci, 1.0 / nc));
        }
        r = scale(rs, 1.0 / norm(rs));
        c = sub(cs, scale(r, dot(cs, r)));
        c = scale(c, 1.0 / norm(c));
        double spread = 0.0;
        for (const PlanSlice& s : slices) {
            const auto& o = s.info->orientation;
            spread = std::max(spread, std::acos(std::clamp(dot(r, Vec3{o[0], o[1], o[2]}) /
                                                               norm(Vec3{o[0], o[1], o[2]}),
                                                           -1.0, 1.0)));
            spread = std::max(spread, std::acos(std::clamp(dot(c, Vec3{o[3], o[4], o[5]}) /
                                                               norm(Vec3{o[3], o[4], o[5]}),
                                                           -1.0, 1.0)));
        }
        if (spread > 1e-4)
            plan.warnings.push_back("slice orientations differ by up to " +
                                    fmt(spread * 180.0 / kPi, 3) +
                                    " deg; the mean orientation is used");
    }
    const Vec3 nrm = cross(r, c);
    plan.direction = {r, c, nrm};

    auto fallbackThickness = [&](std::string& from) {
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
    };

    std::size_t withPosition = 0;
    for (const PlanSlice& s : slices)
        withPosition += (s.info->hasPosition && !s.info->fileLevelPosition) ? 1 : 0;

    // One slice: its thickness is the only z spacing there is.
    if (n == 1) {
        std::string from;
        const double dz = fallbackThickness(from);
        if (f0.hasPosition) plan.origin = f0.position;
        else plan.warnings.push_back("ImagePositionPatient (0020,0032) missing: origin (0, 0, 0) assumed");
        if (from.rfind("assumed", 0) == 0)
            plan.warnings.push_back("single slice without SliceThickness: 1 mm slab assumed");
        plan.dims = {cols, rows, 1};
        plan.spacing = {sx, sy, dz};
        plan.order = {0};
        return plan;
    }

    // Frames of one multi-frame file without positions of their own: stacked in file order.
    if (withPosition == 0 && allFromOneFile) {
        std::string from;
        const double dz = fallbackThickness(from);
        if (f0.hasPosition) plan.origin = f0.position;
        plan.dims = {cols, rows, static_cast<std::int64_t>(n)};
        plan.spacing = {sx, sy, dz};
        plan.order.resize(n);
        std::iota(plan.order.begin(), plan.order.end(), 0);
        plan.warnings.push_back("no per-frame ImagePositionPatient: the " + std::to_string(n) +
                                " frames are stacked in file order at " + fmt(dz, 3) + " mm (" +
                                from + "); the slice geometry is not verified");
        return plan;
    }
    if (withPosition != n) {
        for (const PlanSlice& s : slices)
            if (!s.info->hasPosition || s.info->fileLevelPosition)
                failGeom(source, "ImagePositionPatient (0020,0032) missing in " + s.label +
                                     ": the " + std::to_string(n) +
                                     " slices cannot be ordered by position (file names and "
                                     "InstanceNumber are not used for geometry)");
    }

    // Sort along the normal.
    std::vector<double> tAll(n);
    for (std::size_t i = 0; i < n; ++i) tAll[i] = dot(slices[i].info->position, nrm);
    plan.order.resize(n);
    std::iota(plan.order.begin(), plan.order.end(), 0);
    std::stable_sort(plan.order.begin(), plan.order.end(),
                     [&](int a, int b) { return tAll[static_cast<std::size_t>(a)] < tAll[static_cast<std::size_t>(b)]; });
    std::vector<double> t(n);
    std::vector<Vec3> p(n);
    for (std::size_t k = 0; k < n; ++k) {
        t[k] = tAll[static_cast<std::size_t>(plan.order[k])];
        p[k] = slices[static_cast<std::size_t>(plan.order[k])].info->position;
    }

    // Duplicate positions: two images of the same plane (several acquisitions, echoes or
    // repeated scans mixed in one series). Never averaged or dropped silently.
    constexpr double kDuplicateTol = 0.01; // mm
    {
        std::size_t dups = 0;
        std::size_t firstDup = 0;
        for (std::size_t k = 0; k + 1 < n; ++k) {
            if (t[k + 1] - t[k] < kDuplicateTol) {
                if (dups == 0) firstDup = k;
                ++dups;
            }
        }
        if (dups > 0) {
            const auto& a = slices[static_cast<std::size_t>(plan.order[firstDup])];
            const auto& b = slices[static_cast<std::size_t>(plan.order[firstDup + 1])];
            failGeom(source, "duplicate slice positions: " + std::to_string(dups) + " of " +
                                 std::to_string(n) + " slices repeat a position (e.g. " + a.label +
                                 " and " + b.label + " both at " + fmt(t[firstDup], 3) +
                                 " mm along the normal); the series mixes acquisitions that could "
                                 "not be told apart, refusing to guess which slice belongs where");
        }
    }

    std::vector<double> gaps(n - 1);
    for (std::size_t k = 0; k + 1 < n; ++k) gaps[k] = t[k + 1] - t[k];
    const double gm = median(gaps);
    const double gapTol = std::max(0.01, 0.01 * gm);
    bool uneven = false;
    for (double g : gaps) uneven = uneven || std::abs(g - gm) > gapTol;

    // In-plane offsets of each slice from the first (mm): zero for a stack along the normal.
    std::vector<double> u(n), v(n);
    double maxShift = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        const Vec3 d = sub(p[k], p[0]);
        u[k] = dot(d, r);
        v[k] = dot(d, c);
        maxShift = std::max({maxShift, std::abs(u[k]), std::abs(v[k])});
    }
    const double shiftTol = std::max(0.01, 0.05 * std::min(sx, sy));
    const bool sheared = maxShift > shiftTol;

    const double range = t[n - 1] - t[0];
    if (!uneven && !sheared) {
        plan.dims = {cols, rows, static_cast<std::int64_t>(n)};
        plan.spacing = {sx, sy, range / double(n - 1)};
        plan.origin = p[0];
        return plan;
    }

    // A hole of ten or more missing slices is not something to interpolate across.
    const double maxGap = *std::max_element(gaps.begin(), gaps.end());
    if (maxGap > 10.0 * gm) {
        const auto k = std::size_t(std::max_element(gaps.begin(), gaps.end()) - gaps.begin());
        failGeom(source, "slice gap of " + fmt(maxGap, 3) + " mm between " +
                             slices[static_cast<std::size_t>(plan.order[k])].label + " and " +
                             slices[static_cast<std::size_t>(plan.order[k + 1])].label + " is " +
                             fmt(maxGap / gm, 1) + " times the median gap (" + fmt(gm, 3) +
                             " mm): too large to interpolate across (separate stacks in one "
                             "series?); refusing to load");
    }

    // Resample onto a regular, orthogonal grid: z along the normal at the median gap (adjusted so
    // the first and last slices fall on the grid), x and y extended to cover every slice.
    plan.resample = true;
    std::int64_t m = static_cast<std::int64_t>(std::llround(range / gm)) + 1;
    if (m < 2) m = 2;
    if (m > kMaxDimPerAxis)
        failGeom(source, "resampling the uneven slices at the median gap of " + fmt(gm, 4) +
                             " mm would need " + std::to_string(m) + " slices (at most " +
                             std::to_string(kMaxDimPerAxis) + ")");
    const double dz = range / double(m - 1);
    const double umin = *std::min_element(u.begin(), u.end());
    const double umax = *std::max_element(u.begin(), u.end());
    const double vmin = *std::min_element(v.begin(), v.end());
    const double vmax = *std::max_element(v.begin(), v.end());
    const std::int64_t nx = cols + static_cast<std::int64_t>(std::ceil((umax - umin) / sx - 1e-6));
    const std::int64_t ny = rows + static_cast<std::int64_t>(std::ceil((vmax - vmin) / sy - 1e-6));
    if (nx > kMaxDimPerAxis || ny > kMaxDimPerAxis)
        failGeom(source, "the sheared stack would need " + std::to_string(nx) + " x " +
                             std::to_string(ny) + " pixels per slice (at most " +
                             std::to_string(kMaxDimPerAxis) + ")");
    const double inVoxels = double(cols) * double(rows) * double(n);
    const double outVoxels = double(nx) * double(ny) * double(m);
    if (outVoxels > std::max(16.0 * inVoxels, 64.0 * 1024 * 1024))
        failGeom(source, "resampling the " + std::to_string(n) + " slices onto a regular grid would "
                             "need " + std::to_string(nx) + " x " + std::to_string(ny) + " x " +
                             std::to_string(m) + " voxels (more than 16 times the input); refusing");
    plan.dims = {nx, ny, m};
    plan.spacing = {sx, sy, dz};
    plan.origin = add(p[0], add(scale(r, umin), scale(c, vmin)));
    plan.z0 = 0.0;
    plan.t.resize(n);
    plan.du.resize(n);
    plan.dv.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        plan.t[k] = t[k] - t[0];
        plan.du[k] = (u[k] - umin) / sx;
        plan.dv[k] = (v[k] - vmin) / sy;
    }

    if (uneven) {
        std::string msg = "uneven slice spacing along the normal: gaps " + gapSummary(gaps, gapTol) +
                          " (median " + fmt(gm, 3) + " mm)";
        // Gaps close to a multiple of the median: slices are missing there.
        int missingTotal = 0;
        std::string where;
        for (std::size_t k = 0; k + 1 < n; ++k) {
            const double ratio = gaps[k] / gm;
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
        msg += "; resampled onto " + std::to_string(m) + " slices at " + fmt(dz, 3) +
               " mm by linear interpolation between neighbouring slices";
        plan.warnings.push_back(msg);
    }
    if (sheared) {
        // Angle of the stack against the normal from a least-squares line of the offsets.
        double tm = 0, um = 0, vm = 0;
        for (std::size_t k = 0; k < n; ++k) {
            tm += t[k];
            um += u[k];
            vm += v[k];
        }
        tm /= double(n);
        um /= double(n);
        vm /= double(n);
        double stt = 0, stu = 0, stv = 0;
        for (std::size_t k = 0; k < n; ++k) {
            stt += (t[k] - tm) * (t[k] - tm);
            stu += (t[k] - tm) * (u[k] - um);
            stv += (t[k] - tm) * (v[k] - vm);
        }
        const double angle = stt > 0 ? std::atan(std::hypot(stu / stt, stv / stt)) * 180.0 / kPi : 0.0;
        std::string msg = "gantry tilt / sheared stack: slice positions run at " + fmt(angle, 2) +
                          " deg to the slice normal";
        if (!slices[0].gantryTilt.empty())
            msg += " (GantryDetectorTilt (0018,1120): " + slices[0].gantryTilt + " deg)";
        msg += " (in-plane shift up to " + fmt(maxShift, 2) + " mm); resampled (de-sheared) onto an "
               "orthogonal grid of " + std::to_string(nx) + " x " + std::to_string(ny) + " x " +
               std::to_string(m) + " voxels along the image rows, columns and normal, bilinear in "
               "plane; voxels outside every slice are set to the series minimum";
        plan.warnings.push_back(msg);
    }
    return plan;
}

} // namespace fvr::core::dicom_detail
