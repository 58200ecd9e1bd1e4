#include <fvr/core/render/voxel_model.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include <fvr/core/errors.h>

namespace fvr::core {

const char* voxelModelName(VoxelModel m) {
    switch (m) {
    case VoxelModel::BandLimited: return "bandlimited";
    case VoxelModel::Trilinear: return "trilinear";
    case VoxelModel::BSpline: return "bspline";
    }
    return "?";
}

const char* voxelModelLabel(VoxelModel m) {
    switch (m) {
    case VoxelModel::BandLimited: return "band-limited";
    case VoxelModel::Trilinear: return "trilinear";
    case VoxelModel::BSpline: return "cubic B-spline";
    }
    return "?";
}

VoxelModel parseVoxelModel(const std::string& name) {
    if (name == "bandlimited" || name == "band-limited" || name == "sinc")
        return VoxelModel::BandLimited;
    if (name == "trilinear" || name == "linear") return VoxelModel::Trilinear;
    if (name == "bspline" || name == "b-spline" || name == "cubic") return VoxelModel::BSpline;
    throw SettingsError("voxel model: expected bandlimited|trilinear|bspline, found '" + name +
                        "'");
}

const std::array<VoxelModel, 3>& allVoxelModels() {
    static const std::array<VoxelModel, 3> all{VoxelModel::BandLimited, VoxelModel::Trilinear,
                                               VoxelModel::BSpline};
    return all;
}

double voxelModelReach(VoxelModel m) {
    switch (m) {
    case VoxelModel::BandLimited: return 1.5;
    case VoxelModel::Trilinear: return 1.0;
    case VoxelModel::BSpline: return 6.0;
    }
    return 1.5;
}

namespace {

/** sinc(nu) = sin(pi nu) / (pi nu) and its derivative (series near 0). */
void sincAndDerivative(double nu, double& s, double& ds) {
    constexpr double pi = std::numbers::pi;
    const double x = pi * nu;
    if (std::abs(x) < 1e-3) {
        const double x2 = x * x;
        s = 1.0 - x2 / 6.0 + x2 * x2 / 120.0;
        ds = pi * (-x / 3.0 + x * x2 / 30.0);
        return;
    }
    s = std::sin(x) / x;
    ds = (std::cos(x) - s) / nu;
}

} // namespace

double voxelModelTransfer(VoxelModel m, double nu) {
    double s, ds;
    switch (m) {
    case VoxelModel::BandLimited: return std::abs(nu) <= 0.5 ? 1.0 : 0.0;
    case VoxelModel::Trilinear: sincAndDerivative(nu, s, ds); return s * s;
    case VoxelModel::BSpline:
        sincAndDerivative(nu, s, ds);
        return s * s * s * s * 3.0 / (2.0 + std::cos(2.0 * std::numbers::pi * nu));
    }
    return 0.0;
}

double voxelModelTransferDerivative(VoxelModel m, double nu) {
    double s, ds;
    switch (m) {
    case VoxelModel::BandLimited: return 0.0;
    case VoxelModel::Trilinear: sincAndDerivative(nu, s, ds); return 2.0 * s * ds;
    case VoxelModel::BSpline: {
        sincAndDerivative(nu, s, ds);
        const double w = 2.0 * std::numbers::pi * nu;
        const double den = 2.0 + std::cos(w);
        const double g = 3.0 / den;
        const double dg = 3.0 * 2.0 * std::numbers::pi * std::sin(w) / (den * den);
        return 4.0 * s * s * s * ds * g + s * s * s * s * dg;
    }
    }
    return 0.0;
}

double pixelApertureResponse(double f) {
    double s, ds;
    sincAndDerivative(f, s, ds);
    return s;
}

namespace {

/** sinc^2(nu) in float for nu >= 0: with nu = n + r, |r| <= 1/2, sin(pi nu) = (-1)^n sin(pi r),
 *  so sinc(nu) = s(r) r / nu with s(r) = sin(pi r) / (pi r) (Taylor to r^12: error < 4e-8),
 *  and r / nu = 1 for n = 0. Also sin^2(pi nu) = (pi r s)^2 for the B-spline's prefilter term. */
inline float sinc2Float(float nu, float& sin2) {
    constexpr float pi = std::numbers::pi_v<float>;
    const float n = float(int(nu + 0.5f));
    const float r = nu - n;
    const float x2 = pi * pi * r * r;
    const float s =
        1.0f + x2 * (-1.0f / 6.0f +
                     x2 * (1.0f / 120.0f +
                           x2 * (-1.0f / 5040.0f +
                                 x2 * (1.0f / 362880.0f +
                                       x2 * (-1.0f / 39916800.0f + x2 * (1.0f / 6227020800.0f))))));
    // r / nu without a branch (so the row loops vectorise): exactly 1 for n = 0 (r = nu, also at
    // nu = 0), r / nu to float precision otherwise (nu >= 1/2).
    constexpr float tiny = 1e-30f;
    const float q = (r + tiny) / (nu + tiny);
    sin2 = x2 * s * s;
    const float sinc = s * q;
    return sinc * sinc;
}

} // namespace

// Also compiled for x86-64-v3 (8 floats per AVX register, multiply-adds fused: the values to float
// rounding), chosen at load time (an ifunc) where the CPU has it.
#if defined __x86_64__ && defined __GNUC__ && !defined __clang__
__attribute__((target_clones("arch=x86-64-v3", "default")))
#endif
void voxelModelTransferRow(VoxelModel m, const float nu0[3], const float dnu[3], int count,
                           float* out) {
    const float a0 = nu0[0], a1 = nu0[1], a2 = nu0[2], d0 = dnu[0], d1 = dnu[1], d2 = dnu[2];
    if (m == VoxelModel::Trilinear) {
        for (int j = 0; j < count; ++j) {
            float s0, s1, s2;
            const float fj = float(j);
            out[j] = sinc2Float(std::abs(a0 + fj * d0), s0) *
                     sinc2Float(std::abs(a1 + fj * d1), s1) *
                     sinc2Float(std::abs(a2 + fj * d2), s2);
        }
    } else if (m == VoxelModel::BSpline) {
        // sinc^4 * 3 / (2 + cos 2 pi nu) = sinc^4 * 3 / (3 - 2 sin^2 pi nu)
        for (int j = 0; j < count; ++j) {
            float s0, s1, s2;
            const float fj = float(j);
            const float t0 = sinc2Float(std::abs(a0 + fj * d0), s0);
            const float t1 = sinc2Float(std::abs(a1 + fj * d1), s1);
            const float t2 = sinc2Float(std::abs(a2 + fj * d2), s2);
            out[j] = (t0 * t0) * (t1 * t1) * (t2 * t2) * 27.0f /
                     ((3.0f - 2.0f * s0) * (3.0f - 2.0f * s1) * (3.0f - 2.0f * s2));
        }
    } else {
        throw SettingsError("transfer row: the band-limited model has none");
    }
}

TransferTable::TransferTable(VoxelModel m, double maxNu) : m_model(m) {
    if (m == VoxelModel::BandLimited)
        throw SettingsError("transfer table: the band-limited model has none");
    cover(maxNu);
}

void TransferTable::cover(double maxNu) {
    // The hard cap whatever the caller checked (validateImageGeometry keeps images within
    // kMaxCyclesPerVoxel; the margin absorbs the slice parameters' rounding).
    if (!(std::abs(maxNu) <= kMaxCyclesPerVoxel * 1.001)) {
        char msg[256];
        std::snprintf(msg, sizeof msg,
                      "voxel model table: the slice reaches %g cycles per voxel, beyond the %g "
                      "it covers (the pixel size is far smaller than the voxels)",
                      maxNu, kMaxCyclesPerVoxel);
        throw SettingsError(msg);
    }
    const std::size_t n = std::size_t(std::ceil(std::abs(maxNu) * kPerUnit)) + 2;
    if (n <= m_value.size()) return;
    m_value.resize(n);
    m_derivative.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double nu = double(i) / kPerUnit;
        m_value[i] = float(voxelModelTransfer(m_model, nu));
        m_derivative[i] = float(voxelModelTransferDerivative(m_model, nu));
    }
}

} // namespace fvr::core
