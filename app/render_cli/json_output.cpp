// fvr-render's JSON documents, built with nlohmann-json.
#include "json_output.h"

#include <fvr/core/io/open_study.h>

#include <charconv>
#include <iostream>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/voxel_model.h>

namespace fvr::cli {
namespace {

Json dimsJson(const core::Dims3& d) { return Json::array({d[0], d[1], d[2]}); }
Json vecJson(const core::Vec3& v) { return Json::array({v[0], v[1], v[2]}); }
Json directionJson(const glm::dmat3& m) { // a list of the index axes (columns)
    return Json::array({vecJson(m[0]), vecJson(m[1]), vecJson(m[2])});
}

Json seriesJson(const core::DicomSeriesInfo& s) {
    return Json{{"key", s.key},
                {"series_uid", s.seriesUid},
                {"patient_name", s.patientName},
                {"patient_id", s.patientId},
                {"study_date", s.studyDate},
                {"modality", s.modality},
                {"description", s.description},
                {"transfer_syntax", s.transferSyntax},
                {"images", s.imageCount},
                {"frames", s.frameCount},
                {"dims", dimsJson(s.dims)},
                {"spacing_mm", vecJson(s.spacing)},
                {"loadable", s.loadable()},
                {"unloadable_reason", s.unloadableReason},
                {"warnings", s.warnings}};
}

} // namespace

double floatValue(float f) {
    char buf[32];
    const auto end = std::to_chars(buf, buf + sizeof buf, f).ptr;
    double d = f;
    std::from_chars(buf, end, d); // inf and nan stay as they are (written as null)
    return d;
}

Json volumeInfoJson(const core::Volume& v) {
    const auto [lo, hi] = v.valueRange();
    return Json{{"name", v.name},
                {"dims", dimsJson(v.dims)},
                {"spacing_mm", vecJson(v.spacing)},
                {"origin_mm", vecJson(v.origin)},
                {"direction", directionJson(v.direction)},
                {"units", core::unitsName(v.units)},
                {"value_range", Json::array({floatValue(lo), floatValue(hi)})},
                {"extent_mm", vecJson(v.extent())}};
}

Json seriesListJson(const core::DicomScanResult& scan) {
    Json series = Json::array();
    const std::size_t byDefault = scan.series.empty() ? 0 : core::defaultSeriesIndex(scan);
    for (std::size_t i = 0; i < scan.series.size(); ++i) {
        Json s = seriesJson(scan.series[i]);
        s["default"] = i == byDefault; // what fvr-render and the workstation open without --series
        series.push_back(std::move(s));
    }
    return Json{{"series", series}, {"skipped", scan.skipped}, {"warnings", scan.warnings}};
}

Json settingsJson(const RunFacts& run) {
    const Options& o = run.options;
    const core::Spectrum& s = run.spectrum;
    return Json{{"input", o.input},
                {"backend", run.backend},
                {"kernel", core::kernelName(o.settings.kernel)},
                {"transform", core::transformName(o.settings.transform)},
                {"size", o.settings.size},
                {"height", o.settings.height > 0 ? o.settings.height : o.settings.size},
                {"pixel_size_mm", run.pixelSize},
                {"oversampling", o.settings.oversampling},
                {"values", core::valueMappingName(o.settings.values)},
                {"deapodized", s.deapodizedFor.has_value()},
                {"volume_dims", dimsJson(s.volumeDims)},
                {"padded_dims", dimsJson(s.padded)},
                {"spectrum_mb", double(s.bytes()) / (1 << 20)},
                {"threads", run.threads},
                {"voxel_model", core::voxelModelName(o.settings.voxelModel)},
                {"pixel_aperture", o.settings.pixelAperture},
                {"non_negative", o.settings.nonNegative && s.nonNegative},
                {"clip_to_volume", o.settings.clip},
                {"depth_cue", o.settings.depthCue},
                {"filter",
                 {{"sharpen", o.settings.filter.sharpenAmount},
                  {"sharpen_radius_mm", o.settings.filter.sharpenSigmaMm},
                  {"band_limit_lp_per_mm", o.settings.filter.bandLimitLpMm}}}};
}

Json volumeBlockJson(const core::Volume& volume) {
    return Json{{"name", volume.name},
                {"dims", dimsJson(volume.dims)},
                {"spacing_mm", vecJson(volume.spacing)},
                {"origin_mm", vecJson(volume.origin)},
                {"direction", directionJson(volume.direction)},
                {"units", core::unitsName(volume.units)}};
}

Json outputBlockJson(const Options& o, const WrittenOutput& output) {
    return Json{{"values", output.values},
                {"mu_water_per_mm", o.beerLambert ? o.transmission.muWaterPerMm : 0.0},
                {"energy_kev", o.beerLambert && !o.settings.muWaterPerMm
                                   ? Json(o.settings.energyKeV)
                                   : Json(nullptr)},
                {"exposure", o.beerLambert ? o.transmission.exposure : 0.0},
                {"stacked", output.stacked},
                {"files", output.files},
                {"preprocess_ms", output.preprocessMs},
                {"render_ms_per_view", output.renderMsPerView}};
}

Json sidecarJson(const RunFacts& run, const core::Volume& volume, const WrittenOutput& output,
                 const std::vector<core::ViewFrame>& views) {
    const Options& o = run.options;
    Json viewList = Json::array();
    for (const auto& v : views)
        viewList.push_back({{"dir", vecJson(v.d)}, {"up", vecJson(v.u)}, {"right", vecJson(v.r)}});
    const int width = o.settings.size, height = o.settings.height > 0 ? o.settings.height : width;
    Json image{{"width", width},
               {"height", height},
               {"pixel_size_mm", run.pixelSize},
               {"pixel", "(col, row) is the line integral along dir through centre + (col - W/2) d "
                         "right - (row - H/2) d up (W/2, H/2: integer halves)"}};
    if (width == height) image["size"] = width; // M, as square images always said
    return Json{{"generator", "fvr-render"},
                {"settings", settingsJson(run)},
                {"volume", volumeBlockJson(volume)},
                {"output", outputBlockJson(o, output)},
                {"image", image},
                {"views", viewList}};
}

namespace {

std::string scalarText(const Json& j) {
    // Bytes that are not UTF-8 (a DICOM name in Latin-1, say) become U+FFFD instead of failing.
    return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

/** Text on one line: "[1, 2]", "{"a": 1, "b": [1, 2]}". */
std::string inlineText(const Json& j) {
    if (!j.is_structured()) return scalarText(j);
    std::string out = j.is_array() ? "[" : "{";
    for (auto it = j.begin(); it != j.end(); ++it) {
        if (it != j.begin()) out += ", ";
        if (j.is_object()) out += scalarText(Json(it.key())) + ": ";
        out += inlineText(*it);
    }
    out += j.is_array() ? ']' : '}';
    return out;
}

/** Arrays of numbers (or of arrays of numbers) and short objects of such values fit on a line. */
bool fitsOnALine(const Json& j) {
    if (!j.is_structured()) return true;
    for (const auto& e : j)
        if ((e.is_object() && j.is_array()) || !fitsOnALine(e)) return false;
    return !j.is_object() || inlineText(j).size() <= 100;
}

void writeIndented(std::string& out, const Json& j, int indent) {
    if (fitsOnALine(j) || j.empty()) {
        out += inlineText(j);
        return;
    }
    const std::string pad(std::size_t(indent) + 2, ' ');
    out += j.is_array() ? "[\n" : "{\n";
    for (auto it = j.begin(); it != j.end(); ++it) {
        if (it != j.begin()) out += ",\n";
        out += pad;
        if (j.is_object()) out += scalarText(Json(it.key())) + ": ";
        writeIndented(out, *it, indent + 2);
    }
    out += '\n';
    out.append(std::size_t(indent), ' ');
    out += j.is_array() ? ']' : '}';
}

} // namespace

std::string jsonText(const Json& j) {
    std::string out;
    writeIndented(out, j, 0);
    out += '\n';
    return out;
}

void printJson(const Json& j) { std::cout << jsonText(j) << std::flush; }

} // namespace fvr::cli
