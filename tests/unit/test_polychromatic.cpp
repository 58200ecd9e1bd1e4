// Polychromatic X-ray physics: TASMIP spectra (tungsten K lines, kVp cut-off, HVL of
// the IEC 61267 RQR qualities), the monoenergetic limit (= Beer-Lambert), beam hardening in water
// against a per-ray double-precision sum, materials from CT numbers (fractions, attenuation
// preserved at the reference energy), the linearity of the material line integrals, a bone/water
// phantom against per-ray polychromatic references, and Poisson noise statistics.
#include <cmath>
#include <cstdio>
#include <numbers>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/xray/polychromatic.h>
#include <fvr/core/xray/polychromatic_render.h>
#include <fvr/core/xray/spectrum_model.h>
#include <fvr/core/xray/xray.h>

#include "image_metrics.h"

using namespace fvr::core;

namespace {

/** The per-ray reference, written out here: sum_E S E eta exp(-mu t) over sum_E S E eta. */
double referenceTransmission(const TubeSpectrum& s, const std::vector<std::string>& names,
                             const std::vector<double>& rhoL, bool energy) {
    double num = 0.0, den = 0.0;
    for (std::size_t e = 0; e < s.bins(); ++e) {
        const double w = s.fluence[e] * (energy ? s.keV[e] : 1.0);
        double a = 0.0;
        for (std::size_t m = 0; m < names.size(); ++m)
            a += massAttenuation(names[m], s.keV[e]) * rhoL[m];
        num += w * std::exp(-a);
        den += w;
    }
    return num / den;
}

} // namespace

TEST(TubeSpectrum, TasmipHasTheTungstenKLinesAndEndsAtTheTubeVoltage) {
    const TubeSpectrum s = tasmipSpectrum(100.0);
    ASSERT_EQ(s.keV.back(), 100.0);
    auto at = [&](double e) { return s.fluence[std::size_t(e - s.keV.front())]; };
    // W K-alpha 58.0 / 59.3 keV and K-beta 67.2 keV stand above the bremsstrahlung around them.
    EXPECT_GT(at(59), 1.5 * at(55));
    EXPECT_GT(at(67), 1.25 * at(65));
    EXPECT_LT(at(100), 0.05 * at(50)); // bremsstrahlung falls to 0 at eV = kVp
    EXPECT_EQ(tasmipSpectrum(60.4).keV.back(), 60.0);
    EXPECT_EQ(tasmipSpectrum(60.5).keV.back(), 61.0);
    EXPECT_THROW(tasmipSpectrum(29.0), SettingsError);
    EXPECT_THROW(tasmipSpectrum(141.0), SettingsError);
    EXPECT_THROW(tubeSpectrum(80.0, -1.0), SettingsError);
}

TEST(TubeSpectrum, XraylibWaterMatchesTheNistTableOfTheMonochromaticModel) {
    for (double e : {20.0, 40.0, 60.0, 80.0, 100.0, 150.0})
        EXPECT_NEAR(massAttenuation("Water, Liquid", e) / 10.0, waterAttenuationPerMm(e),
                    0.01 * waterAttenuationPerMm(e))
            << e << " keV";
    EXPECT_THROW(massAttenuation("Unobtainium (ICRP)", 60.0), SettingsError);
}

TEST(TubeSpectrum, HalfValueLayerOfOneEnergyIsLn2OverMu) {
    for (double e : {30.0, 60.0, 100.0}) {
        const double mu = massAttenuation("Al", e) * kAluminiumDensity / 10.0; // 1/mm
        EXPECT_NEAR(halfValueLayerAlMm(monoenergeticSpectrum(e)), std::numbers::ln2 / mu, 1e-5);
    }
    // NIST's air table at its own nodes.
    EXPECT_DOUBLE_EQ(airMassEnergyAbsorption(20.0), 5.389e-01);
    EXPECT_NEAR(airMassEnergyAbsorption(60.0), 3.041e-02, 1e-12);
}

/** The aluminium-equivalent filtration of a tungsten spectrum: the t of Kramers' thick-target
 *  law N(E) ~ (kV - E) / E exp(-(mu/rho)_Al(E) rho_Al t) fitted (log least squares) to the
 *  spectrum over 15..55 keV (between the L and K lines). It includes the anode's
 *  self-absorption, so it is an upper estimate of the filtration of the tube's materials. */
double kramersFiltrationAlMm(const TubeSpectrum& s) {
    double sx = 0.0, sy = 0.0, sxx = 0.0, sxy = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < s.bins(); ++i) {
        const double e = s.keV[i];
        if (e < 15.0 || e > 55.0 || !(s.fluence[i] > 0.0)) continue;
        const double x = -massAttenuation("Al", e) * kAluminiumDensity / 10.0; // per mm
        const double y = std::log(s.fluence[i] * e / (s.kvp - e));
        sx += x, sy += y, sxx += x * x, sxy += x * y, ++n;
    }
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

TEST(TubeSpectrum, HalfValueLayersOfTheIecRqrQualities) {
    // IEC 61267:2005, Table 2 (RQR 5..9): first HVL 2.58 / 3.01 / 3.48 / 3.97 / 5.00 mm Al at
    // 70 / 80 / 90 / 100 / 120 kV (2.6 / 3.0 / 3.5 / 4.0 / 5.0 rounded, as calibration
    // laboratories list them) and homogeneity coefficient h = HVL1 / HVL2 of 0.71 / 0.69 / 0.68 /
    // 0.68 / 0.68, within +-0.03. The standard fixes no filter: a laboratory adds Al to its tube
    // until it gives the table's HVL1, then checks h. We do the same with TASMIP's tube: solve the
    // added Al that gives HVL1 (to 1e-6 mm), then check the spectrum's shape independently:
    // (a) h of the same spectrum within the standard's +-0.03; (b) the filtration is physically
    // plausible: the added Al lies between 1 and 3 mm, and the total Al-equivalent filtration
    // (Kramers fit, anode included) is at least the 2.5 mm Al of IEC 60601-1-3 and below 5 mm.
    const double kv[] = {70, 80, 90, 100, 120}, hvl1[] = {2.58, 3.01, 3.48, 3.97, 5.00};
    const double h[] = {0.71, 0.69, 0.68, 0.68, 0.68};
    for (int i = 0; i < 5; ++i) {
        double lo = 0.0, hi = 20.0; // HVL1 grows with the added Al
        while (hi - lo > 1e-6) {
            const double mid = 0.5 * (lo + hi);
            (halfValueLayerAlMm(tubeSpectrum(kv[i], mid)) < hvl1[i] ? lo : hi) = mid;
        }
        const double al = 0.5 * (lo + hi);
        const TubeSpectrum s = tubeSpectrum(kv[i], al);
        const double first = halfValueLayerAlMm(s), second = secondHalfValueLayerAlMm(s);
        const double total = kramersFiltrationAlMm(s);
        std::printf("[phys] RQR %g kV: + %.2f mm Al (total ~%.2f) gives HVL1 %.3f, HVL2 %.3f mm "
                    "Al, h %.3f (IEC %.2f)\n",
                    kv[i], al, total, first, second, first / second, h[i]);
        EXPECT_NEAR(first, hvl1[i], 1e-4 * hvl1[i]) << kv[i] << " kV";
        EXPECT_NEAR(first / second, h[i], 0.03) << kv[i] << " kV";
        EXPECT_GT(al, 1.0) << kv[i] << " kV";
        EXPECT_LT(al, 3.0) << kv[i] << " kV";
        EXPECT_GE(total, 2.5) << kv[i] << " kV";
        EXPECT_LT(total, 5.0) << kv[i] << " kV";
    }
}

TEST(SpectralResponse, OneEnergyIsBeerLambert) {
    const double e = 60.0;
    const double mu = massAttenuation("Water, Liquid", e); // cm^2/g
    for (auto kind : {DetectorKind::EnergyIntegrating, DetectorKind::PhotonCounting}) {
        SpectralResponse r(monoenergeticSpectrum(e), {kind, 0.0},
                           std::vector<std::vector<double>>{{mu}});
        const Transmission beer{mu / 10.0, 1.0}; // today's model, mu in 1/mm
        for (double mm : {0.0, 10.0, 100.0, 250.0, 400.0}) {
            const double rhoL = mm / 10.0; // g/cm^2 of water
            const float rf = float(rhoL);
            EXPECT_NEAR(r.exact(&rhoL), beer.intensity(mm), 1e-12 * (1 + beer.intensity(mm)));
            EXPECT_NEAR(std::log(r.lookup(&rf)), std::log(beer.intensity(mm)), 1e-5) << mm;
        }
        const double negative = -3.0; // ringing: clamped to no path
        EXPECT_DOUBLE_EQ(r.exact(&negative), 1.0);
    }
}

TEST(SpectralResponse, WaterSlabBeamHardeningAgainstPerRaySums) {
    double worstRel = 0.0;
    for (double kv : {70.0, 120.0}) {
        const TubeSpectrum s = tubeSpectrum(kv, 2.5);
        const std::vector<std::string> water{"Water, Liquid"};
        SpectralResponse r(s, {}, {massAttenuation("Water, Liquid", s.keV)});
        double lastMu = 1e9;
        for (double cm = 5.0; cm <= 30.0; cm += 5.0) {
            const double ref = -std::log(referenceTransmission(s, water, {cm}, true));
            const float rf = float(cm);
            const double got = -std::log(double(r.lookup(&rf)));
            EXPECT_NEAR(got, ref, 0.005 * ref) << kv << " kV, " << cm << " cm";
            worstRel = std::max(worstRel, std::abs(got / ref - 1.0));
            const double muEff = ref / cm; // 1/cm: falls as the beam hardens
            EXPECT_LT(muEff, lastMu) << cm;
            lastMu = muEff;
        }
        std::printf("[phys] water %g kV: mu_eff 5 cm %.4f, 30 cm %.4f /cm\n", kv,
                    -std::log(referenceTransmission(s, water, {5.0}, true)) / 5.0, lastMu);
    }
    std::printf("[phys] water 5-30 cm: table vs per-ray sum, max relative error %.2e\n", worstRel);
}

TEST(SpectralResponse, TableMatchesTheExactSumOverTheBodyRange) {
    const TubeSpectrum s = tubeSpectrum(80.0, 2.5);
    SpectralResponse r(s, {DetectorKind::EnergyIntegrating, 600.0}, defaultMaterials());
    double worst = 0.0;
    for (double air : {0.0, 0.05, 2.0, 5.0}) // lung voxels are air at lung density
        for (double soft = 0.0; soft <= 60.0; soft += 3.7)
            for (double bone = 0.0; bone <= 12.0; bone += 0.9) {
                const double d[3] = {air, soft, bone};
                const float f[3] = {float(air), float(soft), float(bone)};
                const double ref = -std::log(r.exact(d));
                worst = std::max(worst, std::abs(-std::log(double(r.lookup(f))) - ref));
            }
    EXPECT_LT(worst, 1e-3); // absolute in -ln(I/I0): 0.1 % of the transmitted intensity
    std::printf("[phys] table vs exact sum, 3 materials: max |error| %.2e in -ln(I/I0)\n", worst);
    // Five materials: lung and fat ride on the soft-tissue axis.
    const std::vector<Material> five{Material::Air, Material::Lung, Material::Adipose,
                                     Material::Soft, Material::Bone};
    SpectralResponse r5(tubeSpectrum(120.0, 2.5), {}, five);
    worst = 0.0;
    for (double lung : {0.0, 3.0, 8.0})
        for (double fat : {0.0, 4.0, 10.0})
            for (double soft = 0.0; soft <= 40.0; soft += 7.3)
                for (double bone : {0.0, 1.5, 6.0}) {
                    const double d[5] = {0.02, lung, fat, soft, bone};
                    const float f[5] = {0.02f, float(lung), float(fat), float(soft), float(bone)};
                    const double ref = -std::log(r5.exact(d));
                    worst = std::max(worst, std::abs(-std::log(double(r5.lookup(f))) - ref));
                }
    EXPECT_LT(worst, 4e-3); // first order in the residuals: 2.7e-3 at 8 g/cm^2 lung + 10 fat
    std::printf("[phys] table vs exact sum, 5 materials: max |error| %.2e in -ln(I/I0)\n", worst);
}

TEST(Materials, FractionsAreSmoothAndDensitiesKeepTheAttenuation) {
    const MaterialMapping mapping;
    const MaterialDecomposer dec(mapping);
    const double muW = massAttenuation("Water, Liquid", mapping.referenceKeV);
    std::vector<double> last;
    for (double hu = -1100.0; hu <= 2000.0; hu += 1.0) {
        const auto f = materialFractions(mapping.materials, hu);
        double sum = 0.0;
        for (double v : f) sum += v;
        ASSERT_NEAR(sum, 1.0, 1e-12);
        if (!last.empty()) {
            for (std::size_t m = 0; m < f.size(); ++m)
                ASSERT_LT(std::abs(f[m] - last[m]), 0.01) << hu; // no switch at a threshold
        }
        last = f;
        double rho[3], mu = 0.0;
        dec.densities(hu, rho);
        for (int m = 0; m < 3; ++m)
            mu += rho[m] * massAttenuation(materialNistName(mapping.materials[m]), 70.0);
        ASSERT_NEAR(mu, std::max(0.0, 1.0 + hu / 1000.0) * muW, 1e-9) << hu;
    }
    EXPECT_EQ(materialFractions(mapping.materials, 0.0), (std::vector<double>{0, 1, 0}));
    EXPECT_EQ(materialFractions(mapping.materials, 1000.0), (std::vector<double>{0, 0, 1}));
    EXPECT_EQ(parseMaterials("bone,air,soft"), defaultMaterials());
    EXPECT_THROW(parseMaterials("air,steel"), SettingsError);
    EXPECT_THROW(parseMaterials("air,air"), SettingsError);
}

TEST(Noise, PoissonVarianceEqualsMeanOnAFlatField) {
    NoiseModel n;
    n.mAs = 1.0;
    n.seed = 7;
    std::vector<float> flat(512 * 512, 0.25f);
    const double quanta = 2000.0;
    applyQuantumNoise(flat, quanta, n);
    double sum = 0.0, sum2 = 0.0;
    for (float v : flat) {
        const double c = v * quanta; // counts
        sum += c;
        sum2 += c * c;
    }
    const double mean = sum / flat.size(), var = sum2 / flat.size() - mean * mean;
    EXPECT_NEAR(mean, 500.0, 0.5);
    EXPECT_NEAR(var / mean, 1.0, 0.03);
    std::printf("[phys] Poisson flat field: variance / mean %.4f\n", var / mean);
    std::vector<float> again(512 * 512, 0.25f);
    applyQuantumNoise(again, quanta, n);
    EXPECT_EQ(again, flat); // seeded
    // Electronic noise adds its variance: var = mean + sigma^2 (in quanta).
    NoiseModel withElectronic = n;
    withElectronic.electronicSigma = 15.0;
    std::vector<float> noisy(512 * 512, 0.25f);
    applyQuantumNoise(noisy, quanta, withElectronic);
    double s1 = 0.0, s2 = 0.0;
    for (float v : noisy) {
        s1 += v * quanta;
        s2 += double(v * quanta) * (v * quanta);
    }
    const double m1 = s1 / noisy.size(), v1 = s2 / noisy.size() - m1 * m1;
    EXPECT_NEAR(v1 / (m1 + 225.0), 1.0, 0.03);
    // The quanta of an ideal photon-counting detector: TASMIP fluence x mAs x (1 m/SID)^2 x area.
    const TubeSpectrum s = tubeSpectrum(80.0, 2.5);
    SpectralResponse r(s, {DetectorKind::PhotonCounting, 0.0}, defaultMaterials());
    const NoiseModel dose{2.0, 1500.0, 0.25, 0.0, 1};
    EXPECT_NEAR(unattenuatedQuanta(r, dose), s.totalFluence() * 2.0 / 2.25 * 0.25,
                1e-9 * s.totalFluence());
}

namespace {

/** A water cylinder-like ellipsoid holding a bone ellipsoid, in a 64^3 volume over 160 mm. */
struct BoneWater {
    static constexpr int kN = 64, kM = 128;
    double field = 160.0;
    Vec3 spacing{field / kN, field / kN, field / kN};
    EllipsoidPhantom phantom;
    Volume volume;
    double d;
    MaterialMapping mapping{{Material::Soft, Material::Bone}, 70.0};
    BoneWater() {
        phantom.composition = EllipsoidPhantom::Composition::Paint;
        phantom.ellipsoids.push_back({{0, 0, 0}, {70, 55, 60}});
        phantom.ellipsoids.push_back({{12, -8, 5}, {18, 12, 30}});
        phantom.ellipsoids[0].density = 1.0; // water (mu/mu_water)
        phantom.ellipsoids[1].density = 2.4; // cortical-bone-like: +1400 HU
        volume = phantom.voxelize({kN, kN, kN}, spacing, 4);
        d = defaultPixelSize(volume.dims, volume.spacing, kM);
    }
    /** Exact mass thicknesses (g/cm^2) of each material along the renderer's rays: each
     *  ellipsoid is one material at the density the decomposition gives its CT number. */
    std::vector<ProjectionImage> exactMassThickness(const ViewFrame& view) const {
        const MaterialDecomposer dec(mapping);
        std::vector<ProjectionImage> out;
        for (int m = 0; m < 2; ++m) {
            EllipsoidPhantom p = phantom;
            for (auto& e : p.ellipsoids) {
                double rho[2];
                dec.densities(1000.0 * (e.density - 1.0), rho);
                e.density = rho[m];
            }
            ProjectionImage img =
                p.project(view, {kM, d}, ValueMapping::Mu, volume.dims, volume.spacing);
            for (float& v : img.pixels) v *= 0.1f;
            out.push_back(std::move(img));
        }
        return out;
    }
};

std::vector<double> minusLog(const std::vector<float>& v) {
    std::vector<double> out;
    for (float x : v) out.push_back(-std::log(std::max(1e-30, double(x))));
    return out;
}

double psnr(const std::vector<double>& a, const std::vector<double>& ref) {
    std::vector<float> fa(a.begin(), a.end()), fr(ref.begin(), ref.end());
    return compareImages(fa, fr).psnr;
}

} // namespace

TEST(PolychromaticRender, MaterialLineIntegralsSumToTheProjectionOfTheSummedVolume) {
    const BoneWater bw;
    PreprocessOptions po;
    po.effort = PlannerEffort::Estimate;
    std::vector<Volume> mats = materialVolumes(bw.volume, bw.mapping);
    Volume total = mats[0];
    for (std::size_t i = 0; i < total.voxels.size(); ++i) total.voxels[i] += mats[1].voxels[i];
    const RenderParams params{ViewFrame::fromDirUp({0.3, 0.5, 0.81}, {0, 0, 1}),
                              {BoneWater::kM, bw.d}};
    std::vector<float> sum(std::size_t(BoneWater::kM) * BoneWater::kM, 0.0f);
    for (const Volume& v : mats) {
        CpuFourierRenderer r(preprocess(v, po), 2);
        const auto img = r.render(params);
        for (std::size_t p = 0; p < sum.size(); ++p) sum[p] += img.pixels[p];
    }
    CpuFourierRenderer rt(preprocess(total, po), 2);
    const auto whole = rt.render(params);
    double maxAbs = 0.0, peak = 0.0;
    for (std::size_t p = 0; p < sum.size(); ++p) {
        maxAbs = std::max(maxAbs, double(std::abs(sum[p] - whole.pixels[p])));
        peak = std::max(peak, double(whole.pixels[p]));
    }
    EXPECT_GT(peak, 100.0); // g/cm^3 x mm through 11 cm of water and bone
    EXPECT_LT(maxAbs, 1e-4 * peak);
}

TEST(PolychromaticRender, BoneWaterPhantomAgainstPerRayPolychromaticReferences) {
    const BoneWater bw;
    PreprocessOptions po;
    po.effort = PlannerEffort::Estimate;
    std::vector<std::unique_ptr<Renderer>> renderers;
    for (auto& s : preprocessMaterials(bw.volume, bw.mapping, po))
        renderers.push_back(std::make_unique<CpuFourierRenderer>(s, 2));
    const TubeSpectrum s = tubeSpectrum(80.0, 2.5);
    auto response = std::make_shared<SpectralResponse>(s, DetectorModel{}, bw.mapping.materials);
    PolychromaticRenderer poly(std::move(renderers), response, 2);
    const ViewFrame view = ViewFrame::fromDirUp({0.3, 0.5, 0.81}, {0, 0, 1});
    RenderParams params{view, {BoneWater::kM, bw.d}};
    params.nonNegative = true;
    const PolychromaticFrame f = poly.render(params);
    // 1. The spectral sum: against the exact double sum per ray of the rendered rhoL.
    std::vector<double> exactOfRendered;
    for (std::size_t p = 0; p < f.transmission.pixels.size(); ++p) {
        const double rhoL[2] = {f.massThickness[0].pixels[p], f.massThickness[1].pixels[p]};
        exactOfRendered.push_back(-std::log(response->exact(rhoL)));
    }
    const double sumPsnr = psnr(minusLog(f.transmission.pixels), exactOfRendered);
    // 2. The whole chain: against the analytic phantom's exact rhoL, spectrum summed per ray.
    const auto truth = bw.exactMassThickness(view);
    std::vector<double> exactPoly, exactMono, renderedMono;
    const double muSoft = massAttenuation(materialNistName(Material::Soft), 60.0);
    const double muBone = massAttenuation(materialNistName(Material::Bone), 60.0);
    for (std::size_t p = 0; p < truth[0].pixels.size(); ++p) {
        const double t0 = truth[0].pixels[p], t1 = truth[1].pixels[p];
        exactPoly.push_back(-std::log(referenceTransmission(
            s, {materialNistName(Material::Soft), materialNistName(Material::Bone)}, {t0, t1},
            true)));
        exactMono.push_back(muSoft * t0 + muBone * t1);
        renderedMono.push_back(muSoft * std::max(0.0f, f.massThickness[0].pixels[p]) +
                               muBone * std::max(0.0f, f.massThickness[1].pixels[p]));
    }
    const double chainPsnr = psnr(minusLog(f.transmission.pixels), exactPoly);
    const double monoPsnr = psnr(renderedMono, exactMono);
    std::printf("[phys] bone/water -ln(I/I0): spectral sum %.1f dB, whole chain %.1f dB "
                "(monochromatic 60 keV %.1f dB)\n",
                sumPsnr, chainPsnr, monoPsnr);
    EXPECT_GT(sumPsnr, 50.0);
    // The polychromatic model adds no error of its own to the renderer's.
    EXPECT_GT(chainPsnr, monoPsnr - 1.0);

    // 3. The display's -ln(I/I0) straight from the table (no exp and log per pixel) is -ln of
    // I/I0, without noise and with it (the same seed: the same quanta drawn).
    using Output = SpectralResponse::Output;
    const auto logs = poly.render(params, {}, nullptr, Output::NegativeLog).transmission.pixels;
    const auto fromI = minusLog(f.transmission.pixels);
    double worst = 0.0;
    for (std::size_t p = 0; p < logs.size(); ++p)
        worst = std::max(worst, std::abs(logs[p] - fromI[p]) / std::max(1.0, fromI[p]));
    EXPECT_LT(worst, 1e-6);
    NoiseModel noise;
    noise.mAs = 0.5;
    noise.seed = 3;
    auto noisyI = poly.render(params, noise).transmission.pixels;
    const auto noisyLog = poly.render(params, noise, nullptr, Output::NegativeLog).transmission;
    negativeLogInPlace(noisyI);
    EXPECT_EQ(noisyLog.pixels, noisyI);
}
