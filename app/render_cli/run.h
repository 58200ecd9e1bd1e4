#pragma once
/** fvr-render's run: load, preprocess, then --info, --bench and --out in that order. */
#include "options.h"

namespace fvr::cli {

/** Runs the checked options; returns the exit status. Throws InputError for bad input (exit
 *  status 2) and other exceptions for other failures (1). */
int run(const Options& o);

} // namespace fvr::cli
