#include <fvr/ui/background_job.h>

#include <algorithm>
#include <new>

#include <fvr/core/errors.h>

namespace fvr::ui {

JobError jobError(const std::exception_ptr& e) {
    try {
        std::rethrow_exception(e);
    } catch (const core::Cancelled&) {
        return {JobError::Kind::Cancelled,
                QCoreApplication::translate("fvr::ui::BackgroundJobs", "cancelled")};
    } catch (const std::bad_alloc&) {
        return {JobError::Kind::OutOfMemory,
                QCoreApplication::translate("fvr::ui::BackgroundJobs",
                                            "not enough memory (the data or the result do not "
                                            "fit; smaller settings may)")};
    } catch (const std::exception& x) {
        return {JobError::Kind::Failed, QString::fromUtf8(x.what())};
    } catch (...) {
        return {JobError::Kind::Failed,
                QCoreApplication::translate("fvr::ui::BackgroundJobs", "an unknown error")};
    }
}

BackgroundJobs::BackgroundJobs(QObject* context) : m_context(context) {}

BackgroundJobs::~BackgroundJobs() {
    cancelAll();
    for (Job& j : m_jobs)
        if (j.thread.joinable()) j.thread.join();
}

std::shared_ptr<core::CancelToken> BackgroundJobs::start(
    std::function<void(core::CancelToken&)> body, AtExit atExit) {
    reap();
    Job job;
    job.token = std::make_shared<core::CancelToken>();
    job.returned = std::make_shared<std::atomic<bool>>(false);
    job.thread = std::thread([body = std::move(body), token = job.token, returned = job.returned] {
        body(*token); // posts the outcome first
        returned->store(true);
    });
    if (atExit == AtExit::Abandon) job.thread.detach();
    m_jobs.push_back(std::move(job));
    return m_jobs.back().token;
}

void BackgroundJobs::reap() {
    std::erase_if(m_jobs, [](Job& j) {
        if (!j.returned->load()) return false;
        if (j.thread.joinable()) j.thread.join(); // its last instructions, at most
        return true;
    });
}

void BackgroundJobs::cancelAll() {
    for (const Job& j : m_jobs) j.token->cancel();
}

void BackgroundJobs::wait() {
    for (Job& j : m_jobs)
        if (j.thread.joinable()) j.thread.join();
    reap();
}

bool BackgroundJobs::running() const {
    return std::any_of(m_jobs.begin(), m_jobs.end(),
                       [](const Job& j) { return !j.returned->load(); });
}

} // namespace fvr::ui
