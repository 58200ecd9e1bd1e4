// Polychromatic cone beam against independent oracles: a water box holding a bone block, whose
// mass thickness per ray is its chord length (slab method, worked out here) times the density
// the CT number states, summed over the spectrum per ray here; one energy and one material is
// Beer-Lambert of the monochromatic cone-beam image; the shared spectral sum is the parallel
// renderer's; quantum noise has the Poisson mean and variance of the detector's quanta.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/xray/polychromatic.h>
#include <fvr/core/xray/polychromatic_cone.h>
#include <fvr/core/xray/polychromatic_render.h>
#include <fvr/core/xray/spectrum_model.h>

namespace {

using namespace fvr::core;

/** N^3 voxels of 2 mm about the origin, identity directions, HU from f(i, j, k). */
template <class F>
Volume huVolume(int n, F&& f) {
    Volume v;
    v.dims = {n, n, n};
    v.spacing = {2.0, 2.0, 2.0};
    for (int a = 0; a < 3; ++a) v.origin[a] = -(n - 1) / 2.0 * 2.0;
    v.units = ValueUnits::HounsfieldUnits;
    v.voxels.resize(std::size_t(n) * n * n);
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) v.voxels[v.index(i, j, k)] = f(i, j, k);
    return v;
}

/** The chord (mm) of the segment source -> p through the box [lo, hi]^3 (slab method). */
double chord(const glm::dvec3& s, const glm::dvec3& p, double lo, double hi) {
    const glm::dvec3 d = p - s;
    double t0 = 0.0, t1 = 1.0;
    for (int a = 0; a < 3; ++a) {
        double ta = (lo - s[a]) / d[a], tb = (hi - s[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t1 > t0 ? (t1 - t0) * glm::length(d) : 0.0;
}

/** The density (g/cm^3) of one material at a CT number that maps wholly to it: its attenuation
 *  at 70 keV is the CT number's, (1 + HU/1000) mu_water(70). */
double density(Material m, double hu) {
    return (1.0 + hu / 1000.0) * massAttenuation("Water, Liquid", 70.0) /
           massAttenuation(materialNistName(m), 70.0);
}

/** sum_E S E exp(-sum_m mu_m(E) rhoL_m) / sum_E S E: an ideal energy-integrating detector. */
double transmission(const TubeSpectrum& s, const std::vector<Material>& mats,
                    const std::vector<double>& rhoL) {
    double num = 0.0, den = 0.0;
    for (std::size_t e = 0; e < s.bins(); ++e) {
        double a = 0.0;
        for (std::size_t m = 0; m < mats.size(); ++m)
            a += massAttenuation(materialNistName(mats[m]), s.keV[e]) * rhoL[m];
        num += s.fluence[e] * s.keV[e] * std::exp(-a);
        den += s.fluence[e] * s.keV[e];
    }
    return num / den;
}

/** 24^3 voxels of water (0 HU), with an 8^3 block of bone (+1400 HU) at voxels 12..19. The
 *  box model sees the box [-24, 24]^3 mm and the block [0, 16]^3 mm. */
Volume waterWithBone() {
    return huVolume(24, [](int i, int j, int k) {
        const bool bone = i >= 12 && i < 20 && j >= 12 && j < 20 && k >= 12 && k < 20;
        return bone ? 1400.0f : 0.0f;
    });
}

} // namespace

TEST(PolychromaticCone, WaterAndBoneBoxesAgainstChordsSummedOverTheSpectrum) {
    const Volume v = waterWithBone();
    const std::vector<Material> mats{Material::Soft, Material::Bone};
    const TubeSpectrum s = tubeSpectrum(80.0, 2.5);
    auto response = std::make_shared<SpectralResponse>(s, DetectorModel{}, mats);
    PolychromaticConeProjector poly(v, {mats, 70.0}, response, {RayModel::Box});
    const ConeCamera cam = cArmCamera({25.0, 15.0, 700.0, 450.0}, 40, 36, 2.0, 2.0);
    const PolychromaticConeFrame f = poly.project(cam);
    ASSERT_EQ(f.massThickness.size(), 2u);
    ASSERT_EQ(f.transmission.width, 40);
    ASSERT_EQ(f.transmission.height, 36);
    const double rhoSoft = density(Material::Soft, 0.0), rhoBone = density(Material::Bone, 1400.0);
    double worstThickness = 0.0, worstLog = 0.0, maxBone = 0.0, minI = 1.0;
    for (int row = 0; row < 36; ++row)
        for (int col = 0; col < 40; ++col) {
            const glm::dvec3 p = cam.pixelCentre(col, row);
            const double inner = chord(cam.source, p, 0.0, 16.0);
            const double outer = chord(cam.source, p, -24.0, 24.0);
            const std::vector<double> rhoL{rhoSoft * (outer - inner) / 10.0,
                                           rhoBone * inner / 10.0};
            const std::size_t k = std::size_t(row) * 40 + col;
            for (int m = 0; m < 2; ++m)
                worstThickness =
                    std::max(worstThickness, std::abs(f.massThickness[m].pixels[k] - rhoL[m]));
            const double ref = -std::log(transmission(s, mats, rhoL));
            worstLog = std::max(worstLog, std::abs(-std::log(f.transmission.pixels[k]) - ref));
            maxBone = std::max(maxBone, rhoL[1]);
            minI = std::min(minI, double(f.transmission.pixels[k]));
        }
    std::printf("[phys] cone water/bone: worst rhoL error %.2e g/cm^2, worst -ln(I/I0) error "
                "%.2e (bone up to %.2f g/cm^2, I/I0 down to %.4f)\n",
                worstThickness, worstLog, maxBone, minI);
    EXPECT_GT(maxBone, 3.0); // rays cross the bone block
    EXPECT_LT(minI, 0.2);
    EXPECT_LT(worstThickness, 2e-4);
    EXPECT_LT(worstLog, 1e-3); // the table's interpolation (the exact sum: 0)
}

TEST(PolychromaticCone, OneEnergyAndOneMaterialIsBeerLambertOfTheMonochromaticImage) {
    // Lumpy CT numbers from air to dense bone; one material (soft tissue) at the reference
    // energy: I/I0 = exp(-mu_water(70) p) with p the mu image in mm of water.
    const Volume v = huVolume(20, [](int i, int j, int k) {
        const double x = i - 9.5, y = j - 8.0, z = k - 10.5;
        return float(-1000.0 + 2600.0 * std::exp(-(x * x + y * y + z * z) / 40.0));
    });
    const std::vector<Material> mats{Material::Soft};
    auto response =
        std::make_shared<SpectralResponse>(monoenergeticSpectrum(70.0), DetectorModel{}, mats);
    PolychromaticConeProjector poly(v, {mats, 70.0}, response);
    const ConeCamera cam = cArmCamera({-40.0, 20.0, 900.0, 600.0}, 32, 24, 1.8, 1.8);
    const PolychromaticConeFrame f = poly.project(cam);
    ConeProjectorOptions mono;
    mono.mapping = ValueMapping::Mu;
    const DetectorImage p = ConeProjector(v, mono).project(cam);
    const double muPerMm = massAttenuation("Water, Liquid", 70.0) / 10.0;
    double worst = 0.0, peak = 0.0;
    for (std::size_t k = 0; k < p.pixels.size(); ++k) {
        const double ref = std::exp(-muPerMm * p.pixels[k]);
        worst = std::max(worst, std::abs(f.transmission.pixels[k] - ref));
        peak = std::max(peak, double(p.pixels[k]));
    }
    std::printf("[phys] cone one energy: worst |I/I0 - exp(-mu p)| %.2e (p up to %.1f mm)\n", worst,
                peak);
    EXPECT_GT(peak, 20.0);
    EXPECT_LT(worst, 1e-4);
    // -ln(I/I0) straight from the table is -ln of I/I0.
    const auto logs = poly.project(cam, {}, SpectralResponse::Output::NegativeLog).transmission;
    for (std::size_t k = 0; k < p.pixels.size(); ++k)
        EXPECT_NEAR(logs.pixels[k], -std::log(f.transmission.pixels[k]),
                    1e-5 * (1.0 + logs.pixels[k]));
}

TEST(PolychromaticCone, FlatFieldMultipliesTheTransmission) {
    const Volume v = waterWithBone();
    const std::vector<Material> mats{Material::Soft, Material::Bone};
    auto response = std::make_shared<SpectralResponse>(tubeSpectrum(70.0), DetectorModel{}, mats);
    PolychromaticConeProjector poly(v, {mats, 70.0}, response, {RayModel::Box});
    const ConeCamera cam = cArmCamera({0.0, 0.0, 300.0, 200.0}, 32, 32, 4.0, 4.0);
    const std::vector<float> ff = detectorFlatField(cam);
    const auto plain = poly.project(cam).transmission.pixels;
    const auto flat = poly.project(cam, {}, SpectralResponse::Output::Transmission, &ff);
    for (std::size_t k = 0; k < plain.size(); ++k)
        EXPECT_NEAR(flat.transmission.pixels[k], plain[k] * ff[k], 1e-6);
    EXPECT_LT(*std::min_element(ff.begin(), ff.end()), 0.9f); // the corners see less
    const std::vector<float> wrong(5, 1.0f);
    EXPECT_THROW(poly.project(cam, {}, SpectralResponse::Output::Transmission, &wrong),
                 SettingsError);
}

TEST(PolychromaticCone, NoiseHasThePoissonStatisticsOfTheDetectorsQuanta) {
    // Air only (-1000 HU: no attenuation) and photon counting: every pixel counts
    // N ~ Poisson(N0), N0 = fluence x mAs x (1000/SID)^2 x pitch^2.
    const Volume v = huVolume(8, [](int, int, int) { return -1000.0f; });
    const std::vector<Material> mats{Material::Soft, Material::Bone};
    const TubeSpectrum s = tubeSpectrum(80.0, 2.5);
    auto response = std::make_shared<SpectralResponse>(
        s, DetectorModel{DetectorKind::PhotonCounting, 0.0}, mats);
    PolychromaticConeProjector poly(v, {mats, 70.0}, response);
    const ConeCamera cam = cArmCamera({0.0, 0.0, 1200.0, 800.0}, 256, 256, 0.2, 0.25);
    NoiseModel noise;
    noise.mAs = 0.02;
    noise.seed = 11;
    const NoiseModel n = coneNoiseModel(noise, cam);
    EXPECT_NEAR(n.sidMm, 1200.0, 1e-9);
    EXPECT_NEAR(n.pixelAreaMm2, 0.05, 1e-12);
    const double n0 = s.totalFluence() * 0.02 * (1000.0 / 1200.0) * (1000.0 / 1200.0) * 0.05;
    EXPECT_NEAR(unattenuatedQuanta(*response, n), n0, 1e-9 * n0);
    const auto img = poly.project(cam, noise).transmission.pixels;
    double sum = 0.0, sum2 = 0.0;
    for (float x : img) {
        sum += x * n0;
        sum2 += double(x * n0) * (x * n0);
    }
    const double mean = sum / double(img.size()), var = sum2 / double(img.size()) - mean * mean;
    std::printf("[phys] cone noise: N0 %.1f quanta, mean %.2f, variance / mean %.4f\n", n0, mean,
                var / mean);
    EXPECT_GT(n0, 50.0);
    EXPECT_NEAR(mean / n0, 1.0, 0.005);
    EXPECT_NEAR(var / mean, 1.0, 0.03);
    EXPECT_EQ(poly.project(cam, noise).transmission.pixels, img); // seeded
    noise.seed = 12;
    EXPECT_NE(poly.project(cam, noise).transmission.pixels, img);
}

TEST(PolychromaticCone, RefusesNonHounsfieldDataAndAMismatchedResponse) {
    Volume v = huVolume(8, [](int, int, int) { return 0.0f; });
    const std::vector<Material> mats{Material::Soft, Material::Bone};
    auto response = std::make_shared<SpectralResponse>(tubeSpectrum(70.0), DetectorModel{}, mats);
    EXPECT_THROW(PolychromaticConeProjector(v, {{Material::Soft}, 70.0}, response), SettingsError);
    v.units = ValueUnits::Unknown;
    try {
        PolychromaticConeProjector(v, {mats, 70.0}, response);
        FAIL() << "expected SettingsError";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("Hounsfield"), std::string::npos) << e.what();
    }
}

TEST(PolychromaticCone, ANewResponseIsTheProjectorOfThatResponse) {
    const Volume v = waterWithBone();
    const std::vector<Material> mats{Material::Soft, Material::Bone};
    auto r70 = std::make_shared<SpectralResponse>(tubeSpectrum(70.0), DetectorModel{}, mats);
    auto r120 = std::make_shared<SpectralResponse>(tubeSpectrum(120.0), DetectorModel{}, mats);
    PolychromaticConeProjector swapped(v, {mats, 70.0}, r70, {RayModel::Box});
    const ConeCamera cam = cArmCamera({10.0, 0.0, 500.0, 350.0}, 24, 24, 3.0, 3.0);
    const auto at70 = swapped.project(cam).transmission.pixels;
    swapped.setResponse(r120);
    const auto at120 = swapped.project(cam).transmission.pixels;
    EXPECT_EQ(at120, PolychromaticConeProjector(v, {mats, 70.0}, r120, {RayModel::Box})
                         .project(cam)
                         .transmission.pixels);
    for (std::size_t k = 0; k < at70.size(); ++k)
        if (at70[k] < 0.99f) {
            EXPECT_GT(at120[k], at70[k]) << k; // harder beam, more transmitted
        }
    auto one = std::make_shared<SpectralResponse>(tubeSpectrum(70.0), DetectorModel{},
                                                  std::vector<Material>{Material::Soft});
    EXPECT_THROW(swapped.setResponse(one), SettingsError);
}
