#pragma once
/** fvr-render's INPUT: a path or phantom name to a volume. */
#include <optional>
#include <string>
#include <vector>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/volume.h>

#include "options.h"

namespace fvr::cli {

struct LoadedInput {
    /** Set for a DICOM folder with --info and no --series: its series, to list (no volume). */
    std::optional<core::DicomScanResult> seriesList;
    std::optional<core::Volume> volume;
    /** Patient and study of a DICOM input, carried into DICOM outputs. */
    core::DicomExportInfo exportInfo;
    /** What the loader said (which series and why, assumptions, the Hounsfield guess). */
    std::vector<std::string> warnings;
};

/** Opens INPUT by core's rule (core::classifyInput, core::openStudy): phantom:chest[:N],
 * phantom:shepp-logan[:N], a raw file (--raw-dims), a DICOM folder or DICOMDIR (the series of
 * --series, else the default series: loadable, then most slices), one DICOM file, or a volume file;
 * values without units that look like CT are taken for HU. Throws InputError. */
LoadedInput loadInput(const Options& o);

} // namespace fvr::cli
