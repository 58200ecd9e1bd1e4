#pragma once
// Internal: process-wide FFTW state. FFTW's planner is not thread-safe; every plan creation and
// destruction goes through planMutex(). Wisdom is loaded once and saved after new plans.
#include <fftw3.h>

#include <mutex>

namespace fvr::core::detail {

/** Initialises FFTW threads and loads the wisdom file once. */
void ensureFftwInitialised();
std::mutex& planMutex();
/** Saves wisdom to disk if plans were added since the last save (ignores write failures: the
 *  cache is an optimisation). */
void saveWisdom();
unsigned plannerFlags(bool measure);

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
    void reset() {
        if (m_plan) {
            std::lock_guard lock(planMutex());
            fftwf_destroy_plan(m_plan);
            m_plan = nullptr;
        }
    }
    fftwf_plan get() const { return m_plan; }
    explicit operator bool() const { return m_plan != nullptr; }

private:
    fftwf_plan m_plan = nullptr;
};

} // namespace fvr::core::detail
