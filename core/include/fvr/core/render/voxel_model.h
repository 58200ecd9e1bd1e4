#pragma once
/** The voxel model: what lies between the voxels (docs/dev/algorithm.md, "Voxel models").
 *  Every renderer and the spatial reference projector take one; each model is a separable 1D
 *  transfer function t(nu) per axis on the voxels' spectrum (nu in cycles per voxel):
 *   - BandLimited: t = 1 for |nu| <= 1/2, 0 beyond (the sinc interpolant; plain FVR, sharpest,
 *     rings at truncation and between coarse slices and can go negative).
 *   - Trilinear: t = sinc^2(nu) over all frequencies (the triangle's transform): the projection
 *     a trilinear DRR ray caster integrates; never negative for non-negative voxels.
 *   - BSpline: t = sinc^4(nu) * 3 / (2 + cos 2 pi nu): the cubic B-spline through the voxels
 *     (prefilter inverse times the B-spline's transform), padded with zeros.
 *  Outside the band the voxels' spectrum V is periodic with period 1 cycle per voxel (times
 *  (-1) per period along an axis of an even voxel count: the centre lies half-way between two
 *  voxels, see Spectrum), which the renderers sample from the stored spectrum. */
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace fvr::core {

enum class VoxelModel { BandLimited, Trilinear, BSpline };

/** "bandlimited", "trilinear", "bspline". */
const char* voxelModelName(VoxelModel m);
/** A short label for overlays and tables: "band-limited", "trilinear", "cubic B-spline". */
const char* voxelModelLabel(VoxelModel m);
/** Inverse of voxelModelName (also "band-limited", "sinc", "linear", "b-spline", "cubic");
 *  throws SettingsError naming the accepted names. */
VoxelModel parseVoxelModel(const std::string& name);
const std::array<VoxelModel, 3>& allVoxelModels();

/** How far (voxels) beyond the outermost voxel centres the model reaches: 1 for trilinear
 *  (exactly: its projection is 0 outside); 6 for the B-spline (its interpolant of the zeros
 *  around the volume rings on, decaying by |sqrt(3) - 2| = 0.268 per voxel: below 0.02 % of the
 *  last voxel beyond 6); 1.5 for band-limited (the sinc never ends: the clip keeps a voxel and a
 *  half). The clip to the volume (RenderParams::clipToVolume) uses it. */
double voxelModelReach(VoxelModel m);

/** The model's 1D transfer function t(nu) (1 at nu = 0, even). */
double voxelModelTransfer(VoxelModel m, double nu);
/** d t / d nu (depth cueing differentiates the model's spectrum). 0 for BandLimited. */
double voxelModelTransferDerivative(VoxelModel m, double nu);

/** The product T = prod_a t(nu_a) along a row of slice samples, nu_a = nu0[a] + j dnu[a] for
 *  j = 0..count-1, into out (not BandLimited). Float arithmetic without tables (sin(pi r)/(pi r)
 *  as a polynomial on the reduced argument r in [-1/2, 1/2], error below 1e-7), written so the
 *  compiler vectorises it: the CPU renderer's per-row product. */
void voxelModelTransferRow(VoxelModel m, const float nu0[3], const float dnu[3], int count,
                           float* out);

/** The transfer function of a square pixel's area along one image axis, sinc(f) at f cycles per
 *  pixel (the box of one pixel width): RenderParams::pixelAperture. */
double pixelApertureResponse(double cyclesPerPixel);

/**
 * t and dt/dnu tabulated for the CPU renderer's per-sample product (3 lookups instead of 3 sines):
 * kPerUnit intervals per cycle per voxel with linear interpolation (error below 1e-6 of t's
 * peak), covering |nu| <= the largest frequency asked for so far (grown on demand; beyond the
 * table the functions are evaluated directly). Not for BandLimited.
 */
class TransferTable {
public:
    static constexpr int kPerUnit = 1024;
    /** The highest frequency a table covers (16 MiB of tables): validateImageGeometry keeps
     *  every image's slice within it, so that no pixel size can make the table grow without
     *  bound (a pixel of 1e-6 mm once asked for 9 GB). */
    static constexpr double kMaxCyclesPerVoxel = 2048.0;
    explicit TransferTable(VoxelModel m, double maxNu = 2.0);

    VoxelModel model() const { return m_model; }
    /** Makes the table cover |nu| <= maxNu (not thread-safe: call before sampling). Throws
     *  SettingsError beyond kMaxCyclesPerVoxel (with a rounding margin) or for a non-finite
     *  maxNu, before allocating. */
    void cover(double maxNu);
    float value(double nu) const { return lookup(m_value, nu, false); }
    float derivative(double nu) const { return lookup(m_derivative, nu, true); }
    /** value() without the range check: |nu| must lie within what cover() was given (the
     *  renderers' per-sample path; cover() is called with the frame's largest frequency). */
    float valueCovered(float nu) const {
        const float pos = std::abs(nu) * float(kPerUnit);
        const int i = int(pos);
        const float f = pos - float(i);
        const float* t = m_value.data() + i;
        return t[0] + f * (t[1] - t[0]);
    }

private:
    float lookup(const std::vector<float>& t, double nu, bool odd) const {
        const double a = nu < 0 ? -nu : nu;
        const double pos = a * kPerUnit;
        const std::size_t i = std::size_t(pos);
        if (i + 1 >= t.size()) {
            const double v =
                odd ? voxelModelTransferDerivative(m_model, a) : voxelModelTransfer(m_model, a);
            return float(odd && nu < 0 ? -v : v);
        }
        const float f = float(pos - double(i));
        const float v = t[i] + f * (t[i + 1] - t[i]);
        return odd && nu < 0 ? -v : v;
    }

    VoxelModel m_model;
    std::vector<float> m_value, m_derivative;
};

} // namespace fvr::core
