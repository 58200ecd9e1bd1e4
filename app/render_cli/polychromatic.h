#pragma once
/** fvr-render --kvp: the polychromatic run. */
#include <vector>

#include <fvr/core/render/view.h>
#include <fvr/core/volume.h>

#include "options.h"

namespace fvr::cli {

/** Preprocesses one spectrum per material, renders `views` (CPU), writes I/I0 (and
 *  --material-out) with the JSON sidecar FILE.json. Returns the exit status. */
int renderPolychromatic(const Options& o, const core::Volume& volume,
                        const std::vector<core::ViewFrame>& views);

} // namespace fvr::cli
