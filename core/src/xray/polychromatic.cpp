#include <fvr/core/xray/polychromatic.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <random>
#include <sstream>

#include <fvr/core/errors.h>
#include <fvr/core/thread_pool.h>

namespace fvr::core {

// ---- Materials --------------------------------------------------------------------------------

namespace {

struct MaterialInfo {
    Material id;
    const char* key;
    const char* nist;
};
constexpr std::array<MaterialInfo, 5> kMaterials{{
    {Material::Air, "air", "Air, Dry (near sea level)"},
    {Material::Lung, "lung", "Lung (ICRP)"},
    {Material::Adipose, "fat", "Adipose Tissue (ICRP)"},
    {Material::Soft, "soft", "Tissue, Soft (ICRP)"},
    {Material::Bone, "bone", "Bone, Cortical (ICRP)"},
}};

/** The HU interval of the ramp from material a to the next chosen material b (a < b). */
std::array<double, 2> rampBetween(Material a, Material b) {
    if (b == Material::Bone) return {100.0, 400.0};
    if (a == Material::Air && b == Material::Lung) return {-950.0, -850.0};
    if (a == Material::Adipose && b == Material::Soft) return {-80.0, -20.0};
    return {-400.0, -200.0}; // air or lung to fat or soft tissue
}

double smoothstep(double lo, double hi, double x) {
    const double t = std::clamp((x - lo) / (hi - lo), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

} // namespace

const char* materialKey(Material m) { return kMaterials[std::size_t(m)].key; }
const char* materialNistName(Material m) { return kMaterials[std::size_t(m)].nist; }

std::vector<Material> defaultMaterials() { return {Material::Air, Material::Soft, Material::Bone}; }

std::vector<Material> parseMaterials(const std::string& list) {
    std::vector<Material> out;
    std::stringstream in(list);
    std::string item;
    while (std::getline(in, item, ',')) {
        auto it = std::find_if(kMaterials.begin(), kMaterials.end(),
                               [&](const MaterialInfo& m) { return item == m.key; });
        if (it == kMaterials.end())
            throw SettingsError("materials: unknown material \"" + item +
                                "\" (expected air, lung, fat, soft, bone)");
        if (std::find(out.begin(), out.end(), it->id) != out.end())
            throw SettingsError("materials: \"" + item + "\" is given twice");
        out.push_back(it->id);
    }
    if (out.empty()) throw SettingsError("materials: expected a list such as air,soft,bone");
    std::sort(out.begin(), out.end());
    return out;
}

std::vector<double> materialFractions(const std::vector<Material>& materials, double hu) {
    std::vector<double> f(materials.size(), 0.0);
    for (std::size_t i = 0; i + 1 < materials.size(); ++i) {
        const auto [lo, hi] = rampBetween(materials[i], materials[i + 1]);
        if (hu < hi) {
            const double s = smoothstep(lo, hi, hu);
            f[i] = 1.0 - s;
            f[i + 1] = s;
            return f;
        }
    }
    f.back() = 1.0;
    return f;
}

MaterialDecomposer::MaterialDecomposer(const MaterialMapping& mapping)
    : m_materials(mapping.materials) {
    if (m_materials.empty()) throw SettingsError("materials: none chosen");
    for (Material m : m_materials)
        m_muRef.push_back(massAttenuation(materialNistName(m), mapping.referenceKeV));
    m_muWaterRef = massAttenuation("Water, Liquid", mapping.referenceKeV);
}

void MaterialDecomposer::densities(double hu, double* out) const {
    const std::vector<double> f = materialFractions(m_materials, hu);
    double mu = 0.0;
    for (std::size_t i = 0; i < f.size(); ++i) mu += f[i] * m_muRef[i];
    const double rho = hu > -1000.0 ? (1.0 + hu / 1000.0) * m_muWaterRef / mu : 0.0;
    for (std::size_t i = 0; i < f.size(); ++i) out[i] = f[i] * rho;
}

// ---- Detector ---------------------------------------------------------------------------------

std::vector<double> detectorAbsorption(const DetectorModel& d, const std::vector<double>& keV) {
    if (!(d.csiUm >= 0.0))
        throw SettingsError("CsI thickness: expected >= 0 um, found " + std::to_string(d.csiUm));
    std::vector<double> eta(keV.size(), 1.0);
    if (d.csiUm == 0.0) return eta;
    const double rhoT = kCsIDensity * d.csiUm * 1e-4; // g/cm^2
    for (std::size_t i = 0; i < keV.size(); ++i)
        eta[i] = 1.0 - std::exp(-massAttenuation("Cesium Iodide", keV[i]) * rhoT);
    return eta;
}

// ---- The spectral sum -------------------------------------------------------------------------

namespace {

std::vector<std::vector<double>> materialAttenuation(const std::vector<Material>& materials,
                                                     const std::vector<double>& keV) {
    std::vector<std::vector<double>> mu;
    for (Material m : materials) mu.push_back(massAttenuation(materialNistName(m), keV));
    return mu;
}

/** exp(-g) in float arithmetic the compiler vectorises (with -fno-trapping-math, which
 *  core/CMakeLists.txt sets for this file): 2^t = 2^i 2^f with i = round(t),
 *  f in [-0.5, 0.5], 2^f by the Cephes exp2f polynomial (relative error below 2e-7); t clamped
 *  to [-126, 126] (exp(-g) of a path beyond 87 attenuation lengths is 1e-38, not 0). */
inline float expNegative(float g) {
    float t = -g * 1.44269504088896341f;
    t = t < -126.0f ? -126.0f : t;
    t = t > 126.0f ? 126.0f : t;
    const int i = int(t + 128.5f) - 128;
    const float f = t - float(i);
    float p = 1.535336188319500e-4f;
    p = p * f + 1.339887440266574e-3f;
    p = p * f + 9.618437357674640e-3f;
    p = p * f + 5.550332471162809e-2f;
    p = p * f + 2.402264791363012e-1f;
    p = p * f + 6.931472028550421e-1f;
    p = p * f + 1.0f;
    return p * std::bit_cast<float>((i + 127) << 23);
}

} // namespace

SpectralResponse::SpectralResponse(const TubeSpectrum& spectrum, const DetectorModel& detector,
                                   const std::vector<Material>& materials)
    : m_mu(materialAttenuation(materials, spectrum.keV)) {
    setUp(spectrum, detector);
    // Bone: 40 g/cm^2 (20 cm of cortical bone) is beyond any body; the rest extrapolates.
    for (std::size_t m = 0; m < materials.size(); ++m)
        if (materials[m] == Material::Bone) m_extent[m_axisY == int(m) ? 1 : 0] = 40.0;
    buildTables();
}

SpectralResponse::SpectralResponse(const TubeSpectrum& spectrum, const DetectorModel& detector,
                                   std::vector<std::vector<double>> massAttenuation)
    : m_mu(std::move(massAttenuation)) {
    setUp(spectrum, detector);
    buildTables();
}

void SpectralResponse::setUp(const TubeSpectrum& spectrum, const DetectorModel& detector) {
    if (m_mu.empty()) throw SettingsError("spectral response: no materials");
    for (const auto& mu : m_mu)
        if (mu.size() != spectrum.bins())
            throw SettingsError("spectral response: attenuation and spectrum bins differ");
    const std::vector<double> eta = detectorAbsorption(detector, spectrum.keV);
    double sumW = 0.0, sumN = 0.0, sumW2 = 0.0;
    m_weight.resize(spectrum.bins());
    for (std::size_t i = 0; i < spectrum.bins(); ++i) {
        const double n = spectrum.fluence[i] * eta[i];
        const double w = detector.kind == DetectorKind::EnergyIntegrating ? spectrum.keV[i] : 1.0;
        m_weight[i] = n * w;
        sumW += n * w;
        sumN += n;
        sumW2 += n * w * w;
    }
    if (!(sumW > 0.0)) throw SettingsError("spectral response: the spectrum detects no photons");
    for (double& w : m_weight) w /= sumW;
    m_detected = sumN;
    m_swank = sumW * sumW / (sumN * sumW2);
    const int k = int(m_mu.size());
    m_axisX = k >= 2 ? k - 2 : 0;
    m_axisY = k >= 2 ? k - 1 : -1;
    for (int m = 0; m < k - 2; ++m) m_others.push_back(m);
    // Each other material as c times the x axis's material plus a residual: c by weighted least
    // squares over the spectrum, so that the table's hardening carries most of its attenuation.
    for (int m : m_others) {
        double num = 0.0, den = 0.0;
        for (std::size_t e = 0; e < bins(); ++e) {
            num += m_weight[e] * m_mu[m][e] * m_mu[m_axisX][e];
            den += m_weight[e] * m_mu[m_axisX][e] * m_mu[m_axisX][e];
        }
        m_scale.push_back(den > 0.0 ? num / den : 0.0);
    }
    m_extent[0] = m_extent[1] = 80.0;
}

double SpectralResponse::exact(const double* rhoL) const {
    double sum = 0.0;
    for (std::size_t e = 0; e < bins(); ++e) {
        double a = 0.0;
        for (std::size_t m = 0; m < materials(); ++m) a += m_mu[m][e] * std::max(0.0, rhoL[m]);
        sum += m_weight[e] * std::exp(-a);
    }
    return sum;
}

double SpectralResponse::exactLog(double x, double y, std::vector<double>* muBar) const {
    double sum = 0.0;
    if (muBar) muBar->assign(m_others.size(), 0.0);
    for (std::size_t e = 0; e < bins(); ++e) {
        double a = m_mu[m_axisX][e] * x;
        if (m_axisY >= 0) a += m_mu[m_axisY][e] * y;
        const double t = m_weight[e] * std::exp(-a);
        sum += t;
        if (muBar)
            for (std::size_t o = 0; o < m_others.size(); ++o)
                (*muBar)[o] += t * (m_mu[m_others[o]][e] - m_scale[o] * m_mu[m_axisX][e]);
    }
    if (muBar)
        for (double& v : *muBar) v = sum > 0.0 ? v / sum : 0.0;
    return sum > 0.0 ? -std::log(sum) : 700.0;
}

void SpectralResponse::buildTables() {
    if (m_others.size() > 7) throw SettingsError("spectral response: at most 9 materials");
    const int n = kTableSize, stride = int(1 + m_others.size());
    m_ny = m_axisY >= 0 ? n : 1;
    m_nodes.assign(std::size_t(n) * m_ny * stride, 0.0f);
    std::vector<double> muBar;
    for (int j = 0; j < m_ny; ++j)
        for (int i = 0; i < n; ++i) {
            const double x = m_extent[0] * i / (n - 1), y = m_extent[1] * j / (n - 1);
            float* node = m_nodes.data() + (std::size_t(j) * n + i) * stride;
            node[0] = float(exactLog(x, y, &muBar));
            for (std::size_t o = 0; o < m_others.size(); ++o) node[o + 1] = float(muBar[o]);
        }
    m_cells.clear();
    if (m_ny < 2) return;
    m_cells.assign(std::size_t(n - 1) * (n - 1) * stride * 4, 0.0f);
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n; ++i) {
            const float* a = m_nodes.data() + (std::size_t(j) * n + i) * stride;
            const float* c = a + std::size_t(n) * stride;
            float* cell = m_cells.data() + (std::size_t(j) * (n - 1) + i) * stride * 4;
            for (int v = 0; v < stride; ++v) {
                const float v00 = a[v], v10 = a[v + stride], v01 = c[v], v11 = c[v + stride];
                cell[4 * v] = v00;
                cell[4 * v + 1] = v10 - v00;
                cell[4 * v + 2] = v01 - v00;
                cell[4 * v + 3] = v11 - v10 - v01 + v00;
            }
        }
}

float SpectralResponse::lookup(const float* rhoL) const {
    std::vector<const float*> one;
    for (std::size_t m = 0; m < materials(); ++m) one.push_back(rhoL + m);
    float out = 0.0f;
    applyRange(one, &out, 0, 1, Output::Transmission);
    return out;
}

namespace {

/** The table walk of SpectralResponse::applyRange for K other materials (K < 0: any number, at
 *  most 7) and with or without a y axis; writes g = -ln(I/I0). */
struct TableWalk {
    const float* nodes;
    int n, stride;
    float sx, sy;
    const float* xs;
    const float* ys;
    std::array<const float*, 8> others;
    std::array<float, 8> scale;
    int count;
};

template <int K, bool HasY>
void walkTable(const TableWalk& t, float* out, std::int64_t begin, std::int64_t end) {
    const int k = K >= 0 ? K : t.count, stride = K >= 0 ? K + 1 : t.stride;
    const std::size_t rowStep = std::size_t(t.n) * stride;
    std::array<float, 8> z{};
    for (std::int64_t p = begin; p < end; ++p) {
        float x = std::max(0.0f, t.xs[p]);
        for (int o = 0; o < k; ++o) {
            z[o] = std::max(0.0f, t.others[o][p]);
            x += t.scale[o] * z[o];
        }
        const float u = x * t.sx;
        const int i = std::min(int(u), t.n - 2);
        const float tx = u - float(i);
        const float* a = t.nodes + std::size_t(i) * stride;
        float ty = 0.0f;
        if constexpr (HasY) {
            const float w = std::max(0.0f, t.ys[p]) * t.sy;
            const int j = std::min(int(w), t.n - 2);
            ty = w - float(j);
            a += std::size_t(j) * rowStep;
        }
        float g = 0.0f;
        for (int s = 0; s < stride; ++s) {
            float v = a[s] + tx * (a[s + stride] - a[s]);
            if constexpr (HasY) {
                const float* c = a + rowStep;
                const float r1 = c[s] + tx * (c[s + stride] - c[s]);
                v += ty * (r1 - v);
            }
            g += s == 0 ? v : v * z[s - 1];
        }
        out[p] = g;
    }
}

/** The walk over the cell layout (a y axis): per block of pixels first the cells and weights
 *  (vectorised), then one contiguous read of 4 x stride coefficients per pixel. */
template <int K>
void walkCells(const TableWalk& t, const float* cells, float* out, std::int64_t begin,
               std::int64_t end) {
    const int k = K >= 0 ? K : t.count, stride = K >= 0 ? K + 1 : t.stride, cellsPerRow = t.n - 1;
    constexpr int kBlock = 256;
    alignas(64) int cell[kBlock];
    alignas(64) float txs[kBlock], tys[kBlock];
    alignas(64) float zs[8][kBlock];
    const float top = float(t.n - 2);
    for (std::int64_t b0 = begin; b0 < end; b0 += kBlock) {
        const int count = int(std::min<std::int64_t>(kBlock, end - b0));
        const float* xs = t.xs + b0;
        const float* ys = t.ys + b0;
        for (int q = 0; q < count; ++q) {
            float x = std::max(0.0f, xs[q]);
            for (int o = 0; o < k; ++o) {
                const float z = std::max(0.0f, t.others[o][b0 + q]);
                zs[o][q] = z;
                x += t.scale[o] * z;
            }
            const float u = x * t.sx, w = std::max(0.0f, ys[q]) * t.sy;
            const float fi = std::min(float(int(u)), top), fj = std::min(float(int(w)), top);
            txs[q] = u - fi;
            tys[q] = w - fj;
            cell[q] = int(fj) * cellsPerRow + int(fi);
        }
        for (int q = 0; q < count; ++q) {
            const float* c = cells + std::size_t(cell[q]) * stride * 4;
            const float tx = txs[q], ty = tys[q], txy = tx * ty;
            float g = c[0] + c[1] * tx + c[2] * ty + c[3] * txy;
            for (int o = 0; o < k; ++o) {
                const float* d = c + 4 * (o + 1);
                g += (d[0] + d[1] * tx + d[2] * ty + d[3] * txy) * zs[o][q];
            }
            out[b0 + q] = g;
        }
    }
}

} // namespace

void SpectralResponse::applyRange(const std::vector<const float*>& rhoL, float* out,
                                  std::int64_t begin, std::int64_t end, Output output) const {
    const int n = kTableSize;
    TableWalk t{m_nodes.data(),
                n,
                int(1 + m_others.size()),
                float((n - 1) / m_extent[0]),
                float((n - 1) / m_extent[1]),
                rhoL[std::size_t(m_axisX)],
                m_axisY >= 0 ? rhoL[std::size_t(m_axisY)] : nullptr,
                {},
                {},
                int(m_others.size())};
    for (std::size_t o = 0; o < m_others.size(); ++o) {
        t.others[o] = rhoL[std::size_t(m_others[o])];
        t.scale[o] = float(m_scale[o]);
    }
    if (t.ys && t.count == 1)
        walkCells<1>(t, m_cells.data(), out, begin, end);
    else if (t.ys && t.count == 0)
        walkCells<0>(t, m_cells.data(), out, begin, end);
    else if (t.ys)
        walkCells<-1>(t, m_cells.data(), out, begin, end);
    else
        walkTable<-1, false>(t, out, begin, end);
    if (output == Output::Transmission)
        for (std::int64_t p = begin; p < end; ++p) out[p] = expNegative(out[p]); // vectorised
}

void SpectralResponse::apply(const std::vector<const float*>& rhoL, float* out, std::int64_t count,
                             ThreadPool* pool, Output output) const {
    if (rhoL.size() != materials())
        throw SettingsError("spectral response: expected one image per material");
    auto run = [&](std::int64_t begin, std::int64_t end) {
        applyRange(rhoL, out, begin, end, output);
    };
    if (pool)
        pool->parallelFor(count, 16384, run);
    else
        run(0, count);
}

// ---- Noise ------------------------------------------------------------------------------------

double unattenuatedQuanta(const SpectralResponse& response, const NoiseModel& noise) {
    if (!(noise.sidMm > 0.0 && noise.pixelAreaMm2 > 0.0 && noise.mAs >= 0.0))
        throw SettingsError("noise: expected mAs >= 0, SID > 0 and pixel area > 0");
    const double photons = response.detectedFluence() * noise.mAs * (1000.0 / noise.sidMm) *
                           (1000.0 / noise.sidMm) * noise.pixelAreaMm2;
    return photons * response.swankFactor();
}

void applyQuantumNoise(std::vector<float>& iOverI0, double quanta, const NoiseModel& noise) {
    if (!noise.active()) return;
    if (!(quanta > 0.0)) throw SettingsError("noise: the beam gives no quanta per pixel");
    std::mt19937_64 rng(noise.seed);
    std::normal_distribution<double> electronic(0.0, noise.electronicSigma);
    for (float& v : iOverI0) {
        const double mean = std::max(0.0, double(v)) * quanta;
        double n = mean > 0.0 ? double(std::poisson_distribution<std::int64_t>(mean)(rng)) : 0.0;
        if (noise.electronicSigma > 0.0) n += electronic(rng);
        v = float(n / quanta);
    }
}

void negativeLogInPlace(std::vector<float>& iOverI0) {
    for (float& v : iOverI0) v = -std::log(std::max(1e-30f, v));
}

} // namespace fvr::core
