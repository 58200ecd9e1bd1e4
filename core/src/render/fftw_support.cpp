#include "fftw_support.h"

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

/** One worker thread, started on the first job and never joined (the object is never
 *  destroyed, so a job still running at exit touches nothing that was). */
class BackgroundPlanner {
public:
    void enqueue(std::function<void()> job) {
        std::lock_guard lock(m_mutex);
        m_queue.push_back(std::move(job));
        if (!m_started) {
            m_started = true;
            std::thread([this] { run(); }).detach();
        }
        m_wake.notify_one();
    }
    void finish() {
        std::unique_lock lock(m_mutex);
        m_idle.wait(lock, [this] { return m_queue.empty() && !m_busy; });
    }
    int made() {
        std::lock_guard lock(m_mutex);
        return m_made;
    }

private:
    void run() {
        std::unique_lock lock(m_mutex);
        for (;;) {
            m_wake.wait(lock, [this] { return !m_queue.empty(); });
            auto job = std::move(m_queue.front());
            m_queue.pop_front();
            m_busy = true;
            lock.unlock();
            try {
                job();
                detail::saveWisdom();
            } catch (...) { // an optimisation failed (no memory for the scratch buffers)
            }
            job = nullptr; // what it held (a plan slot) goes before m_mutex is taken again
            lock.lock();
            m_busy = false;
            ++m_made;
            if (m_queue.empty()) m_idle.notify_all();
        }
    }

    std::mutex m_mutex;
    std::condition_variable m_wake, m_idle;
    std::deque<std::function<void()>> m_queue;
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
bool g_dirty = false;
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
    std::lock_guard lock(planMutex());
    if (!g_dirty) return;
    g_dirty = false;
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

void planInBackground(std::function<void()> job) { backgroundPlanner().enqueue(std::move(job)); }

} // namespace detail
} // namespace fvr::core
