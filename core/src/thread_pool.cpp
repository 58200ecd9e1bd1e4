#include <fvr/core/thread_pool.h>

#include <algorithm>

namespace fvr::core {

int hardwareThreads() { return std::max(1u, std::thread::hardware_concurrency()); }

ThreadPool::ThreadPool(int threads) {
    const int n = threads > 0 ? threads : hardwareThreads();
    for (int i = 1; i < n; ++i) m_workers.emplace_back([this] { workerLoop(); });
}

ThreadPool::~ThreadPool() {
    {
        std::lock_guard lock(m_mutex);
        m_stop = true;
    }
    m_wake.notify_all();
    for (auto& t : m_workers) t.join();
}

void ThreadPool::runChunks() {
    for (;;) {
        std::int64_t begin;
        const std::function<void(std::int64_t, std::int64_t)>* fn;
        {
            std::lock_guard lock(m_mutex);
            if (m_next >= m_count || m_error || !m_fn) return;
            begin = m_next;
            m_next = std::min(m_count, m_next + m_grain);
            fn = m_fn;
        }
        const std::int64_t end = std::min(m_count, begin + m_grain);
        try {
            (*fn)(begin, end);
        } catch (...) {
            std::lock_guard lock(m_mutex);
            if (!m_error) m_error = std::current_exception();
            // No chunk is handed out after an error: a worker that wakes late finds no work
            // (and never a function the caller has already dropped).
            m_next = m_count;
        }
    }
}

void ThreadPool::workerLoop() {
    std::uint64_t seen = 0;
    for (;;) {
        {
            std::unique_lock lock(m_mutex);
            m_wake.wait(lock, [&] { return m_stop || m_generation != seen; });
            if (m_stop) return;
            seen = m_generation;
            ++m_busy;
        }
        runChunks();
        {
            std::lock_guard lock(m_mutex);
            --m_busy;
        }
        m_done.notify_all();
    }
}

void ThreadPool::parallelFor(std::int64_t count, std::int64_t grain,
                             const std::function<void(std::int64_t, std::int64_t)>& fn) {
    if (count <= 0) return;
    grain = std::max<std::int64_t>(1, grain);
    if (m_workers.empty() || count <= grain) {
        fn(0, count);
        return;
    }
    {
        std::lock_guard lock(m_mutex);
        m_fn = &fn;
        m_count = count;
        m_grain = grain;
        m_next = 0;
        m_error = nullptr;
        ++m_generation;
    }
    m_wake.notify_all();
    runChunks();
    std::exception_ptr error;
    {
        std::unique_lock lock(m_mutex);
        m_done.wait(lock, [&] { return m_busy == 0 && (m_next >= m_count || m_error); });
        m_fn = nullptr;
        error = m_error;
        m_error = nullptr;
    }
    if (error) std::rethrow_exception(error);
}

} // namespace fvr::core
