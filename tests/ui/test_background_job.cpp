// The workstation's one way of running work off the GUI thread (BackgroundJobs): the result
// comes back on the GUI thread, what the work throws is mapped to one JobError the same way for
// every job, and nothing reaches a receiver destroyed before the work ended.
#include <QObject>
#include <QPointer>
#include <QTest>
#include <QThread>

#include <atomic>
#include <memory>
#include <new>
#include <optional>
#include <stdexcept>
#include <thread>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/ui/background_job.h>

#include "ui/ui_support.h"

using namespace fvr;
using ui::BackgroundJobs;
using ui::JobError;

namespace {

constexpr int kGuardMs = 30000; // against a hang only

/** Runs `work` and waits for its outcome. */
template <class Work>
std::optional<JobError> failureOf(Work work) {
    QObject receiver;
    std::optional<JobError> error;
    bool done = false;
    {
        BackgroundJobs jobs(&receiver);
        jobs.run(
            work, [&](int) { done = true; }, [&](const JobError& e) { error = e; });
        EXPECT_TRUE(QTest::qWaitFor([&] { return done || error; }, kGuardMs));
    }
    EXPECT_FALSE(done);
    return error;
}

} // namespace

TEST(BackgroundJobs, ResultArrivesOnTheGuiThread) {
    test::app();
    QObject receiver;
    BackgroundJobs jobs(&receiver);
    std::atomic<bool> workOnGuiThread{true};
    QThread* deliveredOn = nullptr;
    std::optional<int> result;
    jobs.run(
        [&](core::CancelToken&) {
            workOnGuiThread = QThread::currentThread() == qApp->thread();
            return 6 * 7;
        },
        [&](int r) {
            deliveredOn = QThread::currentThread();
            result = r;
        },
        [](const JobError& e) { ADD_FAILURE() << e.message.toStdString(); });
    ASSERT_TRUE(QTest::qWaitFor([&] { return result.has_value(); }, kGuardMs));
    EXPECT_EQ(*result, 42);
    EXPECT_FALSE(workOnGuiThread.load());
    EXPECT_EQ(deliveredOn, qApp->thread());
    jobs.wait();
    EXPECT_FALSE(jobs.running());
}

TEST(BackgroundJobs, VoidWorkCallsDoneWithNothing) {
    test::app();
    QObject receiver;
    BackgroundJobs jobs(&receiver);
    bool done = false;
    jobs.run([](core::CancelToken&) {}, [&] { done = true; }, [](const JobError&) {});
    EXPECT_TRUE(QTest::qWaitFor([&] { return done; }, kGuardMs));
}

TEST(BackgroundJobs, CancelledIsMappedToCancelled) {
    test::app();
    QObject receiver;
    BackgroundJobs jobs(&receiver);
    std::atomic<bool> started{false};
    std::optional<JobError> error;
    const auto token = jobs.run(
        [&](core::CancelToken& t) {
            started = true;
            for (;;) {
                t.check();
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            }
            return 0;
        },
        [](int) { ADD_FAILURE() << "a result from cancelled work"; },
        [&](const JobError& e) { error = e; });
    ASSERT_TRUE(QTest::qWaitFor([&] { return started.load(); }, kGuardMs));
    EXPECT_TRUE(jobs.running());
    token->cancel();
    ASSERT_TRUE(QTest::qWaitFor([&] { return error.has_value(); }, kGuardMs));
    EXPECT_EQ(error->kind, JobError::Kind::Cancelled);
    EXPECT_TRUE(error->cancelled());
    EXPECT_EQ(error->message, QStringLiteral("cancelled"));
}

TEST(BackgroundJobs, BadAllocIsMappedToNotEnoughMemory) {
    test::app();
    const auto error = failureOf([](core::CancelToken&) -> int { throw std::bad_alloc(); });
    ASSERT_TRUE(error);
    EXPECT_EQ(error->kind, JobError::Kind::OutOfMemory);
    EXPECT_TRUE(error->message.startsWith(QStringLiteral("not enough memory")))
        << error->message.toStdString();
    EXPECT_FALSE(error->cancelled());
}

TEST(BackgroundJobs, OtherErrorsKeepTheirText) {
    test::app();
    const auto error = failureOf([](core::CancelToken&) -> int {
        throw core::LoadError("/data/study.nii: truncated (expected 1048576 bytes, found 12)");
    });
    ASSERT_TRUE(error);
    EXPECT_EQ(error->kind, JobError::Kind::Failed);
    EXPECT_EQ(error->message,
              QStringLiteral("/data/study.nii: truncated (expected 1048576 bytes, found 12)"));
    // Not derived from std::exception: still an error, not a crash.
    const auto odd = failureOf([](core::CancelToken&) -> int { throw 7; });
    ASSERT_TRUE(odd);
    EXPECT_EQ(odd->kind, JobError::Kind::Failed);
    EXPECT_FALSE(odd->message.isEmpty());
}

// The receiver goes while one job still runs and another's result waits in the event queue:
// neither outcome is delivered, nothing crashes.
TEST(BackgroundJobs, NothingReachesAReceiverDestroyedBeforeTheOutcome) {
    test::app();
    auto* receiver = new QObject;
    BackgroundJobs jobs(receiver);
    std::atomic<bool> release{false};
    int delivered = 0;
    jobs.run(
        [&](core::CancelToken&) {
            while (!release.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
            return 1;
        },
        [&](int) { ++delivered; }, [&](const JobError&) { ++delivered; });
    std::atomic<bool> quickReturned{false};
    jobs.run(
        [&](core::CancelToken&) {
            quickReturned = true;
            return 2;
        },
        [&](int) { ++delivered; }, [&](const JobError&) { ++delivered; });
    // The quick job's result is posted; no event is processed before the receiver goes.
    for (int i = 0; i < kGuardMs && !quickReturned.load(); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ASSERT_TRUE(quickReturned.load());
    delete receiver;
    release = true;
    jobs.wait();
    EXPECT_FALSE(jobs.running());
    QTest::qWait(100); // any delivery would run now
    QCoreApplication::sendPostedEvents();
    EXPECT_EQ(delivered, 0);
}

// Destroying the jobs cancels them and waits for AtExit::Wait work (it may use its owner).
TEST(BackgroundJobs, DestructionCancelsAndWaitsForItsJobs) {
    test::app();
    QObject receiver;
    std::atomic<bool> started{false}, ended{false};
    bool delivered = false;
    {
        BackgroundJobs jobs(&receiver);
        jobs.run(
            [&](core::CancelToken& t) {
                struct End {
                    std::atomic<bool>& e;
                    ~End() { e = true; }
                } end{ended};
                started = true;
                for (;;) {
                    t.check();
                    std::this_thread::sleep_for(std::chrono::milliseconds(1));
                }
            },
            [&] { delivered = true; }, [&](const JobError&) { delivered = true; });
        ASSERT_TRUE(QTest::qWaitFor([&] { return started.load(); }, kGuardMs));
    }
    EXPECT_TRUE(ended.load()); // the destructor returned after the work
    QTest::qWait(50);
    EXPECT_TRUE(delivered); // the receiver lives on: it hears of the cancel
}

// AtExit::Abandon work (a query waiting for a network timeout) is not waited for: the owner and
// the receiver go at once, the work ends later on its own and its outcome finds no one.
TEST(BackgroundJobs, AbandonedWorkEndsOnItsOwnAndFindsNoOne) {
    test::app();
    auto receiver = std::make_unique<QObject>();
    auto jobs = std::make_unique<BackgroundJobs>(receiver.get());
    auto release = std::make_shared<std::atomic<bool>>(false);
    auto ended = std::make_shared<std::atomic<bool>>(false);
    auto delivered = std::make_shared<int>(0);
    jobs->run(
        [release, ended](core::CancelToken&) { // owns what it uses
            while (!release->load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
            ended->store(true);
            return 1;
        },
        [delivered](int) { ++*delivered; }, [delivered](const JobError&) { ++*delivered; },
        BackgroundJobs::AtExit::Abandon);
    // Were the destructor to wait, this guard would release the work (and the test fail).
    std::atomic<bool> guardFired{false};
    std::thread guard([&, release] {
        for (int i = 0; i < kGuardMs && !release->load(); ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        if (!release->exchange(true)) guardFired = true;
    });
    jobs.reset();
    receiver.reset();
    release->store(true);
    guard.join();
    EXPECT_FALSE(guardFired.load());
    ASSERT_TRUE(QTest::qWaitFor([&] { return ended->load(); }, kGuardMs));
    QTest::qWait(100);
    EXPECT_EQ(*delivered, 0);
}
