#include <fvr/core/xray/xray.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include <fvr/core/errors.h>

namespace fvr::core {

double waterAttenuationPerMm(double keV) {
    // NIST XCOM, water: energy (keV), mu/rho (cm^2/g) total with coherent scattering.
    static constexpr std::array<std::array<double, 2>, 8> table{{{20, 0.8096},
                                                                 {30, 0.3756},
                                                                 {40, 0.2683},
                                                                 {50, 0.2269},
                                                                 {60, 0.2059},
                                                                 {80, 0.1837},
                                                                 {100, 0.1707},
                                                                 {150, 0.1505}}};
    if (!(keV >= table.front()[0] && keV <= table.back()[0]))
        throw SettingsError("photon energy: expected 20..150 keV, found " + std::to_string(keV));
    std::size_t i = 0;
    while (i + 2 < table.size() && keV > table[i + 1][0]) ++i;
    const double x0 = std::log(table[i][0]), x1 = std::log(table[i + 1][0]);
    const double y0 = std::log(table[i][1]), y1 = std::log(table[i + 1][1]);
    const double y = y0 + (y1 - y0) * (std::log(keV) - x0) / (x1 - x0);
    return std::exp(y) / 10.0; // cm^-1 at 1 g/cm^3 -> mm^-1
}

// A negative line integral (what is left of ringing where nothing attenuates) would transmit
// more than the beam: the physics clamps the path at 0 (the signal is at most the exposure).
double Transmission::intensity(double lineIntegral) const {
    return exposure * std::exp(-muWaterPerMm * std::max(0.0, lineIntegral));
}

double Transmission::logExposure(double lineIntegral) const {
    return std::min(0.0, std::log10(exposure) -
                             muWaterPerMm * std::max(0.0, lineIntegral) / std::numbers::ln10);
}

void applyLogExposure(std::vector<float>& pixels, const Transmission& t) {
    if (!t.active() || !(t.exposure > 0.0))
        throw SettingsError("log exposure: needs an active transmission");
    for (float& v : pixels) v = float(t.logExposure(double(v)));
}

void applyTransmission(std::vector<float>& pixels, const Transmission& t) {
    if (!(t.muWaterPerMm > 0.0 && t.muWaterPerMm < 10.0))
        throw SettingsError("transmission: mu_water must be in (0, 10) per mm, found " +
                            std::to_string(t.muWaterPerMm));
    if (!(t.exposure > 0.0 && std::isfinite(t.exposure)))
        throw SettingsError("transmission: exposure must be positive, found " +
                            std::to_string(t.exposure));
    for (float& v : pixels) v = float(t.intensity(double(v)));
}

DepthCueWeights depthCueWeights(double strength, const Dims3& dims, const Vec3& spacing) {
    if (!(strength >= 0.0 && strength <= 1.0))
        throw SettingsError("depth cueing: strength must be in [0, 1], found " +
                            std::to_string(strength));
    double d2 = 0.0;
    for (int a = 0; a < 3; ++a) d2 += std::pow(double(dims[a]) * spacing[a], 2);
    DepthCueWeights w;
    w.radiusMm = 0.5 * std::sqrt(d2);
    if (w.radiusMm <= 0.0) return w;
    // w(t) = 1 - strength (t + R) / (2R)
    w.a = 1.0 - strength / 2.0;
    w.b = -strength / (2.0 * w.radiusMm);
    return w;
}

double SliceFilter::blur(double nu) const {
    return std::exp(-2.0 * std::numbers::pi * std::numbers::pi * sharpenSigmaMm * sharpenSigmaMm *
                    nu * nu);
}

double SliceFilter::response(double nu) const {
    const double q = bandLimitLpMm > 0.0 ? (nu * nu) / (bandLimitLpMm * bandLimitLpMm) : 0.0;
    return sliceFilterGain(sharpenAmount, sharpenAmount > 0.0 ? blur(nu) : 1.0, q);
}

void validateSliceFilter(const SliceFilter& f) {
    if (!(f.sharpenAmount >= 0.0 && f.sharpenAmount <= 20.0))
        throw SettingsError("edge enhancement: amount must be in [0, 20], found " +
                            std::to_string(f.sharpenAmount));
    if (!(f.sharpenSigmaMm > 0.0 && f.sharpenSigmaMm <= 100.0))
        throw SettingsError("edge enhancement: radius must be in (0, 100] mm, found " +
                            std::to_string(f.sharpenSigmaMm));
    if (!(f.bandLimitLpMm >= 0.0 && std::isfinite(f.bandLimitLpMm)))
        throw SettingsError("band limit: cutoff must be >= 0 lp/mm, found " +
                            std::to_string(f.bandLimitLpMm));
}

} // namespace fvr::core
