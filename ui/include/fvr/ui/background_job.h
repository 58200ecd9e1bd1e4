#pragma once
/** Work off the GUI thread, its result or its error back on the GUI thread: the one way the
 *  workstation runs background work (study loading and preprocessing, the material spectra, the
 *  accuracy readout, PACS queries, retrieves and sends).
 *
 *  - Each job runs on a thread of its own with a core::CancelToken; cancelAll() asks every job to
 *    stop at its next check.
 *  - Its outcome is delivered on the GUI thread to a context QObject: `done(result)`, or
 *    `failed(JobError)` for whatever it threw. Nothing is delivered once the context is
 *    destroyed (the delivery goes through the application object and looks at a QPointer to the
 *    context there, on the GUI thread, where the context is destroyed).
 *  - What a job throws is mapped by jobError() the same way everywhere: core::Cancelled is
 *    Cancelled ("cancelled"), std::bad_alloc is OutOfMemory ("not enough memory …"), anything
 *    else is Failed with the exception's text.
 *  - Destroying the BackgroundJobs cancels every job and waits for those started with
 *    AtExit::Wait (they use their owner, or write where others read: a retrieve into the store);
 *    AtExit::Abandon jobs (a query that waits for a network timeout and cannot be cancelled) end
 *    on their own, and their outcome finds no context. Abandoned work must own what it uses. */
#include <QCoreApplication>
#include <QObject>
#include <QPointer>
#include <QString>

#include <atomic>
#include <exception>
#include <functional>
#include <memory>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include <fvr/core/render/preprocess.h>

namespace fvr::ui {

/** Why a background job gave no result. */
struct JobError {
    enum class Kind { Cancelled, OutOfMemory, Failed };
    Kind kind = Kind::Failed;
    /** For the user: "cancelled", "not enough memory …", or the exception's own text. */
    QString message;
    bool cancelled() const { return kind == Kind::Cancelled; }
};

/** The error for an exception (core::Cancelled, std::bad_alloc, any other). */
JobError jobError(const std::exception_ptr& e);

/** Runs `fn` on the GUI thread unless `context` is destroyed before it gets there. Any thread
 *  may call it; `context` must have been made a QPointer on the GUI thread. */
template <class T, class Fn>
void postToGui(QPointer<T> context, Fn fn) {
    QCoreApplication* app = QCoreApplication::instance();
    if (!app) return; // the application is gone: no GUI thread to deliver to
    QMetaObject::invokeMethod(
        app,
        [context = std::move(context), fn = std::move(fn)]() mutable {
            if (context) fn();
        },
        Qt::QueuedConnection);
}

class BackgroundJobs {
public:
    /** At destruction, after cancelAll(): wait for the job, or let it end on its own. */
    enum class AtExit { Wait, Abandon };

    /** Outcomes go to `context` (a QObject on the GUI thread; usually the owner, which then
     *  declares this member last so that its jobs end before the rest of it is destroyed). */
    explicit BackgroundJobs(QObject* context);
    ~BackgroundJobs(); ///< cancels every job, waits for the AtExit::Wait ones
    BackgroundJobs(const BackgroundJobs&) = delete;
    BackgroundJobs& operator=(const BackgroundJobs&) = delete;

    /** Starts `work(token)` on a new thread (GUI thread only). Then, on the GUI thread while the
     *  context exists: `done(result)` (`done()` for void work), or `failed(JobError)`. Returns
     *  the job's token (cancel() stops it at its next check). */
    template <class Work, class Done, class Failed>
    std::shared_ptr<core::CancelToken> run(Work work, Done done, Failed failed,
                                           AtExit atExit = AtExit::Wait) {
        using Result = std::invoke_result_t<Work&, core::CancelToken&>;
        auto body = [context = m_context, work = std::move(work), done = std::move(done),
                     failed = std::move(failed)](core::CancelToken& token) mutable {
            try {
                if constexpr (std::is_void_v<Result>) {
                    work(token);
                    postToGui(context, std::move(done));
                } else {
                    auto result = std::make_shared<Result>(work(token));
                    postToGui(context, [done = std::move(done), result]() mutable {
                        done(std::move(*result));
                    });
                }
            } catch (...) {
                postToGui(context, [failed = std::move(failed),
                                    error = jobError(std::current_exception())]() mutable {
                    failed(error);
                });
            }
        };
        // Held by a shared pointer: std::function copies, the work need not be copyable.
        auto held = std::make_shared<decltype(body)>(std::move(body));
        return start([held](core::CancelToken& token) { (*held)(token); }, atExit);
    }

    /** `fn` on the GUI thread while the context exists: what a job's work hands over before its
     *  end (a progress step, a cache). From the work of AtExit::Wait jobs only. */
    template <class Fn>
    void post(Fn fn) const {
        postToGui(m_context, std::move(fn));
    }

    /** Asks every running job to stop at its next check. */
    void cancelAll();
    /** Blocks until the work of every AtExit::Wait job has returned (its outcome may still be
     *  on its way to the GUI thread). */
    void wait();
    /** Whether the work of some job has not returned yet. A job's outcome is posted before its
     *  work counts as returned: once this is false, every outcome is on its way or delivered. */
    bool running() const;

private:
    struct Job {
        std::thread thread; ///< joinable for AtExit::Wait jobs
        std::shared_ptr<core::CancelToken> token;
        std::shared_ptr<std::atomic<bool>> returned;
    };
    std::shared_ptr<core::CancelToken> start(std::function<void(core::CancelToken&)> body,
                                             AtExit atExit);
    /** Joins and forgets the jobs whose work has returned. */
    void reap();

    QPointer<QObject> m_context;
    std::vector<Job> m_jobs;
};

} // namespace fvr::ui
