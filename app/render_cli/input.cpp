// fvr-render's INPUT: the path (or phantom name) to a volume by core's rule (io/open_study.h),
// the same rule the workstation follows.
#include "input.h"

#include <fvr/core/io/open_study.h>
#include <fvr/core/pacs/dicom_url.h>

#include "pacs.h"

namespace fvr::cli {

LoadedInput loadInput(const Options& o) {
    using namespace fvr::core;
    // A study on a PACS: retrieved into the local store, then a folder like any other.
    InputSource source =
        classifyInput(pacs::isDicomUrl(o.input) ? retrieveInput(o).string() : o.input);
    if (o.raw && source.kind == InputKind::DicomFolder)
        throw SettingsError("--raw-dims: " + o.input + " is a folder, not a raw file");
    LoadedInput in;
    OpenOptions options;
    options.seriesKey = o.series;
    options.raw = o.raw;
    if (source.kind == InputKind::DicomFolder) {
        auto scan = std::make_shared<const DicomScanResult>(scanDicomFolder(source.path));
        if (o.info && o.series.empty()) { // list the series (the default one marked), no volume
            in.seriesList = *scan;
            return in;
        }
        options.scan = std::move(scan);
    }
    OpenedStudy study = openStudy(source, options);
    in.warnings = std::move(study.warnings);
    in.exportInfo = exportInfoFor(study.series);
    in.volume = std::move(study.volume);
    return in;
}

} // namespace fvr::cli
