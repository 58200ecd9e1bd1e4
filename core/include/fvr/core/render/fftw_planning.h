#pragma once
/** How FFTW plans are made (process-wide). FFTW_MEASURE plans execute faster than FFTW_ESTIMATE
 *  ones but take far longer to make (about 0.3 to 2 s each on 2 cores) than to run once. Wisdom
 *  (~/.cache/fvr-workstation/fftwf-wisdom or $FVR_FFTW_WISDOM) holds the measured plans of
 *  earlier runs. */

#include <chrono>

namespace fvr::core {

enum class FftwPlanning {
    /** Default: a plan from wisdom when wisdom has it; else an FFTW_ESTIMATE plan at once, while
     *  the measured plan is made on a background thread once the process is quiet (the renderer
     *  swaps it in when ready) and saved as wisdom for the next run. A first run on a fresh
     *  machine does not wait. */
    Background,
    /** A plan from wisdom, else FFTW_MEASURE at once on the calling thread (slow first run). */
    Foreground,
    /** A plan from wisdom, else FFTW_ESTIMATE, and nothing measured (for comparisons). */
    EstimateOnly
};

/** The policy in force: FVR_FFTW_PLANNING=background|foreground|estimate when set, else
 *  Background. */
FftwPlanning fftwPlanning();
void setFftwPlanning(FftwPlanning planning);

/** Blocks until the background planner has made (and saved as wisdom) every plan queued so
 *  far. Nothing needs to call it: tests and benchmarks do. */
void finishBackgroundPlanning();
/** How long the process must have been quiet (no frame rendered, no preprocessing) before the
 *  background planner measures (default 2 s): measuring on 2 busy cores would slow the work
 *  at hand and measure badly. Tests set 0 to plan while rendering. */
void setPlannerQuietPeriod(std::chrono::milliseconds quiet);
/** How many measured plans the background planner has made since the process started. */
int backgroundPlansMade();

/** Marks the process busy while it lives: every frame (CPU and GPU renderers) and the
 *  preprocessing hold one. The background planner measures only while none is alive and the last
 *  one ended a quiet period ago (a frame longer than the quiet period does not let it start). */
class PlannerBusyScope {
public:
    PlannerBusyScope();
    ~PlannerBusyScope();
    PlannerBusyScope(const PlannerBusyScope&) = delete;
    PlannerBusyScope& operator=(const PlannerBusyScope&) = delete;
};

} // namespace fvr::core
