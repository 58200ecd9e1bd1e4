#include <fvr/core/xray/spectrum_model.h>

#include <xraylib.h>

#include <array>
#include <cmath>
#include <map>
#include <mutex>
#include <string>

#include <fvr/core/errors.h>

#include "tasmip_table.h"

namespace fvr::core {

double TubeSpectrum::totalFluence() const {
    double sum = 0.0;
    for (double f : fluence) sum += f;
    return sum;
}

double TubeSpectrum::meanEnergy() const {
    double sum = 0.0, weighted = 0.0;
    for (std::size_t i = 0; i < bins(); ++i) {
        sum += fluence[i];
        weighted += fluence[i] * keV[i];
    }
    return sum > 0.0 ? weighted / sum : 0.0;
}

TubeSpectrum tasmipSpectrum(double kvp) {
    if (!(kvp >= kTasmipMinKv && kvp <= kTasmipMaxKv))
        throw SettingsError("tube voltage: expected 30..140 kV (TASMIP), found " +
                            std::to_string(kvp));
    TubeSpectrum s;
    s.kvp = kvp;
    for (int e = detail::kTasmipFirstKeV; e <= detail::kTasmipLastKeV; ++e) {
        if (e - 0.5 > kvp) break;
        const auto& a = detail::kTasmip[e - detail::kTasmipFirstKeV];
        const double f = a[0] + kvp * (a[1] + kvp * (a[2] + kvp * a[3]));
        s.keV.push_back(double(e));
        s.fluence.push_back(std::max(0.0, f));
    }
    return s;
}

namespace {

/** CS_Total_CP without its leak: for a NIST compound name, CS_Total_CP first tries the name as a
 *  chemical formula, and that failed parse leaks 8 bytes per call in xraylib 4.1 (LeakSanitizer
 *  failed every polychromatic test). The NIST compound first, then the formula: the same sum
 *  of CS_Total weighted by mass fractions that CS_Total_CP computes. */
double totalCrossSection(const std::string& compound, double keV, xrl_error** error) {
    compoundDataNIST* nist = GetCompoundDataNISTByName(compound.c_str(), nullptr);
    if (!nist) {
        // Nor can a name with other characters be a formula (its parse would leak too).
        if (compound.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                       "0123456789().") != std::string::npos) {
            throw SettingsError("material \"" + compound +
                                "\": not a NIST compound of xraylib nor a chemical formula");
        }
        return CS_Total_CP(compound.c_str(), keV, error);
    }
    double mu = 0.0;
    for (int i = 0; i < nist->nElements && !*error; ++i)
        mu += CS_Total(nist->Elements[i], keV, error) * nist->massFractions[i];
    FreeCompoundDataNIST(nist);
    return mu;
}

} // namespace

double massAttenuation(const std::string& compound, double keV) {
    // CS_Total_CP is pure but costs a parse per call: cache per (compound, energy).
    static std::mutex mutex;
    static std::map<std::pair<std::string, double>, double> cache;
    const std::lock_guard lock(mutex);
    const auto key = std::make_pair(compound, keV);
    if (auto it = cache.find(key); it != cache.end()) return it->second;
    xrl_error* error = nullptr;
    const double mu = totalCrossSection(compound, keV, &error);
    if (error) {
        const std::string message = error->message ? error->message : "unknown error";
        xrl_error_free(error);
        throw SettingsError("material \"" + compound + "\" at " + std::to_string(keV) +
                            " keV: xraylib: " + message);
    }
    cache.emplace(key, mu);
    return mu;
}

std::vector<double> massAttenuation(const std::string& compound, const std::vector<double>& keV) {
    std::vector<double> mu(keV.size());
    for (std::size_t i = 0; i < keV.size(); ++i) mu[i] = massAttenuation(compound, keV[i]);
    return mu;
}

TubeSpectrum filtered(const TubeSpectrum& s, const std::string& nistName, double density,
                      double thicknessMm) {
    if (!(thicknessMm >= 0.0))
        throw SettingsError("filtration of " + nistName + ": expected >= 0 mm, found " +
                            std::to_string(thicknessMm));
    TubeSpectrum out = s;
    if (thicknessMm == 0.0) return out;
    const double rhoT = density * thicknessMm / 10.0; // g/cm^2
    for (std::size_t i = 0; i < s.bins(); ++i)
        out.fluence[i] *= std::exp(-massAttenuation(nistName, s.keV[i]) * rhoT);
    return out;
}

TubeSpectrum tubeSpectrum(double kvp, double filtrationAlMm, double filtrationCuMm) {
    TubeSpectrum s = tasmipSpectrum(kvp);
    s = filtered(s, "Al", kAluminiumDensity, filtrationAlMm);
    s = filtered(s, "Cu", kCopperDensity, filtrationCuMm);
    s.filtrationAlMm = filtrationAlMm;
    s.filtrationCuMm = filtrationCuMm;
    return s;
}

TubeSpectrum monoenergeticSpectrum(double keV) {
    if (!(keV >= 1.0 && keV <= 1000.0))
        throw SettingsError("photon energy: expected 1..1000 keV, found " + std::to_string(keV));
    TubeSpectrum s;
    s.kvp = keV;
    s.keV = {keV};
    s.fluence = {1.0};
    return s;
}

double airMassEnergyAbsorption(double keV) {
    // NIST X-Ray Mass Attenuation Coefficients (J. H. Hubbell and S. M. Seltzer, NISTIR 5632,
    // physics.nist.gov/PhysRefData/XrayMassCoef), Table 4, "Air, Dry (near sea level)":
    // energy (MeV), mu_en/rho (cm^2/g).
    static constexpr std::array<std::array<double, 2>, 14> table{{{8.0e-03, 9.446e+00},
                                                                  {1.0e-02, 4.742e+00},
                                                                  {1.5e-02, 1.334e+00},
                                                                  {2.0e-02, 5.389e-01},
                                                                  {3.0e-02, 1.537e-01},
                                                                  {4.0e-02, 6.833e-02},
                                                                  {5.0e-02, 4.098e-02},
                                                                  {6.0e-02, 3.041e-02},
                                                                  {8.0e-02, 2.407e-02},
                                                                  {1.0e-01, 2.325e-02},
                                                                  {1.5e-01, 2.496e-02},
                                                                  {2.0e-01, 2.672e-02},
                                                                  {3.0e-01, 2.872e-02},
                                                                  {4.0e-01, 2.949e-02}}};
    const double mev = keV / 1000.0;
    if (!(mev >= table.front()[0] && mev <= table.back()[0]))
        throw SettingsError("air mu_en/rho: expected 8..400 keV, found " + std::to_string(keV));
    std::size_t i = 0;
    while (i + 2 < table.size() && mev > table[i + 1][0]) ++i;
    const double x0 = std::log(table[i][0]), x1 = std::log(table[i + 1][0]);
    const double y0 = std::log(table[i][1]), y1 = std::log(table[i + 1][1]);
    return std::exp(y0 + (y1 - y0) * (std::log(mev) - x0) / (x1 - x0));
}

double airKerma(const TubeSpectrum& s) {
    // K = sum phi(E) E (mu_en/rho)(E): photons/mm^2 x keV x cm^2/g. 1 keV = 1.602176634e-16 J,
    // 1/mm^2 = 100/cm^2, 1 cm^2/g = 1e-1 m^2/kg... in Gy: phi[1/mm^2] * 100 [mm^2/cm^2]
    // * E[keV] * 1.602176634e-16 [J/keV] * mu_en/rho [cm^2/g] * 1000 [g/kg]; reported in uGy.
    constexpr double kevToJ = 1.602176634e-16;
    double sum = 0.0;
    for (std::size_t i = 0; i < s.bins(); ++i)
        sum += s.fluence[i] * s.keV[i] * airMassEnergyAbsorption(s.keV[i]);
    return sum * 100.0 * kevToJ * 1000.0 * 1e6;
}

double aluminiumForKermaFractionMm(const TubeSpectrum& s, double fraction) {
    if (!(fraction > 0.0 && fraction < 1.0))
        throw SettingsError("half-value layer: the kerma fraction must lie in (0, 1)");
    const double k0 = airKerma(s);
    if (!(k0 > 0.0)) throw SettingsError("half-value layer: the spectrum has no air kerma");
    std::vector<double> muAl = massAttenuation("Al", s.keV);
    auto kerma = [&](double mm) {
        double sum = 0.0;
        for (std::size_t i = 0; i < s.bins(); ++i)
            sum += s.fluence[i] * s.keV[i] * airMassEnergyAbsorption(s.keV[i]) *
                   std::exp(-muAl[i] * kAluminiumDensity * mm / 10.0);
        return sum;
    };
    const double target = fraction * kerma(0.0);
    double lo = 0.0, hi = 1.0;
    while (kerma(hi) > target) hi *= 2.0;
    while (hi - lo > 1e-6) {
        const double mid = 0.5 * (lo + hi);
        (kerma(mid) > target ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

double halfValueLayerAlMm(const TubeSpectrum& s) { return aluminiumForKermaFractionMm(s, 0.5); }

double secondHalfValueLayerAlMm(const TubeSpectrum& s) {
    return aluminiumForKermaFractionMm(s, 0.25) - aluminiumForKermaFractionMm(s, 0.5);
}

} // namespace fvr::core
