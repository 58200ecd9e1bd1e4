#pragma once
/** fvr-render's run: load, preprocess, then --info, --bench and --out in that order. */
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/renderer.h>

#include "options.h"

namespace fvr::cli {

/** Runs the checked options; returns the exit status. Throws InputError for bad input (exit
 *  status 2) and other exceptions for other failures (1). */
int run(const Options& o);

/** The options with the settings for this volume (core::RenderSettings::forVolume: raw values
 *  for data that are not Hounsfield units, said on stderr where --values asked otherwise);
 *  SettingsError where --beer-lambert then has no attenuation. */
Options resolvedForVolume(const Options& asked, const core::Volume& volume);

/** fvr-render's rules from settings to the core's parameters, shared with the Python module: */
/** The spectrum's settings: --values, --transform, --oversampling, --threads, and gridding
 *  correction for --kernel where --deapodize says so, else where it helps (the workstation's
 *  rule, core::griddingCorrectionHelps). */
core::PreprocessOptions preprocessOptions(const Options& o);
/** The view of --view, else of --dir/--up. */
core::ViewFrame baseView(const Options& o, const core::Volume& volume);
/** --size and --pixel-size (default: core::defaultPixelSize), checked (SettingsError). */
core::ImageGeometry imageGeometry(const Options& o, const core::Volume& volume);
/** What every view is rendered with: the options' kernel, model, filter, clipping... */
core::RenderParams renderParams(const Options& o, const core::ViewFrame& view,
                                const core::ImageGeometry& geometry);

} // namespace fvr::cli
