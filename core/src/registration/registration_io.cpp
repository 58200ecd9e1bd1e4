// The X-ray inputs of 2D/3D registration and its overlay images (registration_io.h). Pose files
// and target points are in pose_io.cpp.
#include <fvr/core/registration/registration_io.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <dcmtk/dcmdata/dctk.h>
#include <nlohmann/json.hpp>

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/errors.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/text.h>

namespace fvr::core {

namespace fs = std::filesystem;
using Json = nlohmann::json;

const char* xrayValuesName(XrayValues v) {
    switch (v) {
    case XrayValues::Auto: return "auto";
    case XrayValues::LineIntegrals: return "line-integrals";
    case XrayValues::Intensity: return "intensity";
    }
    return "auto";
}

XrayValues parseXrayValues(const std::string& name) {
    const std::string n = asciiLower(name);
    if (n == "auto") return XrayValues::Auto;
    if (n == "line-integrals" || n == "line-integral" || n == "log")
        return XrayValues::LineIntegrals;
    if (n == "intensity" || n == "intensities" || n == "lin") return XrayValues::Intensity;
    throw SettingsError("X-ray values '" + name + "': expected auto, line-integrals or intensity");
}

namespace {

[[noreturn]] void failLoad(const fs::path& file, const std::string& what) {
    throw LoadError(file.string() + ": " + what);
}

std::string number(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

/** The q-quantile (0..1) of the finite values (0 for none). */
double quantile(const std::vector<float>& values, double q) {
    std::vector<float> v;
    v.reserve(values.size());
    for (const float x : values)
        if (std::isfinite(x)) v.push_back(x);
    if (v.empty()) return 0.0;
    const auto k = std::size_t(std::lround(q * double(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
    return v[k];
}

void checkFinite(const fs::path& file, const std::vector<float>& values) {
    const auto bad =
        std::count_if(values.begin(), values.end(), [](float x) { return !std::isfinite(x); });
    if (bad > 0)
        failLoad(file, std::to_string(bad) + " pixel values are not finite (NaN or infinite)");
}

/** Intensities I to -ln(I / I0) / mu (mu 1: the line integrals times the attenuation scale).
 *  I0 <= 0: the 99.5th percentile of the image (the open beam, where the field has any air). */
void intensityToLineIntegrals(XrayInput& x, double i0, double mu, const std::string& i0From) {
    std::vector<float>& p = x.view.image;
    if (!(i0 > 0.0)) i0 = quantile(p, 0.995);
    if (!(i0 > 0.0))
        failLoad(x.file, "intensities with no positive open-beam level (the 99.5th percentile is " +
                             number(i0) + "): not a radiograph's intensities");
    const double floor = i0 * 1e-6;
    std::size_t clamped = 0;
    for (float& v : p) {
        double i = v;
        if (!(i > floor)) {
            i = floor;
            ++clamped;
        }
        v = float(-std::log(i / i0) / mu);
    }
    x.valuesNote = "-ln(I/I0)" +
                   std::string(mu != 1.0 ? " / mu_water (" + number(mu) + "/mm)" : "") +
                   ", I0 = " + number(i0) + " (" + i0From + ")";
    if (clamped > 0)
        x.warnings.push_back(std::to_string(clamped) +
                             " intensities at or below I0 x 1e-6 taken as "
                             "I0 x 1e-6 (a line integral of 13.8)");
}

// ---- DICOM ------------------------------------------------------------------------------------

std::string tagString(DcmDataset* ds, const DcmTagKey& tag) {
    OFString s;
    if (ds->findAndGetOFStringArray(tag, s).bad()) return {};
    std::string out = s.c_str();
    while (!out.empty() && (out.back() == ' ' || out.back() == '\0')) out.pop_back();
    return out;
}

/** The values' relation and the file's identity from its header (the pixels are the geometry
 *  reader's). */
void readDicomIdentity(XrayInput& x, std::string& relationship, bool& ours, bool& monochrome1) {
    DcmFileFormat ff;
    // Elements over 4 KiB (the pixels) are left in the file.
    if (ff.loadFile(x.file.c_str(), EXS_Unknown, EGL_noChange, 4096).bad())
        failLoad(x.file, "cannot read the DICOM header");
    DcmDataset* ds = ff.getDataset();
    relationship = tagString(ds, DCM_PixelIntensityRelationship);
    std::transform(relationship.begin(), relationship.end(), relationship.begin(),
                   [](unsigned char c) { return char(std::toupper(c)); });
    ours = tagString(ds, DCM_Manufacturer) == "FVR Workstation";
    monochrome1 = tagString(ds, DCM_PhotometricInterpretation) == "MONOCHROME1";
    x.patientId = tagString(ds, DCM_PatientID);
    const std::string frame = tagString(ds, DCM_FrameOfReferenceUID);
    const std::string study = tagString(ds, DCM_StudyInstanceUID);
    if (!frame.empty())
        x.frameOfReference = "FrameOfReferenceUID " + frame;
    else if (!study.empty() && !(ours && x.patientId.empty()))
        // A DRR this project wrote of a volume with no patient (a phantom) gets a new study UID
        // per export: its study says nothing about its frame.
        x.frameOfReference = "StudyInstanceUID " + study;
}

/** The geometry reader assumes what a file leaves out, and says so (xray_geometry.h). A DRR may
 *  be made with an assumed value; a registration may not: a wrong SID or pitch is a wrong
 *  magnification, a wrong angle a wrong view, and the pose found would be wrong without a sign.
 *  So an assumed SID, detector pitch or primary angle is refused (each named by its tag); the
 *  isocentre and SOD only place the starting pose, which the registration moves. */
void refuseAssumedGeometry(const XrayGeometry& g) {
    static const char* const kRefused[] = {
        "DistanceSourceToDetector (0018,1110) missing: assumed",
        "ImagerPixelSpacing (0018,1164) and PixelSpacing (0028,0030) missing",
        "PositionerPrimaryAngle (0018,1510) missing: assumed"};
    for (const std::string& w : g.warnings)
        for (const char* r : kRefused)
            if (w.rfind(r, 0) == 0)
                failLoad(g.file, w.substr(0, w.find(" missing")) +
                                     " missing: a registration needs the X-ray's stated "
                                     "geometry (a DRR would have" +
                                     w.substr(w.find(':') + 1) + ")");
}

XrayInput readDicomXray(const fs::path& path, const glm::dvec3& isocentre, XrayValues values,
                        int frame) {
    XrayGeometry g = readXrayGeometry(path, true);
    refuseAssumedGeometry(g);
    XrayInput x;
    x.file = path;
    x.frame = frame;
    if (frame < 0 || std::size_t(frame) >= g.frameCount())
        failLoad(path, "frame " + std::to_string(frame) + " out of range: the file holds " +
                           std::to_string(g.frameCount()) + " frame(s)");
    x.view.camera = g.camera(std::size_t(frame), isocentre);
    const std::size_t n = std::size_t(g.width) * std::size_t(g.height);
    if (g.pixels.size() < n * (std::size_t(frame) + 1)) failLoad(path, "no pixel data");
    x.view.image.assign(g.pixels.begin() + std::ptrdiff_t(n * std::size_t(frame)),
                        g.pixels.begin() + std::ptrdiff_t(n * (std::size_t(frame) + 1)));
    x.warnings = g.warnings;
    if (!g.isocentreStated)
        x.warnings.push_back("isocentre not stated in the file: taken at (" + number(isocentre.x) +
                             ", " + number(isocentre.y) + ", " + number(isocentre.z) + ") mm");
    std::string relationship;
    bool ours = false, monochrome1 = false;
    readDicomIdentity(x, relationship, ours, monochrome1);
    checkFinite(path, x.view.image);
    XrayValues v = values;
    if (v == XrayValues::Auto) {
        v = relationship == "LIN" ? XrayValues::Intensity : XrayValues::LineIntegrals;
        if (relationship != "LIN" && relationship != "LOG")
            x.warnings.push_back(
                "PixelIntensityRelationship (0028,1040) " +
                (relationship.empty() ? std::string("absent") : "'" + relationship + "'") +
                ": the values are taken as line integrals (larger = more attenuation, as a "
                "MONOCHROME2 radiograph shows bone bright); --values intensity for a raw "
                "radiograph's intensities");
    }
    if (v == XrayValues::Intensity && monochrome1)
        // The reader inverted the stored values (larger = brighter); -ln of them would not be a
        // line integral, and the stored range that undoes it is not kept.
        failLoad(path, "intensities (PixelIntensityRelationship LIN or --values intensity) stored "
                       "as MONOCHROME1 are not supported: convert the image to MONOCHROME2, or "
                       "give --values line-integrals to use its inverted values as they are");
    if (v == XrayValues::Intensity) {
        intensityToLineIntegrals(x, 0.0, 1.0, "the 99.5th percentile of the frame");
    } else {
        x.valuesNote = relationship == "LOG" && ours ? "line integrals as stored (a DRR of ours)"
                                                     : "line integrals as stored";
    }
    x.view.name = path.filename().string();
    return x;
}

// ---- An image with fvr-render's JSON sidecar ---------------------------------------------------

Json readSidecar(const fs::path& image, const fs::path& sidecar) {
    std::ifstream in(sidecar);
    if (!in)
        failLoad(image, "no camera sidecar " + sidecar.filename().string() +
                            " beside it (fvr-render --geometry cone writes FILE.json with the "
                            "image): an image without its geometry cannot be registered");
    try {
        return Json::parse(in);
    } catch (const std::exception& e) {
        failLoad(sidecar, std::string("not JSON: ") + e.what());
    }
}

glm::dvec3 vec3Of(const Json& j, const char* key, const fs::path& sidecar) {
    if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3)
        failLoad(sidecar, std::string("\"") + key + "\": expected 3 numbers");
    glm::dvec3 v;
    for (int k = 0; k < 3; ++k) {
        if (!j[key][std::size_t(k)].is_number())
            failLoad(sidecar, std::string("\"") + key + "\": expected 3 numbers");
        v[k] = j[key][std::size_t(k)].get<double>();
    }
    return v;
}

glm::dvec2 vec2Of(const Json& j, const char* key, const fs::path& sidecar) {
    if (!j.contains(key) || !j[key].is_array() || j[key].size() != 2 || !j[key][0].is_number() ||
        !j[key][1].is_number())
        failLoad(sidecar, std::string("\"") + key + "\": expected 2 numbers");
    return {j[key][0].get<double>(), j[key][1].get<double>()};
}

ConeCamera sidecarCamera(const Json& views, int frame, const fs::path& sidecar) {
    const Json& v = views[std::size_t(frame)];
    if (!v.is_object() || !v.contains("source_mm"))
        failLoad(sidecar, "no cone-beam camera in views[" + std::to_string(frame) +
                              "] (a parallel-beam render?): registration needs the cone-beam "
                              "geometry (fvr-render --geometry cone)");
    if (!v.contains("width") || !v["width"].is_number_integer() || !v.contains("height") ||
        !v["height"].is_number_integer())
        failLoad(sidecar, "views[" + std::to_string(frame) + "]: no integer width and height");
    const glm::dvec2 pitch = vec2Of(v, "pitch_mm", sidecar);
    const glm::dvec2 offset = v.contains("principal_offset_px")
                                  ? vec2Of(v, "principal_offset_px", sidecar)
                                  : glm::dvec2(0);
    try {
        return coneCamera(vec3Of(v, "source_mm", sidecar), vec3Of(v, "detector_centre_mm", sidecar),
                          vec3Of(v, "u", sidecar), vec3Of(v, "v", sidecar), v["width"].get<int>(),
                          v["height"].get<int>(), pitch.x, pitch.y, offset);
    } catch (const SettingsError& e) {
        failLoad(sidecar, "views[" + std::to_string(frame) + "]: " + e.what());
    }
}

/** The image's frame `frame`: .npy (rows, cols) or (count, rows, cols), .pfm, .png. */
std::vector<float> imageFrame(const fs::path& path, const std::string& ext, int frame, int& rows,
                              int& cols) {
    int frames = 1;
    std::vector<float> pixels;
    if (ext == ".npy") {
        std::vector<std::int64_t> shape;
        pixels = readNpy(path, shape);
        if (shape.size() != 2 && shape.size() != 3)
            failLoad(path, "expected an image (rows, cols) or a stack (count, rows, cols)");
        frames = shape.size() == 3 ? int(shape[0]) : 1;
        rows = int(shape[shape.size() - 2]);
        cols = int(shape[shape.size() - 1]);
    } else if (ext == ".pfm") {
        pixels = readPfm(path, rows, cols);
    } else {
        pixels = readPng(path, rows, cols);
    }
    if (frame < 0 || frame >= frames)
        failLoad(path, "frame " + std::to_string(frame) + " out of range: the file holds " +
                           std::to_string(frames) + " frame(s)");
    const std::size_t n = std::size_t(rows) * std::size_t(cols);
    return {pixels.begin() + std::ptrdiff_t(n * std::size_t(frame)),
            pixels.begin() + std::ptrdiff_t(n * (std::size_t(frame) + 1))};
}

/** The sidecar's output quantity: line integrals; transmitted intensities (Beer-Lambert:
 *  exposure x exp(-mu L)) whose -ln(I / exposure) / mu gives the line integrals back; or a
 *  polychromatic render's I/I0 (relative to the open beam: I0 = 1). A PNG holds display levels:
 *  of the line integrals, or of -ln(I/I0) for a polychromatic render (both taken as line
 *  integrals), or a film's densities for Beer-Lambert (refused). */
void sidecarValues(XrayInput& x, const Json& j, const std::string& ext, XrayValues values,
                   const fs::path& sidecar) {
    const Json out = j.value("output", Json::object());
    const std::string quantity = out.is_object() ? out.value("values", std::string()) : "";
    const bool transmission = quantity == "transmission";
    const bool relative = quantity.rfind("I/I0", 0) == 0;
    if (ext == ".png") {
        if (transmission)
            failLoad(x.file, "a PNG of a Beer-Lambert render holds film densities, not "
                             "intensities: register its .npy or .pfm output");
        x.warnings.push_back("PNG: display levels of the line integrals (the render's window), "
                             "clipped outside it; .npy or .pfm keeps the values");
    }
    XrayValues v = values;
    if (v == XrayValues::Auto)
        v = (transmission || relative) && ext != ".png" ? XrayValues::Intensity
                                                        : XrayValues::LineIntegrals;
    if (v == XrayValues::LineIntegrals) {
        x.valuesNote =
            "line integrals as stored (" +
            (quantity.empty() ? std::string("the sidecar states no quantity") : quantity) +
            (ext == ".png" ? ", PNG display levels" : "") + ")";
        return;
    }
    const double mu = out.is_object() ? out.value("mu_water_per_mm", 0.0) : 0.0;
    const double exposure = out.is_object() ? out.value("exposure", 0.0) : 0.0;
    if (transmission && mu > 0.0 && exposure > 0.0)
        intensityToLineIntegrals(x, exposure, mu,
                                 "the exposure " + sidecar.filename().string() + " states");
    else if (relative)
        intensityToLineIntegrals(x, 1.0, 1.0, "the open beam, as " + quantity);
    else
        intensityToLineIntegrals(x, 0.0, 1.0, "the 99.5th percentile of the frame");
}

std::string sidecarFrame(const Json& j) {
    if (!j.contains("volume") || !j["volume"].is_object()) return {};
    Json v = j["volume"];
    v.erase("units");
    return "volume " + v.dump();
}

/** Where an image's camera is: its own sidecar FILE.json (the view of its frame), or, for one of
 *  the numbered files STEM_NNNN.EXT that fvr-render writes for several views unstacked, the
 *  sidecar STEM.EXT.json whose "output" "files" list names it (the view at that place). */
struct SidecarRef {
    fs::path sidecar;
    int view = -1; ///< -1: the frame's
};

SidecarRef findSidecar(const fs::path& path) {
    const fs::path own = path.string() + ".json";
    const std::string stem = path.stem().string();
    const std::size_t us = stem.rfind('_');
    if (fs::exists(own) || us == std::string::npos || us + 5 > stem.size() ||
        stem.find_first_not_of("0123456789", us + 1) != std::string::npos)
        return {own};
    const fs::path base =
        path.parent_path() / (stem.substr(0, us) + path.extension().string() + ".json");
    std::ifstream in(base);
    if (!in) return {own};
    try {
        const Json j = Json::parse(in);
        const Json files = j.at("output").at("files");
        for (std::size_t k = 0; k < files.size(); ++k)
            if (files[k].get<std::string>() == path.filename().string()) return {base, int(k)};
    } catch (const std::exception&) {
        // Not a sidecar that lists this file: the image's own is missing then.
    }
    return {own};
}

XrayInput readSidecarXray(const fs::path& path, const std::string& ext, XrayValues values,
                          int frame) {
    const SidecarRef ref = findSidecar(path);
    const fs::path& sidecar = ref.sidecar;
    const Json j = readSidecar(path, sidecar);
    if (!j.is_object() || !j.contains("views") || !j["views"].is_array() || j["views"].empty())
        failLoad(sidecar, "no \"views\" list: not an fvr-render sidecar");
    if (j.value("geometry", std::string()) != "cone")
        failLoad(sidecar, "a parallel-beam render (no \"geometry\": \"cone\"): registration needs "
                          "the cone-beam camera (fvr-render --geometry cone)");
    const Json& views = j["views"];
    // A stack holds one image per view; a single image is the first view's.
    const int view = ref.view >= 0 ? ref.view : frame;
    if (view < 0 || std::size_t(view) >= views.size())
        failLoad(path, "frame " + std::to_string(frame) +
                           " out of range: " + sidecar.filename().string() + " lists " +
                           std::to_string(views.size()) + " view(s)");
    XrayInput x;
    x.file = path;
    x.frame = frame;
    x.view.camera = sidecarCamera(views, view, sidecar);
    int rows = 0, cols = 0;
    x.view.image = imageFrame(path, ext, frame, rows, cols);
    if (rows != x.view.camera.height || cols != x.view.camera.width)
        failLoad(path, std::to_string(cols) + " x " + std::to_string(rows) + " pixels, but " +
                           sidecar.filename().string() + "'s camera has " +
                           std::to_string(x.view.camera.width) + " x " +
                           std::to_string(x.view.camera.height));
    checkFinite(path, x.view.image);
    sidecarValues(x, j, ext, values, sidecar);
    x.frameOfReference = sidecarFrame(j);
    x.view.name = path.filename().string();
    return x;
}

} // namespace

XrayInput readXrayInput(const fs::path& path, const glm::dvec3& isocentre, XrayValues values,
                        int frame) {
    if (!fs::is_regular_file(path)) failLoad(path, "no such file");
    const std::string ext = asciiLower(path.extension().string());
    if (ext == ".npy" || ext == ".pfm" || ext == ".png")
        return readSidecarXray(path, ext, values, frame);
    return readDicomXray(path, isocentre, values, frame);
}

void checkSameFrame(const std::vector<XrayInput>& inputs) {
    auto kind = [](const std::string& s) { return s.substr(0, s.find(' ')); };
    for (std::size_t i = 0; i < inputs.size(); ++i)
        for (std::size_t k = i + 1; k < inputs.size(); ++k) {
            const XrayInput &a = inputs[i], &b = inputs[k];
            const std::string both = a.file.string() + " and " + b.file.string();
            if (!a.patientId.empty() && !b.patientId.empty() && a.patientId != b.patientId)
                throw SettingsError(both + ": different patients (PatientID '" + a.patientId +
                                    "' and '" + b.patientId + "')");
            if (!a.frameOfReference.empty() && !b.frameOfReference.empty() &&
                kind(a.frameOfReference) == kind(b.frameOfReference) &&
                a.frameOfReference != b.frameOfReference)
                throw SettingsError(both + ": images of different frames (" + a.frameOfReference +
                                    " and " + b.frameOfReference +
                                    "): the views of one registration must show one CT's frame");
        }
}

// ---- Overlays ---------------------------------------------------------------------------------

namespace {

/** The image windowed on its own 1st-99th percentiles to [0, 1]. */
std::vector<float> windowed(const std::vector<float>& image) {
    const double lo = quantile(image, 0.01), hi = quantile(image, 0.99);
    const double span = hi > lo ? hi - lo : 1.0;
    std::vector<float> out(image.size());
    for (std::size_t k = 0; k < image.size(); ++k) {
        const double t = std::isfinite(image[k]) ? (image[k] - lo) / span : 0.0;
        out[k] = float(std::clamp(t, 0.0, 1.0));
    }
    return out;
}

std::uint8_t byte(double t) { return std::uint8_t(std::lround(std::clamp(t, 0.0, 1.0) * 255.0)); }

} // namespace

/** "blend": the X-ray in green and the DRR in magenta (red and blue), each windowed on its own,
 *  as the workstation's Register to X-ray shows them: where the two agree the pixel is grey, where
 *  they are offset the edges show green on one side and magenta on the other. "checkerboard":
 *  squares of `square` pixels, the X-ray's grey and the DRR's grey in turn (the top-left square
 *  the X-ray's), so that edges run on unbroken across the squares' borders when the two match. */
void writeOverlayPng(const fs::path& path, const std::string& kind, const std::vector<float>& xray,
                     const std::vector<float>& drr, int width, int height, int square) {
    const std::size_t n = std::size_t(width) * std::size_t(height);
    if (width < 1 || height < 1 || xray.size() != n || drr.size() != n)
        throw SettingsError(path.string() + ": overlay images must both be " +
                            std::to_string(width) + " x " + std::to_string(height));
    if (kind != "blend" && kind != "checkerboard")
        throw SettingsError(path.string() + ": overlay '" + kind +
                            "': expected blend or checkerboard");
    if (square < 1) throw SettingsError(path.string() + ": checkerboard square must be >= 1");
    const std::vector<float> x = windowed(xray), d = windowed(drr);
    std::vector<std::uint8_t> rgb(n * 3);
    if (kind == "blend") {
        for (std::size_t k = 0; k < n; ++k) {
            rgb[3 * k] = rgb[3 * k + 2] = byte(d[k]);
            rgb[3 * k + 1] = byte(x[k]);
        }
    } else {
        for (int y = 0; y < height; ++y)
            for (int c = 0; c < width; ++c) {
                const std::size_t k = std::size_t(y) * std::size_t(width) + std::size_t(c);
                const bool fromXray = ((c / square) + (y / square)) % 2 == 0;
                rgb[3 * k] = rgb[3 * k + 1] = rgb[3 * k + 2] = byte(fromXray ? x[k] : d[k]);
            }
    }
    writePngRgb(path, rgb.data(), height, width);
}

} // namespace fvr::core
