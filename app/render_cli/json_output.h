#pragma once
/** fvr-render's JSON: --info, the DICOM series list, the settings record of --bench and of the
 *  sidecar, and the sidecar itself. Written with nlohmann-json: numbers at full precision (they
 *  read back to the same double), a number that is not finite as null. */
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>
#include <fvr/core/volume.h>

#include "options.h"

namespace fvr::cli {

using Json = nlohmann::ordered_json; ///< keys in the order written

/** --info: name, dims, spacing_mm, origin_mm, direction, units, value_range, extent_mm. A
 *  value range with an infinite end (a float volume holding inf) gives null there. */
Json volumeInfoJson(const core::Volume& v);

/** --info on a DICOM folder: {"series": [...], "skipped": [...]}. */
Json seriesListJson(const core::DicomScanResult& scan);

/** What a run rendered with: the options, the spectrum's facts and the resolved pixel size,
 *  threads and backend name. */
struct RunFacts {
    const Options& options;
    const core::Spectrum& spectrum;
    double pixelSize = 0.0;
    int threads = 0;
    std::string backend;
};

/** The "settings" object of --bench and of the sidecar. */
Json settingsJson(const RunFacts& run);

/** The sidecar FILE.json's "output" object's own facts. */
struct WrittenOutput {
    std::string values; ///< what the pixels hold (units)
    bool stacked = false;
    std::vector<std::string> files;
    double preprocessMs = 0.0;
    double renderMsPerView = 0.0;
};

/** The sidecar's "volume" object: name, dims, spacing, origin, direction, units. */
Json volumeBlockJson(const core::Volume& volume);
/** The sidecar's "output" object: the values, the transmission's beam, the files, the times. */
Json outputBlockJson(const Options& o, const WrittenOutput& output);

/** The sidecar FILE.json: every parameter and view, so the output can be reproduced and
 *  registered (origin and spacing at full precision). */
Json sidecarJson(const RunFacts& run, const core::Volume& volume, const WrittenOutput& output,
                 const std::vector<core::ViewFrame>& views);

/** `j` as text, indented, with a final newline (bytes that are not UTF-8 replaced). */
std::string jsonText(const Json& j);

/** Prints `j` on stdout, indented, with a final newline. */
void printJson(const Json& j);

/** The shortest decimal that reads back as `f`, as a double (3.2f -> 3.2, not 3.2000000477). */
double floatValue(float f);

} // namespace fvr::cli
