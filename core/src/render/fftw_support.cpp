#include "fftw_support.h"

#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <string>
#include <thread>

#include <unistd.h>

namespace fvr::core {

namespace {
FftwPlanning planningFromEnvironment() {
    const char* e = std::getenv("FVR_FFTW_PLANNING");
    if (e && std::strcmp(e, "foreground") == 0) return FftwPlanning::Foreground;
    if (e && std::strcmp(e, "estimate") == 0) return FftwPlanning::EstimateOnly;
    return FftwPlanning::Background;
}
std::atomic<FftwPlanning>& planningPolicy() {
    static std::atomic<FftwPlanning> p{planningFromEnvironment()};
    return p;
}

using Clock = std::chrono::steady_clock;
/** The last time a renderer or the preprocessing was at work (noteBusy). */
std::atomic<Clock::rep> g_lastBusy{0};
/** Frames (and preprocessing runs) at work now (PlannerBusyScope). */
std::atomic<int> g_active{0};
/** How long the process must have rendered nothing before a planning job starts (ms): longer
 *  than the pauses inside a batch (fvr-render probes the GPU between the preprocessing and the
 *  first frame: ~0.5 s on a busy machine), short against a user's pause in the workstation. */
std::atomic<long> g_quietMs{2000};

/** One worker thread, started on the first job and never joined (the object is never
 *  destroyed, so a job still running at exit touches nothing that was). Urgent jobs (plans to
 *  destroy) run first and at once; the others wait until the process has been quiet for
 *  g_quietMs (planInBackground). */
class BackgroundPlanner {
public:
    /** plans: the job makes a plan (counted by made()), else it only destroys one. */
    void enqueue(std::function<void()> job, bool urgent, bool plans = true) {
        std::lock_guard lock(m_mutex);
        (urgent ? m_urgent : m_whenIdle).push_back({std::move(job), plans});
        if (!m_started) {
            m_started = true;
            std::thread([this] { run(); }).detach();
        }
        m_wake.notify_one();
    }
    void finish() {
        std::unique_lock lock(m_mutex);
        m_idle.wait(lock, [this] { return empty() && !m_busy; });
    }
    int made() {
        std::lock_guard lock(m_mutex);
        return m_made;
    }

private:
    bool empty() const { return m_urgent.empty() && m_whenIdle.empty(); }

    /** The next job to run, waiting as the queues say (m_mutex held). */
    struct Job {
        std::function<void()> run;
        bool plans = true;
    };

    Job next(std::unique_lock<std::mutex>& lock) {
        for (;;) {
            m_wake.wait(lock, [this] { return !empty(); });
            auto& q = m_urgent.empty() ? m_whenIdle : m_urgent;
            const auto quietSince = Clock::time_point(Clock::duration(g_lastBusy.load()));
            const auto quiet = std::chrono::milliseconds(g_quietMs.load());
            const auto wait =
                g_active.load() > 0 ? Clock::duration(quiet) : quietSince + quiet - Clock::now();
            if (&q == &m_urgent || wait <= Clock::duration::zero()) {
                auto job = std::move(q.front());
                q.pop_front();
                return job;
            }
            m_wake.wait_for(lock, wait); // an urgent job may come meanwhile
        }
    }

    void run() {
        std::unique_lock lock(m_mutex);
        for (;;) {
            auto job = next(lock);
            m_busy = true;
            lock.unlock();
            try {
                job.run();
                detail::saveWisdom();
            } catch (...) { // an optimisation failed (no memory for the scratch buffers)
            }
            const bool plans = job.plans;
            job.run = nullptr; // what it held (a plan slot) goes before m_mutex is taken again
            lock.lock();
            m_busy = false;
            m_made += plans ? 1 : 0;
            if (empty()) m_idle.notify_all();
        }
    }

    std::mutex m_mutex;
    std::condition_variable m_wake, m_idle;
    std::deque<Job> m_urgent, m_whenIdle;
    bool m_started = false, m_busy = false;
    int m_made = 0;
};

BackgroundPlanner& backgroundPlanner() {
    static auto* p = new BackgroundPlanner; // never destroyed (see the class)
    return *p;
}
} // namespace

FftwPlanning fftwPlanning() { return planningPolicy().load(); }
void setFftwPlanning(FftwPlanning planning) { planningPolicy().store(planning); }
void finishBackgroundPlanning() { backgroundPlanner().finish(); }
void setPlannerQuietPeriod(std::chrono::milliseconds quiet) {
    g_quietMs.store(long(quiet.count()));
}
int backgroundPlansMade() { return backgroundPlanner().made(); }

namespace detail {

namespace {
std::filesystem::path wisdomPath() {
    if (const char* p = std::getenv("FVR_FFTW_WISDOM")) return p;
    std::filesystem::path base;
    if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x)
        base = x;
    else if (const char* h = std::getenv("HOME"); h && *h)
        base = std::filesystem::path(h) / ".cache";
    else
        return {};
    return base / "fvr-workstation" / "fftwf-wisdom";
}
/** Plans were measured since the last save (written under planMutex, read before taking it: a
 *  save with nothing to write never waits for the background planner). */
std::atomic<bool> g_dirty{false};
} // namespace

std::mutex& planMutex() {
    // Never destroyed: the background planner may still plan while the process exits.
    static auto* m = new std::mutex;
    return *m;
}

void ensureFftwInitialised() {
    static std::once_flag once;
    std::call_once(once, [] {
        std::lock_guard lock(planMutex());
        fftwf_init_threads();
        const auto p = wisdomPath();
        if (!p.empty() && std::filesystem::exists(p)) fftwf_import_wisdom_from_filename(p.c_str());
        // Bound the time MEASURE planning may take for a new size.
        fftwf_set_timelimit(3.0);
    });
}

unsigned plannerFlags(bool measure) {
    if (measure) {
        g_dirty = true;
        return FFTW_MEASURE;
    }
    return FFTW_ESTIMATE;
}

void saveWisdom() {
    if (!g_dirty.load()) return;
    std::lock_guard lock(planMutex());
    if (!g_dirty.exchange(false)) return;
    const auto p = wisdomPath();
    if (p.empty()) return;
    std::error_code ec;
    std::filesystem::create_directories(p.parent_path(), ec);
    const auto tmp = p.string() + ".tmp" + std::to_string(::getpid());
    if (fftwf_export_wisdom_to_filename(tmp.c_str()))
        std::filesystem::rename(tmp, p, ec);
    else
        std::filesystem::remove(tmp, ec);
}

void planInBackground(std::function<void()> job) {
    backgroundPlanner().enqueue(std::move(job), false);
}

void destroyLater(fftwf_plan plan) {
    backgroundPlanner().enqueue(
        [plan] {
            std::lock_guard lock(planMutex());
            fftwf_destroy_plan(plan);
        },
        true, false);
}

void noteBusy() {
    g_lastBusy.store(Clock::now().time_since_epoch().count(), std::memory_order_relaxed);
}

} // namespace detail

PlannerBusyScope::PlannerBusyScope() {
    g_active.fetch_add(1);
    detail::noteBusy();
}

PlannerBusyScope::~PlannerBusyScope() {
    detail::noteBusy();
    g_active.fetch_sub(1);
}
} // namespace fvr::core
