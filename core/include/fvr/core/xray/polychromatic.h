#pragma once
/** Polychromatic X-ray physics, part 2: materials from CT numbers, the detector, the spectral sum
 *  I/I0 = sum_E S(E) eta(E) w(E) exp(-sum_m (mu/rho)_m(E) rhoL_m) / sum_E S eta w (exact in
 *  double, and tabulated for the frames), and quantum noise. */
#include <cstdint>
#include <string>
#include <vector>

#include <fvr/core/xray/spectrum_model.h>

namespace fvr::core {

class ThreadPool;

// ---- Materials --------------------------------------------------------------------------------

/** Material classes, in the order of their CT numbers. */
enum class Material { Air, Lung, Adipose, Soft, Bone };

/** "air", "lung", "fat", "soft", "bone". */
const char* materialKey(Material m);
/** The NIST compound as xraylib spells it: "Air, Dry (near sea level)", "Lung (ICRP)",
 *  "Adipose Tissue (ICRP)", "Tissue, Soft (ICRP)", "Bone, Cortical (ICRP)". */
const char* materialNistName(Material m);
/** Parses "air,soft,bone" (any order, no repeats, 1..5 names); returns them in CT-number order.
 *  Throws SettingsError naming the bad entry. */
std::vector<Material> parseMaterials(const std::string& list);
/** The default decomposition: air, soft tissue, bone. */
std::vector<Material> defaultMaterials();

/**
 * CT number to materials (Schneider, Bortfeld and Schlegel 2000, Phys. Med. Biol. 45:459: a CT
 * number is a mixture of tissue compositions whose density follows from its attenuation):
 * - mass fractions f_m(HU): between consecutive chosen materials a smoothstep ramp
 *   (3t^2 - 2t^3) over an HU interval (air|lung -950..-850, {air,lung}|{fat,soft} -400..-200,
 *   fat|soft -80..-20, anything|bone 100..400; outside the ramps one material), so that
 *   no CT number switches material abruptly (hard thresholds alias into the spectrum);
 * - the mass density rho(HU) (g/cm^3) that gives the voxel the attenuation its CT number
 *   states at the reference energy E_ref: rho sum_m f_m (mu/rho)_m(E_ref) =
 *   (1 + HU/1000) (mu/rho)_water(E_ref), 0 at or below -1000 HU;
 * the voxel holds rho_m = f_m rho of each material.
 */
struct MaterialMapping {
    std::vector<Material> materials = defaultMaterials();
    double referenceKeV = 70.0; ///< E_ref, the CT's effective energy
};

/** Mass fractions (sum 1) at a CT number, one per mapping.materials. */
std::vector<double> materialFractions(const std::vector<Material>& materials, double hu);

/** Densities rho_m (g/cm^3) of each material at a CT number: a fast evaluator built once. */
class MaterialDecomposer {
public:
    explicit MaterialDecomposer(const MaterialMapping& mapping);
    std::size_t size() const { return m_materials.size(); }
    /** Writes size() densities. */
    void densities(double hu, double* out) const;

private:
    std::vector<Material> m_materials;
    std::vector<double> m_muRef; ///< (mu/rho)_m(E_ref)
    double m_muWaterRef = 0.0;
};

// ---- Detector ---------------------------------------------------------------------------------

enum class DetectorKind {
    EnergyIntegrating, ///< w(E) = E
    PhotonCounting ///< w(E) = 1
};

struct DetectorModel {
    DetectorKind kind = DetectorKind::EnergyIntegrating;
    /** CsI absorber thickness (um): eta(E) = 1 - exp(-(mu/rho)_CsI(E) 4.51 t); 0: ideal. */
    double csiUm = 0.0;
};

/** eta(E) of the detector at each energy. */
std::vector<double> detectorAbsorption(const DetectorModel& d, const std::vector<double>& keV);

// ---- The spectral sum -------------------------------------------------------------------------

/**
 * I/I0 for material mass thicknesses rhoL_m (g/cm^2), each clamped at >= 0 first.
 * exact() is the double sum over the bins. apply() reads a table: g = -ln(I/I0) over the mass
 * thicknesses of the last two materials (soft tissue and bone by default; one axis with one
 * material), bilinear, with linear extrapolation beyond the table's end. Every other material
 * m (air, lung, fat: low-Z, close to soft tissue) is written mu_m(E) = c_m mu_x(E) + delta_m(E)
 * (c_m by least squares over the spectrum): its c_m part joins the x axis, x' = x + sum c_m
 * rhoL_m, and its small residual enters to first order through its mean over the spectrum
 * hardened by (x', y): I = exp(-g(x', y) - sum_m deltabar_m(x', y) rhoL_m), deltabar_m
 * tabulated on the same grid.
 */
class SpectralResponse {
public:
    SpectralResponse(const TubeSpectrum& spectrum, const DetectorModel& detector,
                     const std::vector<Material>& materials);
    /** Same with explicit per-bin mass attenuation (cm^2/g) per material (tests, water). */
    SpectralResponse(const TubeSpectrum& spectrum, const DetectorModel& detector,
                     std::vector<std::vector<double>> massAttenuation);

    std::size_t materials() const { return m_mu.size(); }
    std::size_t bins() const { return m_weight.size(); }
    /** The normalised weights S eta w / sum (sum 1). */
    const std::vector<double>& weights() const { return m_weight; }
    /** sum_E S(E) eta(E): the detected photons per mm^2 per mAs at 1 m (tube spectra). */
    double detectedFluence() const { return m_detected; }
    /** Noise-equivalent quanta per detected photon: (sum S eta w)^2 / (sum S eta) (sum S eta
     *  w^2): 1 for photon counting, the Swank factor of the energy weighting otherwise. */
    double swankFactor() const { return m_swank; }

    /** I/I0 in double from rhoL[0..materials()). */
    double exact(const double* rhoL) const;
    /** I/I0 from the tables. */
    float lookup(const float* rhoL) const;
    /** What apply() writes: I/I0, or -ln(I/I0) as the table holds it (the display's quantity:
     *  no exp per pixel to take the log of again). */
    enum class Output { Transmission, NegativeLog };
    /** out[p] = lookup of (rhoL[0][p], rhoL[1][p], ...) for p < count, in parallel on pool
     *  (null: the calling thread). */
    void apply(const std::vector<const float*>& rhoL, float* out, std::int64_t count,
               ThreadPool* pool = nullptr, Output output = Output::Transmission) const;

    /** The table's size per axis and extent (g/cm^2) per axis. */
    static constexpr int kTableSize = 256;
    double tableExtent(int axis) const { return m_extent[axis]; }

    /** The table as apply() reads it (a GPU pass evaluates the same): tableRows() rows of
     *  kTableSize nodes (x fastest), tableStride() floats per node: -ln(I/I0), then deltabar of
     *  each other material. x = rhoL[axisX()] + sum_o otherScales()[o] rhoL[otherMaterials()[o]],
     *  y = rhoL[axisY()] (-1: one row); each rhoL clamped at >= 0 first. */
    const std::vector<float>& tableNodes() const { return m_nodes; }
    int tableStride() const { return int(1 + m_others.size()); }
    int tableRows() const { return m_ny; }
    int axisX() const { return m_axisX; }
    int axisY() const { return m_axisY; }
    const std::vector<int>& otherMaterials() const { return m_others; }
    const std::vector<double>& otherScales() const { return m_scale; }

private:
    void setUp(const TubeSpectrum& spectrum, const DetectorModel& detector);
    void buildTables();
    /** out[p] for p in [begin, end) from rhoL[m][p]. */
    void applyRange(const std::vector<const float*>& rhoL, float* out, std::int64_t begin,
                    std::int64_t end, Output output) const;
    double exactLog(double x, double y, std::vector<double>* muBar) const;

    std::vector<double> m_weight;
    std::vector<std::vector<double>> m_mu; ///< per material, per bin
    double m_detected = 0.0;
    double m_swank = 1.0;
    int m_axisX = -1, m_axisY = -1; ///< materials on the table's axes (-1: none)
    double m_extent[2] = {1.0, 1.0};
    int m_ny = 1;
    /** Per grid node (x fastest): -ln(I/I0), then deltabar of each other material. */
    std::vector<float> m_nodes;
    /** The same per cell (with a y axis), for the CPU's walk: per cell (x fastest) and value
     *  the bilinear coefficients {a, b, c, d}, v = a + b tx + c ty + d tx ty: one cache line
     *  per pixel instead of two rows. */
    std::vector<float> m_cells;
    std::vector<int> m_others;
    std::vector<double> m_scale; ///< per other material: c in mu_m ~ c mu_x + residual
};

// ---- Noise ------------------------------------------------------------------------------------

/** Quantum noise for an exposure: the unattenuated beam gives
 *  N0 = sum_E S(E) eta(E) x mAs x (1000 mm / SID)^2 x pixel area detected photons per pixel
 *  (TASMIP fluence is per mm^2 per mAs at 1 m). Photon counting: N ~ Poisson(N0 I/I0), output
 *  N / N0. Energy integrating: Poisson in noise-equivalent quanta (N0 x Swank factor), the
 *  compound-Poisson variance of the energy weighting. Electronic noise: Gaussian of the given
 *  standard deviation in quanta, added before normalising. */
struct NoiseModel {
    double mAs = 0.0; ///< 0: no noise
    double sidMm = 1000.0;
    double pixelAreaMm2 = 1.0;
    double electronicSigma = 0.0;
    std::uint64_t seed = 1;
    bool active() const { return mAs > 0.0; }
};

/** The noise-equivalent quanta per pixel of the unattenuated beam. */
double unattenuatedQuanta(const SpectralResponse& response, const NoiseModel& noise);

/** Replaces I/I0 by its noisy version, in place (deterministic for a seed). */
void applyQuantumNoise(std::vector<float>& iOverI0, double quanta, const NoiseModel& noise);

/** -ln(I/I0) in place (the display's quantity, bone white), I/I0 floored at 1e-30 (a pixel that
 *  noise left at no photon is 69 attenuation lengths, not infinity). */
void negativeLogInPlace(std::vector<float>& iOverI0);

} // namespace fvr::core
