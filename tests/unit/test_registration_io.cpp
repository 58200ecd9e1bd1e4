// The registration's X-ray inputs (registration_io.h): cameras from fvr-render's sidecar and from
// DICOM files this project writes, the values brought to line integrals, each refusal's message,
// the same-frame check, the overlays; and the PFM and PNG readers beneath them.
#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/errors.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/registration/registration_io.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "dicom_test_support.h"
#include "stored_deflate.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using namespace fvr::core;
using fvr::test::dicom::normalisedP;
using fvr::test::dicom::scratch;
using Json = nlohmann::json;

constexpr int kW = 48, kH = 40;

/** A C-arm at LAO 30, cranial 10 about (5, -3, 12), with a principal offset: nothing default. */
CArm testArm() {
    CArm arm;
    arm.primaryDeg = 30.0;
    arm.secondaryDeg = 10.0;
    arm.sid = 1100.0;
    arm.sod = 800.0;
    arm.isocentre = {5.0, -3.0, 12.0};
    return arm;
}

ConeCamera testCamera() { return cArmCamera(testArm(), kW, kH, 2.5, 2.0, {1.5, -2.0}); }

/** Line integrals: 0 (air) in a border, a smooth ramp with a bump inside, 0..~6. */
std::vector<float> lineIntegrals() {
    std::vector<float> p(std::size_t(kW) * kH, 0.0f);
    for (int r = 6; r < kH - 6; ++r)
        for (int c = 6; c < kW - 6; ++c)
            p[std::size_t(r) * kW + c] =
                float(1.0 + 0.05 * c + 0.03 * r +
                      3.0 * std::exp(-((c - 24) * (c - 24) + (r - 20) * (r - 20)) / 40.0));
    return p;
}

Json vec3(const glm::dvec3& v) { return Json::array({v.x, v.y, v.z}); }

/** A sidecar in fvr-render's cone layout (app/render_cli/cone.cpp), written by hand. */
Json coneSidecar(const std::vector<ConeCamera>& cameras, const Json& output) {
    Json views = Json::array();
    for (const ConeCamera& c : cameras)
        views.push_back({{"source_mm", vec3(c.source)},
                         {"detector_centre_mm", vec3(c.detectorCentre)},
                         {"u", vec3(c.u)},
                         {"v", vec3(c.v)},
                         {"width", c.width},
                         {"height", c.height},
                         {"pitch_mm", {c.pitchU, c.pitchV}},
                         {"principal_offset_px", {c.principalOffset.x, c.principalOffset.y}}});
    return Json{{"generator", "fvr-render"},
                {"geometry", "cone"},
                {"volume", {{"name", "ct-a"}, {"dims", {10, 10, 10}}, {"units", "HU"}}},
                {"output", output},
                {"views", views}};
}

void writeText(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

/** The message of readXrayInput's LoadError (empty when it did not throw one). */
std::string loadMessage(const fs::path& p, XrayValues values = XrayValues::Auto, int frame = 0) {
    try {
        readXrayInput(p, glm::dvec3(0.0), values, frame);
    } catch (const LoadError& e) {
        return e.what();
    }
    return {};
}

void expectSameP(const ConeCamera& a, const ConeCamera& b, double tol) {
    const ProjectionMatrix pa = a.matrix(), pb = b.matrix();
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 4; ++k)
            EXPECT_NEAR(pa.rows[r][k], pb.rows[r][k], tol * (1.0 + std::abs(pa.rows[r][k])))
                << "P[" << r << "][" << k << "]";
}

TEST(RegistrationIo, SidecarCameraAndLineIntegralsComeBackExactly) {
    const fs::path dir = scratch("regio_sidecar");
    const ConeCamera cam = testCamera();
    const std::vector<float> L = lineIntegrals();
    writeNpy(dir / "x.npy", L.data(), kH, kW);
    writeText(dir / "x.npy.json", coneSidecar({cam}, {{"values", "mm (mu/mu_water x mm)"}}).dump());
    const XrayInput x = readXrayInput(dir / "x.npy", glm::dvec3(0.0));
    expectSameP(x.view.camera, cam, 1e-9);
    EXPECT_EQ(x.view.camera.width, kW);
    EXPECT_EQ(x.view.camera.height, kH);
    EXPECT_EQ(x.view.image, L);
    EXPECT_TRUE(x.view.mask.empty());
    EXPECT_NE(x.valuesNote.find("line integrals as stored"), std::string::npos) << x.valuesNote;
    EXPECT_NE(x.frameOfReference.find("ct-a"), std::string::npos);

    // The same through a PFM (rows stored bottom to top: read back top to bottom).
    writePfm(dir / "x.pfm", L.data(), kH, kW);
    fs::copy_file(dir / "x.npy.json", dir / "x.pfm.json");
    EXPECT_EQ(readXrayInput(dir / "x.pfm", glm::dvec3(0.0)).view.image, L);
}

TEST(RegistrationIo, SidecarStackPicksTheFramesCamera) {
    const fs::path dir = scratch("regio_stack");
    ConeCamera second = testCamera();
    second.source += glm::dvec3(0, 0, 40);
    second.detectorCentre += glm::dvec3(0, 0, 40);
    std::vector<float> both = lineIntegrals();
    std::vector<float> two = both;
    for (float& v : two) v *= 2.0f;
    both.insert(both.end(), two.begin(), two.end());
    writeNpy(dir / "s.npy", both.data(), kH, kW, 2);
    writeText(dir / "s.npy.json", coneSidecar({testCamera(), second}, {{"values", "mm"}}).dump());
    const XrayInput x = readXrayInput(dir / "s.npy", glm::dvec3(0.0), XrayValues::Auto, 1);
    expectSameP(x.view.camera, second, 1e-9);
    EXPECT_EQ(x.view.image, two);
    const std::string m = loadMessage(dir / "s.npy", XrayValues::Auto, 2);
    EXPECT_NE(m.find("s.npy"), std::string::npos) << m;
    EXPECT_NE(m.find("frame 2 out of range"), std::string::npos) << m;

    // Several views unstacked: STEM_NNNN.npy, one sidecar STEM.npy.json listing them in order.
    writeNpy(dir / "n_0000.npy", both.data(), kH, kW);
    writeNpy(dir / "n_0001.npy", two.data(), kH, kW);
    Json j = coneSidecar({testCamera(), second}, {{"values", "mm"}});
    j["output"]["files"] = {"n_0000.npy", "n_0001.npy"};
    writeText(dir / "n.npy.json", j.dump());
    const XrayInput n1 = readXrayInput(dir / "n_0001.npy", glm::dvec3(0.0));
    expectSameP(n1.view.camera, second, 1e-9);
    EXPECT_EQ(n1.view.image, two);
    expectSameP(readXrayInput(dir / "n_0000.npy", glm::dvec3(0.0)).view.camera, testCamera(), 1e-9);
}

TEST(RegistrationIo, SidecarTransmissionComesBackAsLineIntegrals) {
    // Beer-Lambert: I = exposure exp(-mu L); -ln(I / exposure) / mu = L.
    const fs::path dir = scratch("regio_transmission");
    const double mu = 0.0183, exposure = 0.8;
    const std::vector<float> L = lineIntegrals();
    std::vector<float> I(L.size());
    for (std::size_t k = 0; k < L.size(); ++k) I[k] = float(exposure * std::exp(-mu * L[k]));
    writeNpy(dir / "t.npy", I.data(), kH, kW);
    writeText(dir / "t.npy.json", coneSidecar({testCamera()}, {{"values", "transmission"},
                                                               {"mu_water_per_mm", mu},
                                                               {"exposure", exposure}})
                                      .dump());
    const XrayInput x = readXrayInput(dir / "t.npy", glm::dvec3(0.0));
    for (std::size_t k = 0; k < L.size(); ++k) ASSERT_NEAR(x.view.image[k], L[k], 1e-4) << k;
    EXPECT_NE(x.valuesNote.find("-ln(I/I0)"), std::string::npos) << x.valuesNote;
    // Read as stored when asked: the intensities themselves.
    EXPECT_EQ(readXrayInput(dir / "t.npy", glm::dvec3(0.0), XrayValues::LineIntegrals).view.image,
              I);
}

TEST(RegistrationIo, DicomXaOfLineIntegralsComesBackAsTheDrr) {
    const fs::path dir = scratch("regio_xa");
    DetectorImage img;
    img.width = kW;
    img.height = kH;
    img.camera = testCamera();
    img.pixels = lineIntegrals();
    writeXrayDicom(dir / "drr.dcm", img, testArm());
    const XrayInput x = readXrayInput(dir / "drr.dcm", glm::dvec3(0.0));
    // The camera the file carries (its isocentre in our private tags, not the caller's origin).
    const auto a = normalisedP(x.view.camera), b = normalisedP(img.camera);
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_NEAR(a[k], b[k], 1e-6) << k;
    // 16-bit stored values over the image's range: within half a step of 6.5/65535.
    float hi = 0.0f;
    for (float v : img.pixels) hi = std::max(hi, v);
    ASSERT_EQ(x.view.image.size(), img.pixels.size());
    for (std::size_t k = 0; k < img.pixels.size(); ++k)
        ASSERT_NEAR(x.view.image[k], img.pixels[k], hi / 65535.0) << k;
    EXPECT_NE(x.valuesNote.find("line integrals as stored"), std::string::npos) << x.valuesNote;
}

TEST(RegistrationIo, DicomXaOfTransmissionComesBackAsMinusLn) {
    // PixelIntensityRelationship LIN: -ln(I / I0), I0 the frame's 99.5th percentile, which is the
    // open beam (1) where more than 0.5 % of the field is air: then exactly mu L.
    const fs::path dir = scratch("regio_xa_lin");
    const double mu = 0.02;
    DetectorImage img;
    img.width = kW;
    img.height = kH;
    img.camera = testCamera();
    const std::vector<float> L = lineIntegrals();
    for (const float l : L) img.pixels.push_back(float(std::exp(-mu * 50.0 * l)));
    DicomExportInfo info;
    info.transmission = true;
    writeXrayDicom(dir / "lin.dcm", img, testArm(), info);
    const XrayInput x = readXrayInput(dir / "lin.dcm", glm::dvec3(0.0));
    EXPECT_NE(x.valuesNote.find("-ln(I/I0), I0 = 1 "), std::string::npos) << x.valuesNote;
    for (std::size_t k = 0; k < L.size(); ++k) {
        // I quantized in steps of (1 - min I) / 65535: -ln moves by that over I.
        const double tol = 0.5 / 65535.0 / img.pixels[k] + 1e-6;
        ASSERT_NEAR(x.view.image[k], mu * 50.0 * L[k], tol) << k;
    }
    // The same intensities stored as MONOCHROME1: the reader inverts them for display, and -ln
    // of inverted values would be no line integral: refused, naming the file.
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile((dir / "lin.dcm").c_str()).good());
    ff.loadAllDataIntoMemory();
    ff.getDataset()->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME1");
    ASSERT_TRUE(ff.saveFile((dir / "mono1.dcm").c_str(), EXS_LittleEndianExplicit).good());
    try {
        readXrayInput(dir / "mono1.dcm", glm::dvec3(0.0));
        FAIL() << "MONOCHROME1 intensities were read";
    } catch (const LoadError& e) {
        EXPECT_NE(std::string(e.what()).find("mono1.dcm"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("MONOCHROME1"), std::string::npos) << e.what();
    }
    EXPECT_NO_THROW(readXrayInput(dir / "mono1.dcm", glm::dvec3(0.0), XrayValues::LineIntegrals));
}

TEST(RegistrationIo, RefusalsNameTheFileAndTheProblem) {
    const fs::path dir = scratch("regio_refusals");
    const std::vector<float> L = lineIntegrals();
    writeNpy(dir / "bare.npy", L.data(), kH, kW);
    std::string m = loadMessage(dir / "bare.npy");
    EXPECT_NE(m.find("bare.npy"), std::string::npos) << m;
    EXPECT_NE(m.find("no camera sidecar bare.npy.json"), std::string::npos) << m;

    // A parallel render's sidecar: views of dir/up/right, no camera.
    writeNpy(dir / "par.npy", L.data(), kH, kW);
    writeText(dir / "par.npy.json",
              Json{{"generator", "fvr-render"},
                   {"views", {{{"dir", {0, 1, 0}}, {"up", {0, 0, 1}}, {"right", {1, 0, 0}}}}}}
                  .dump());
    m = loadMessage(dir / "par.npy");
    EXPECT_NE(m.find("par.npy.json"), std::string::npos) << m;
    EXPECT_NE(m.find("parallel-beam"), std::string::npos) << m;

    // A single image: frame 1 does not exist.
    writeNpy(dir / "one.npy", L.data(), kH, kW);
    writeText(dir / "one.npy.json", coneSidecar({testCamera()}, {{"values", "mm"}}).dump());
    m = loadMessage(dir / "one.npy", XrayValues::Auto, 1);
    EXPECT_NE(m.find("one.npy"), std::string::npos) << m;
    EXPECT_NE(m.find("frame 1 out of range"), std::string::npos) << m;

    // An image of another size than its camera.
    writeNpy(dir / "size.npy", L.data(), kW, kH);
    fs::copy_file(dir / "one.npy.json", dir / "size.npy.json");
    m = loadMessage(dir / "size.npy");
    EXPECT_NE(m.find("40 x 48 pixels"), std::string::npos) << m;

    // Values that are not finite.
    std::vector<float> nan = L;
    nan[7] = std::nanf("");
    writeNpy(dir / "nan.npy", nan.data(), kH, kW);
    fs::copy_file(dir / "one.npy.json", dir / "nan.npy.json");
    m = loadMessage(dir / "nan.npy");
    EXPECT_NE(m.find("nan.npy: 1 pixel values are not finite"), std::string::npos) << m;

    // A DICOM without any X-ray geometry: not an image at all.
    writeText(dir / "junk.dcm", "not DICOM");
    m = loadMessage(dir / "junk.dcm");
    EXPECT_NE(m.find("junk.dcm"), std::string::npos) << m;

    EXPECT_NE(loadMessage(dir / "missing.npy").find("missing.npy: no such file"),
              std::string::npos);
    EXPECT_THROW(parseXrayValues("log-ish"), SettingsError);
    EXPECT_EQ(parseXrayValues("intensity"), XrayValues::Intensity);
    EXPECT_STREQ(xrayValuesName(XrayValues::LineIntegrals), "line-integrals");
}

/** Our XA of the test image with `tags` removed (DCMTK), as `name`. */
fs::path xaWithout(const fs::path& dir, const std::string& name,
                   const std::vector<DcmTagKey>& tags) {
    DetectorImage img;
    img.width = kW;
    img.height = kH;
    img.camera = testCamera();
    img.pixels = lineIntegrals();
    writeXrayDicom(dir / name, img, testArm());
    DcmFileFormat ff;
    EXPECT_TRUE(ff.loadFile((dir / name).c_str()).good());
    ff.loadAllDataIntoMemory(); // the file is written over
    for (const DcmTagKey& t : tags) ff.getDataset()->findAndDeleteElement(t);
    EXPECT_TRUE(ff.saveFile((dir / name).c_str(), EXS_LittleEndianExplicit).good());
    return dir / name;
}

TEST(RegistrationIo, DicomWithoutItsGeometryIsRefusedByTag) {
    const fs::path dir = scratch("regio_geometry");
    std::string m = loadMessage(
        xaWithout(dir, "nosid.dcm",
                  {DCM_DistanceSourceToDetector, DCM_EstimatedRadiographicMagnificationFactor}));
    EXPECT_NE(m.find("nosid.dcm: DistanceSourceToDetector (0018,1110) missing: a registration "
                     "needs the X-ray's stated geometry"),
              std::string::npos)
        << m;
    m = loadMessage(xaWithout(dir, "nopitch.dcm", {DCM_ImagerPixelSpacing, DCM_PixelSpacing}));
    EXPECT_NE(m.find("nopitch.dcm: ImagerPixelSpacing (0018,1164) and PixelSpacing (0028,0030) "
                     "missing"),
              std::string::npos)
        << m;
    m = loadMessage(xaWithout(dir, "noangle.dcm", {DCM_PositionerPrimaryAngle}));
    EXPECT_NE(m.find("noangle.dcm: PositionerPrimaryAngle (0018,1510) missing"), std::string::npos)
        << m;
    // SOD alone is derived (SID / magnification): read, with the reader's warning.
    const XrayInput x =
        readXrayInput(xaWithout(dir, "nosod.dcm", {DCM_DistanceSourceToPatient}), glm::dvec3(0.0));
    bool said = false;
    for (const auto& w : x.warnings) said = said || w.find("DistanceSourceToPatient") == 0;
    EXPECT_TRUE(said);
}

TEST(RegistrationIo, TwoDifferentFramesAreRefused) {
    const fs::path dir = scratch("regio_frames");
    const std::vector<float> L = lineIntegrals();
    Json a = coneSidecar({testCamera()}, {{"values", "mm"}});
    Json b = a;
    b["volume"]["name"] = "ct-b";
    for (const char* n : {"a.npy", "a2.npy", "b.npy"}) writeNpy(dir / n, L.data(), kH, kW);
    writeText(dir / "a.npy.json", a.dump());
    writeText(dir / "a2.npy.json", a.dump());
    writeText(dir / "b.npy.json", b.dump());
    const XrayInput xa = readXrayInput(dir / "a.npy", glm::dvec3(0.0));
    EXPECT_NO_THROW(checkSameFrame({xa, readXrayInput(dir / "a2.npy", glm::dvec3(0.0))}));
    try {
        checkSameFrame({xa, readXrayInput(dir / "b.npy", glm::dvec3(0.0))});
        FAIL() << "two CTs' frames accepted";
    } catch (const SettingsError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("a.npy and "), std::string::npos) << m;
        EXPECT_NE(m.find("b.npy: images of different frames"), std::string::npos) << m;
    }

    // DICOM: two patients.
    DetectorImage img;
    img.width = kW;
    img.height = kH;
    img.camera = testCamera();
    img.pixels = L;
    DicomExportInfo p1, p2;
    p1.patientId = "PAT-1";
    p2.patientId = "PAT-2";
    p1.studyInstanceUid = p2.studyInstanceUid = "1.2.3.4";
    writeXrayDicom(dir / "p1.dcm", img, testArm(), p1);
    writeXrayDicom(dir / "p1b.dcm", img, testArm(), p1);
    writeXrayDicom(dir / "p2.dcm", img, testArm(), p2);
    const XrayInput d1 = readXrayInput(dir / "p1.dcm", glm::dvec3(0.0));
    EXPECT_EQ(d1.patientId, "PAT-1");
    EXPECT_NO_THROW(checkSameFrame({d1, readXrayInput(dir / "p1b.dcm", glm::dvec3(0.0))}));
    try {
        checkSameFrame({d1, readXrayInput(dir / "p2.dcm", glm::dvec3(0.0))});
        FAIL() << "two patients accepted";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("different patients (PatientID 'PAT-1' and 'PAT-2')"),
                  std::string::npos)
            << e.what();
    }
}

TEST(RegistrationIo, PngReaderUndoesEveryFilter) {
    // One row per PNG filter (none, Sub, Up, Average, Paeth), the values worked by hand.
    const std::string rows[] = {
        std::string("\0\x0a\x14\x1e", 4), std::string("\x01\x05\x05\x05", 4),
        std::string("\x02\x01\x02\x03", 4), std::string("\x03\x04\x04\x04", 4),
        std::string("\x04\x01\x01\x01", 4)};
    const int expected[5][3] = {{10, 20, 30}, {5, 10, 15}, {6, 12, 18}, {7, 13, 19}, {8, 14, 20}};
    std::string raw;
    for (const auto& r : rows) raw += r;
    auto chunk = [](const std::string& type, const std::string& data) {
        std::string c;
        fvr::test::appendUnsigned(c, std::uint32_t(data.size()), 4, true);
        c += type + data;
        fvr::test::appendUnsigned(c, fvr::test::crc32(type + data), 4, true);
        return c;
    };
    std::string ihdr;
    fvr::test::appendUnsigned(ihdr, 3, 4, true);
    fvr::test::appendUnsigned(ihdr, 5, 4, true);
    ihdr += std::string("\x08\0\0\0\0", 5);
    const std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) +
                            chunk("IDAT", fvr::test::zlibStored(raw)) + chunk("IEND", "");
    const fs::path dir = scratch("regio_png");
    writeText(dir / "f.png", png);
    int h = 0, w = 0;
    const std::vector<float> v = readPng(dir / "f.png", h, w);
    ASSERT_EQ(h, 5);
    ASSERT_EQ(w, 3);
    for (int r = 0; r < 5; ++r)
        for (int c = 0; c < 3; ++c)
            EXPECT_FLOAT_EQ(v[std::size_t(r * 3 + c)], expected[r][c] / 255.0f);

    // A colour PNG (ours, RGB) is refused by name.
    const std::uint8_t rgb[6] = {1, 2, 3, 4, 5, 6};
    writePngRgb(dir / "c.png", rgb, 1, 2);
    try {
        readPng(dir / "c.png", h, w);
        FAIL() << "colour PNG read";
    } catch (const LoadError& e) {
        EXPECT_NE(std::string(e.what()).find("c.png: PNG colour type 2"), std::string::npos)
            << e.what();
    }
}

TEST(RegistrationIo, OverlaysAreRgbPngsOfTheImagesSize) {
    const fs::path dir = scratch("regio_overlay");
    const std::vector<float> L = lineIntegrals();
    writeOverlayPng(dir / "b.png", "blend", L, L, kW, kH);
    writeOverlayPng(dir / "c.png", "checkerboard", L, L, kW, kH, 8);
    for (const char* n : {"b.png", "c.png"}) {
        std::ifstream in(dir / n, std::ios::binary);
        const std::string s((std::istreambuf_iterator<char>(in)), {});
        ASSERT_GT(s.size(), 33u);
        EXPECT_EQ(s.substr(12, 4), "IHDR");
        EXPECT_EQ(std::uint8_t(s[19]), kW); // width's low byte
        EXPECT_EQ(std::uint8_t(s[23]), kH);
        EXPECT_EQ(s[25], 2) << n; // RGB
    }
    EXPECT_THROW(writeOverlayPng(dir / "x.png", "side-by-side", L, L, kW, kH), SettingsError);
    EXPECT_THROW(writeOverlayPng(dir / "x.png", "blend", L, {}, kW, kH), SettingsError);
}

} // namespace
