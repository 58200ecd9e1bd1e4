#pragma once
/** X-ray image formation beyond the paper: CT values to attenuation (plain and bone-enhanced),
 *  Beer-Lambert transmission with an exposure, depth cueing (Totsuka and Levoy 1993) and the
 *  spectral filters that act on the 2D slice before the inverse transform. The renderers, the
 *  spatial reference projector, the analytic phantom and the display all use these definitions. */
#include <cmath>
#include <vector>

#include <fvr/core/render/spectrum.h>
#include <fvr/core/volume.h>

namespace fvr::core {

// ---- Attenuation ------------------------------------------------------------------------------

/** Bone-enhanced mapping (ValueMapping::MuBone): the water line mu/mu_water = 1 + HU/1000 up to
 *  kBoneThresholdHu, kBoneGain times steeper above, so bone (and iodine) stand out as on a
 *  low-kV radiograph. */
constexpr double kBoneThresholdHu = 100.0;
constexpr double kBoneGain = 2.0;

/** The value the transform integrates for a stored value v: v itself (Raw), max(0, 1 + v/1000)
 *  (Mu), or the bone-enhanced piecewise-linear curve, clipped at 0 (MuBone). v is in HU for the
 *  mu mappings. */
inline float mapValue(ValueMapping m, float v) {
    switch (m) {
    case ValueMapping::Raw: return v;
    case ValueMapping::Mu: return v > -1000.0f ? 1.0f + v / 1000.0f : 0.0f;
    case ValueMapping::MuBone: {
        if (v <= -1000.0f) return 0.0f;
        constexpr float t = float(kBoneThresholdHu), g = float(kBoneGain);
        return v <= t ? 1.0f + v / 1000.0f : 1.0f + t / 1000.0f + g * (v - t) / 1000.0f;
    }
    }
    return v;
}
/** Whether the mapping yields attenuation relative to water (line integrals in mm of water). */
inline bool isAttenuation(ValueMapping m) { return m != ValueMapping::Raw; }

// ---- Beer-Lambert -----------------------------------------------------------------------------

/** Linear attenuation coefficient of water (1/mm) at a photon energy in keV (20..150),
 *  log-log interpolated in the NIST XCOM table (total attenuation with coherent scattering,
 *  density 1 g/cm^3): 0.02683 at 40 keV, 0.02059 at 60, 0.01837 at 80, 0.01707 at 100.
 *  Throws SettingsError outside 20..150 keV. */
double waterAttenuationPerMm(double keV);

/** Beer-Lambert: the detector signal exposure * exp(-muWater * max(0, L)) for a line integral L
 *  in mm of water (mu/mu_water x mm); exposure 1 is the unattenuated beam at full scale, which no
 *  pixel exceeds (a negative L, left by ringing, is no path at all).
 *  The display shows it as film does: blackening follows the log exposure (the straight part of
 *  the film's characteristic curve) and saturates at full scale, so the window applies to
 *  logExposure() = min(0, log10(signal)); more exposure darkens, a higher energy flattens. */
struct Transmission {
    double muWaterPerMm = 0.0; ///< 0: no transmission (the display shows line integrals)
    double exposure = 1.0;

    bool active() const { return muWaterPerMm > 0.0; }
    double intensity(double lineIntegral) const;
    /** min(0, log10(intensity)), computed without underflow for thick paths. */
    double logExposure(double lineIntegral) const;
};
/** Replaces line integrals by transmitted intensities, in place. Throws SettingsError for a
 *  non-positive mu or exposure. */
void applyTransmission(std::vector<float>& pixels, const Transmission& t);
/** Replaces line integrals by the log exposure the display windows (see Transmission). */
void applyLogExposure(std::vector<float>& pixels, const Transmission& t);

// ---- Depth cueing -----------------------------------------------------------------------------

/** w(t) = a + b t for the depth t (mm) along the view direction, measured from the volume's
 *  centre: 1 at the front of the volume's bounding sphere (t = -R, R half the volume diagonal),
 *  1 - strength at its back (t = +R). strength in [0, 1]; 0 is no depth cueing. */
struct DepthCueWeights {
    double a = 1.0;
    double b = 0.0;
    double radiusMm = 0.0;
};
/** Throws SettingsError for strength outside [0, 1]. */
DepthCueWeights depthCueWeights(double strength, const Dims3& dims, const Vec3& spacing);

// ---- Spectral filters on the 2D slice ---------------------------------------------------------

/**
 * A real, radially symmetric filter multiplied into the central slice before the inverse
 * transform (free per frame; the same for the FFT and the FHT path):
 *   H(nu) = (1 + a (1 - exp(-2 pi^2 sigma^2 nu^2))) / sqrt(1 + (nu / nu_c)^16)
 * for the spatial frequency nu (cycles per mm, |(m, n)| / (M d)): an unsharp mask (image plus a
 * times image minus its Gaussian blur of sigma mm) and an order-8 Butterworth band limit at
 * nu_c line pairs per mm (-3 dB there).
 */
struct SliceFilter {
    double sharpenAmount = 0.0; ///< a >= 0; 0: no unsharp mask
    double sharpenSigmaMm = 1.0; ///< sigma > 0
    double bandLimitLpMm = 0.0; ///< nu_c > 0; 0: no band limit

    bool active() const { return sharpenAmount > 0.0 || bandLimitLpMm > 0.0; }
    /** H(nu): sliceFilterGain(a, blur(nu), (nu / nu_c)^2). */
    double response(double nuPerMm) const;
    /** The Gaussian blur's transfer function exp(-2 pi^2 sigma^2 nu^2), separable:
     *  blur(|(nu_x, nu_y)|) = blur(nu_x) blur(nu_y). */
    double blur(double nuPerMm) const;
    bool operator==(const SliceFilter&) const = default;
};

/** The slice filter from its parts, the one formula every evaluation uses (the filter's
 *  response in double, the renderers' per-sample float tables in SliceFilterTable):
 *  (1 + a (1 - blur)) / sqrt(1 + q^8) for the unsharp mask's amount a (0: none), the blur's
 *  transfer value and q = (nu / nu_c)^2 (0: no band limit). The GPU's slice.glsl
 *  (filterResponse) repeats this expression in GLSL: keep the two alike (the GPU tests compare
 *  the filtered renders with the CPU's). */
template <class T>
inline T sliceFilterGain(T amount, T blur, T q) {
    T h = T(1);
    if (amount > T(0)) h *= T(1) + amount * (T(1) - blur);
    if (q > T(0)) {
        const T q2 = q * q, q4 = q2 * q2;
        h /= std::sqrt(T(1) + q4 * q4);
    }
    return h;
}
/** Throws SettingsError naming the bad parameter. */
void validateSliceFilter(const SliceFilter& f);

} // namespace fvr::core
