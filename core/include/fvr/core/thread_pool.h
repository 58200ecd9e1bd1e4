#pragma once
/** A small persistent worker pool for data-parallel loops (the CPU renderer runs per frame, so
 *  spawning threads per call would cost more than the work at small slice sizes). */
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace fvr::core {

class ThreadPool {
public:
    /** threads <= 0: one per hardware thread. The calling thread always takes part. */
    explicit ThreadPool(int threads = 0);
    ~ThreadPool();
    ThreadPool(const ThreadPool&) = delete;
    ThreadPool& operator=(const ThreadPool&) = delete;

    int size() const { return int(m_workers.size()) + 1; }

    /** Calls fn(begin, end) on disjoint chunks covering [0, count), in parallel; returns when all
     *  are done. Chunks are handed out dynamically (`grain` items at a time). The first exception
     *  thrown by fn is rethrown here. Not re-entrant. */
    void parallelFor(std::int64_t count, std::int64_t grain,
                     const std::function<void(std::int64_t, std::int64_t)>& fn);

private:
    void workerLoop();
    void runChunks();

    std::vector<std::thread> m_workers;
    std::mutex m_mutex;
    std::condition_variable m_wake;
    std::condition_variable m_done;
    const std::function<void(std::int64_t, std::int64_t)>* m_fn = nullptr;
    std::int64_t m_count = 0;
    std::int64_t m_grain = 1;
    std::int64_t m_next = 0;
    int m_busy = 0;
    std::uint64_t m_generation = 0;
    bool m_stop = false;
    std::exception_ptr m_error;
};

/** Hardware threads, at least 1. */
int hardwareThreads();

} // namespace fvr::core
