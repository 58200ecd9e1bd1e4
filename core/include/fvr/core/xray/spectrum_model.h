#pragma once
/** Polychromatic X-ray physics, part 1: the tube spectrum (TASMIP), filtration, mass attenuation
 *  of NIST compounds (xraylib), air kerma (NIST mu_en/rho of air) and the half-value layer. */
#include <string>
#include <vector>

namespace fvr::core {

/** TASMIP's range of tube voltages (Boone and Seibert 1997). */
constexpr double kTasmipMinKv = 30.0;
constexpr double kTasmipMaxKv = 140.0;

/** Densities (g/cm^3) of the filter and detector materials. */
constexpr double kAluminiumDensity = 2.699;
constexpr double kCopperDensity = 8.96;
constexpr double kCsIDensity = 4.51;

/** A spectrum in bins: fluence[i] photons per mm^2 per mAs at 1 m in the bin centred at keV[i]
 *  (1-keV bins for tube spectra). */
struct TubeSpectrum {
    double kvp = 0.0;
    double filtrationAlMm = 0.0;
    double filtrationCuMm = 0.0;
    std::vector<double> keV;
    std::vector<double> fluence;

    std::size_t bins() const { return keV.size(); }
    double totalFluence() const;
    /** Fluence-weighted mean energy (keV). */
    double meanEnergy() const;
};

/** The unfiltered TASMIP spectrum at kvp (30..140 kV, any real value): 1-keV bins centred at
 *  9..floor(kvp) keV (a bin counts when it starts at or below kvp), fluence per bin
 *  a0 + a1 V + a2 V^2 + a3 V^3 clamped at 0, with the published coefficients
 *  (src/xray/tasmip_table.h). Throws SettingsError outside 30..140 kV. */
TubeSpectrum tasmipSpectrum(double kvp);

/** The spectrum through a slab of a NIST compound (xraylib name) of density rho (g/cm^3) and
 *  thickness mm: fluence x exp(-(mu/rho)(E) rho t). */
TubeSpectrum filtered(const TubeSpectrum& s, const std::string& nistName, double density,
                      double thicknessMm);

/** TASMIP at kvp with added aluminium and copper filtration (mm). SettingsError for negative
 *  thicknesses or a voltage outside 30..140 kV. */
TubeSpectrum tubeSpectrum(double kvp, double filtrationAlMm = 0.0, double filtrationCuMm = 0.0);

/** One bin of unit fluence at keV (the monoenergetic limit). */
TubeSpectrum monoenergeticSpectrum(double keV);

/** Mass attenuation coefficient (cm^2/g, coherent scattering included) of a NIST compound
 *  (xraylib's spelling, e.g. "Tissue, Soft (ICRP)") or of an element symbol ("Al", "Cu", ...)
 *  at keV: xraylib's CS_Total_CP. Throws SettingsError naming the compound when xraylib does
 *  not know it. */
double massAttenuation(const std::string& compound, double keV);
/** massAttenuation for each of the energies. */
std::vector<double> massAttenuation(const std::string& compound, const std::vector<double>& keV);

/** Mass energy-absorption coefficient mu_en/rho (cm^2/g) of dry air at keV (8..200), log-log
 *  interpolated in NIST's table (Hubbell and Seltzer, NISTIR 5632, Table 4, "Air, Dry (near sea
 *  level)"). Not xraylib's mu_en, which differs from NIST by tens of percent at 20 keV. */
double airMassEnergyAbsorption(double keV);

/** Air kerma (uGy per mAs at 1 m) of a spectrum: sum of fluence x E x (mu_en/rho)_air. */
double airKerma(const TubeSpectrum& s);

/** The added aluminium (mm) that brings the air kerma down to `fraction` (0..1) of its value
 *  (bisection to 1e-6 mm). */
double aluminiumForKermaFractionMm(const TubeSpectrum& s, double fraction);

/** First half-value layer in mm of aluminium: the added Al that halves the air kerma. */
double halfValueLayerAlMm(const TubeSpectrum& s);

/** Second half-value layer (mm Al): the further Al from 1/2 to 1/4 of the air kerma. The
 *  homogeneity coefficient of IEC 61267 is h = HVL1 / HVL2. */
double secondHalfValueLayerAlMm(const TubeSpectrum& s);

} // namespace fvr::core
