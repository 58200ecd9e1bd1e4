#pragma once
/** What the steps after preprocessing share: the volume, its spectrum, the renderer and the
 *  settings every view is rendered with. */
#include <memory>
#include <vector>

#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/render/renderer.h>
#include <fvr/core/volume.h>

#include "backend.h"
#include "json_output.h"
#include "options.h"

namespace fvr::cli {

struct Session {
    const Options& options;
    const core::Volume& volume;
    std::shared_ptr<const core::Spectrum> spectrum;
    double preprocessMs = 0.0;
    core::ImageGeometry geometry;
    int threads = 0; ///< resolved (--threads, else all cores)
    core::ViewFrame base; ///< --view, else --dir/--up
    RenderBackend& backend;

    /** Every view is rendered with the same settings (the CPU and the GPU renderer take the
     *  same). */
    core::RenderParams params(const core::ViewFrame& view) const;
    RunFacts facts() const;
};

/** --bench: times the frames, ray-casts the same views and prints all of it as JSON. */
void runBench(const Session& s);

/** Views from --views FILE: "dx dy dz ux uy uz" per line. Throws SettingsError naming
 *  file:line, LoadError where the file cannot be read. */
std::vector<core::ViewFrame> readViewsFile(const std::string& path);
/** The views --out renders: --sweep's N views about --axis (default the head-feet axis) from
 *  `base` (from AP where the default view looks along the axis; SettingsError for a view of the
 *  user's own along it: every view would be one projection turned), the views file, else `base`.
 */
std::vector<core::ViewFrame> outputViews(const Options& o, const core::Volume& volume,
                                         const core::ViewFrame& base,
                                         const std::vector<core::ViewFrame>& fileViews);

/** --out: renders `views` (outputViews), writes the images and the JSON sidecar FILE.json, all
 *  or nothing (output_files.h: staged beside FILE, committed together once all are written; an
 *  interruption or a write error leaves an earlier run's files as they were), and says what it
 *  wrote on stderr. */
void writeOutputs(const Session& s, const std::vector<core::ViewFrame>& views,
                  const core::DicomExportInfo& exportInfo);

} // namespace fvr::cli
