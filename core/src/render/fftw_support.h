#pragma once
// Internal: process-wide FFTW state. FFTW's planner is not thread-safe; every plan creation and
// destruction goes through planMutex(). Wisdom is loaded once and saved after new plans.
#include <fftw3.h>

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>

#include <fvr/core/render/fftw_planning.h>

namespace fvr::core::detail {

/** Initialises FFTW threads and loads the wisdom file once. */
void ensureFftwInitialised();
std::mutex& planMutex();
/** Saves wisdom to disk if plans were added since the last save (ignores write failures: the
 *  cache is an optimisation). */
void saveWisdom();
unsigned plannerFlags(bool measure);

/** Destroys `plan` on the background planner, after the plan it is making. */
void destroyLater(fftwf_plan plan);

/** RAII owner of an fftwf_plan. */
class Plan {
public:
    Plan() = default;
    explicit Plan(fftwf_plan p) : m_plan(p) {}
    Plan(Plan&& o) noexcept : m_plan(o.m_plan) { o.m_plan = nullptr; }
    Plan& operator=(Plan&& o) noexcept {
        if (this != &o) {
            reset();
            m_plan = o.m_plan;
            o.m_plan = nullptr;
        }
        return *this;
    }
    ~Plan() { reset(); }
    /** Destroys the plan now, or, while another thread plans (the background planner measures
     *  for up to seconds), hands it to the background planner (destroyLater): a renderer never
     *  waits for a plan it does not need. Never call with planMutex() held. */
    void reset() {
        if (!m_plan) return;
        if (std::unique_lock lock(planMutex(), std::try_to_lock); lock.owns_lock())
            fftwf_destroy_plan(m_plan);
        else
            destroyLater(m_plan);
        m_plan = nullptr;
    }
    fftwf_plan get() const { return m_plan; }
    explicit operator bool() const { return m_plan != nullptr; }

private:
    fftwf_plan m_plan = nullptr;
};

/** A plan made now, and whether its measured version is still to be made (background). */
struct QuickPlan {
    fftwf_plan plan = nullptr;
    bool measureLater = false;
};

/** With planMutex() held: `make(flags)` planned as the policy says. measure = false: ESTIMATE.
 *  measure = true: from wisdom when wisdom has the problem (FFTW_WISDOM_ONLY); else MEASURE at
 *  once (FftwPlanning::Foreground) or ESTIMATE now, with measureLater set for Background. */
template <class Make>
QuickPlan planQuickly(bool measure, Make&& make) {
    if (!measure) return {make(FFTW_ESTIMATE), false};
    if (fftwPlanning() == FftwPlanning::Foreground) return {make(plannerFlags(true)), false};
    if (fftwf_plan p = make(FFTW_MEASURE | FFTW_WISDOM_ONLY)) return {p, false};
    return {make(FFTW_ESTIMATE), fftwPlanning() == FftwPlanning::Background};
}

/** Runs `job` on the process-wide background planning thread once the process has been quiet
 *  for a while (noteBusy, setPlannerQuietPeriod), then saves wisdom: measuring competes for the
 *  cores with the work at hand (2 cores) and measures badly meanwhile, and a measured plan saves
 *  only a few percent over the ESTIMATE one in use. The job makes its MEASURE plans on buffers
 *  of its own, under planMutex(). The thread is never joined: a process may end with a plan
 *  half made (its wisdom is then not saved). */
void planInBackground(std::function<void()> job);
/** Marks the process busy now (renderers per frame, the preprocessing): planning waits. */
void noteBusy();

/** A measured plan handed from the background planner to the thread that renders: set() once
 *  by the planner, take() by the owner after ready(). */
class PlanSlot {
public:
    bool ready() const { return m_ready.load(std::memory_order_acquire); }
    void set(fftwf_plan p) {
        m_plan = Plan(p);
        m_ready.store(true, std::memory_order_release);
    }
    Plan take() { return std::move(m_plan); }

private:
    Plan m_plan;
    std::atomic<bool> m_ready{false};
};

} // namespace fvr::core::detail
