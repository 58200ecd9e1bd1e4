#include <fvr/core/voxel_model.h>

#include <cmath>
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
    if (name == "bandlimited" || name == "band-limited" || name == "sinc") return VoxelModel::BandLimited;
    if (name == "trilinear" || name == "linear") return VoxelModel::Trilinear;
    if (name == "bspline" || name == "b-spline" || name == "cubic") return VoxelModel::BSpline;
    throw SettingsError("voxel model: expected bandlimited|trilinear|bspline, found '" + name + "'");
}

const std::array<VoxelModel, 3>& allVoxelModels() {
    static const std::array<VoxelModel, 3> all{VoxelModel::BandLimited, VoxelModel::Trilinear, VoxelModel::BSpline};
    return all;
}

double voxelModelReach(VoxelModel m) {
    switch (m) {
    case VoxelModel::BandLimited: return 1.5;
    case VoxelModel::Trilinear: return 1.0;
    case VoxelModel::BSpline: return 3.0;
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

TransferTable::TransferTable(VoxelModel m, double maxNu) : m_model(m) {
    if (m == VoxelModel::BandLimited) throw SettingsError("transfer table: the band-limited model has none");
    cover(maxNu);
}

void TransferTable::cover(double maxNu) {
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
