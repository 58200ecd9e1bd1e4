#pragma once
/** fvr-render's INPUT: a path or phantom name to a volume. */
#include <optional>

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
};

/** Opens INPUT: phantom:shepp-logan[:N], a raw file (--raw-dims), a DICOM folder (the series of
 *  --series, else the one with most slices), one DICOM file, or a volume file. Prints the
 *  loaders' warnings on stderr. Throws InputError for bad input. */
LoadedInput loadInput(const Options& o);

} // namespace fvr::cli
