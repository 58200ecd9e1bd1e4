#pragma once
/** fvr-render --geometry cone --kvp: polychromatic cone-beam views. */
#include <vector>

#include <fvr/core/volume.h>

#include "cone.h"
#include "options.h"

namespace fvr::cli {

/** Decomposes INPUT's CT numbers into the materials' density volumes, casts each material's
 *  line integrals per view (--backend's caster per material), writes I/I0 through the spectrum
 *  (and noise, the flat field, --material-out) as the parallel --kvp run does, with the cone
 *  beam's sidecar (the cameras and P) and the "polychromatic" settings. `views` are checked
 *  against the volume already. Returns the exit status. */
int renderConePolychromatic(const Options& o, const core::Volume& volume,
                            const std::vector<ConeView>& views, const ConeFiles& files);

} // namespace fvr::cli
