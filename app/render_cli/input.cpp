// fvr-render's INPUT: the one place that turns the path (or phantom name) into a volume.
#include "input.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <fvr/core/errors.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/xray/phantom.h>

namespace fvr::cli {
namespace {

using namespace fvr::core;

void printWarnings(const std::vector<std::string>& warnings) {
    for (const auto& w : warnings) std::fprintf(stderr, "fvr-render: warning: %s\n", w.c_str());
}

int parsePhantomSize(const std::string& s) {
    const std::string what = "phantom size";
    double v = 0;
    try {
        std::size_t pos = 0;
        v = std::stod(s, &pos);
        if (pos != s.size() || !std::isfinite(v)) throw std::invalid_argument(s);
    } catch (const std::exception&) {
        throw SettingsError(what + ": expected a number, found '" + s + "'");
    }
    if (v != std::floor(v) || std::abs(v) > 1e9)
        throw SettingsError(what + ": expected an integer, found '" + s + "'");
    return int(v);
}

Volume loadPhantom(const std::string& rest) {
    const auto colon = rest.find(':');
    const std::string kind = rest.substr(0, colon);
    if (kind != "shepp-logan")
        throw SettingsError("INPUT: unknown phantom '" + kind + "' (expected shepp-logan)");
    const int n = colon == std::string::npos ? 128 : parsePhantomSize(rest.substr(colon + 1));
    return makeSheppLoganVolume(n);
}

LoadedInput loadDicomFolder(const Options& o, const std::filesystem::path& path) {
    LoadedInput in;
    auto scan = scanDicomFolder(path);
    if (o.info && o.series.empty()) {
        in.seriesList = std::move(scan);
        return in;
    }
    const DicomSeriesInfo* chosen = nullptr;
    for (const auto& s : scan.series)
        if (o.series.empty() ? (!chosen || s.frameCount > chosen->frameCount)
                             : (s.key == o.series || s.seriesUid == o.series))
            chosen = &s;
    if (!chosen) throw LoadError(o.input + ": series '" + o.series + "' not found (see --info)");
    if (o.series.empty() && scan.series.size() > 1)
        std::fprintf(stderr,
                     "fvr-render: %zu series in %s; using %s (%d slices); pick one with --series\n",
                     scan.series.size(), o.input.c_str(), chosen->key.c_str(), chosen->frameCount);
    auto loaded = loadDicomSeries(*chosen);
    printWarnings(loaded.warnings);
    in.exportInfo.patientName = chosen->patientName;
    in.exportInfo.patientId = chosen->patientId;
    in.exportInfo.studyInstanceUid = chosen->studyUid;
    in.volume = std::move(loaded.volume);
    return in;
}

} // namespace

LoadedInput loadInput(const Options& o) {
    const std::string prefix = "phantom:";
    LoadedInput in;
    if (o.input.rfind(prefix, 0) == 0) {
        in.volume = loadPhantom(o.input.substr(prefix.size()));
        return in;
    }
    if (o.raw) {
        in.volume = loadRaw(o.input, *o.raw);
        return in;
    }
    const std::filesystem::path path(o.input);
    if (std::filesystem::is_directory(path)) return loadDicomFolder(o, path);
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == ".dcm" || ext == ".dicom" || ext.empty()) {
        auto loaded = loadDicomFile(path);
        printWarnings(loaded.warnings);
        in.volume = std::move(loaded.volume);
        return in;
    }
    in.volume = loadVolume(path);
    return in;
}

} // namespace fvr::cli
