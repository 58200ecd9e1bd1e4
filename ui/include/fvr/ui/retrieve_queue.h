#pragma once
/** The workstation's PACS retrieves, one after another in the order asked, beside any window:
 *  the PACS dialog queues them and may close, the main window shows the running one's progress
 *  in its status bar and decides what a finished one opens. Each retrieve takes only what the
 *  local store lacks (core::pacs::retrieveMissing). Owned by PacsService, with the store. */
#include <QObject>
#include <QString>
#include <QWidget>

#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/ui/background_job.h>

class QLabel;
class QProgressBar;
class QPushButton;

namespace fvr::ui {

/** One retrieve: what was asked and, once it ran, what happened. */
struct RetrieveJob {
    enum class State { Waiting, Running, Done, Failed, Cancelled };

    int id = 0; ///< given by the queue, from 1
    core::pacs::Node node;
    core::pacs::LocalAe local;
    std::string studyUid;
    std::string seriesUid; ///< empty: the whole study
    QString label; ///< for the user: "Doe^John", "Doe^John, Series 3"
    /** Asked with "Retrieve and open": opened when it ends, unless another study was opened
     *  after it was asked (RetrieveQueue::studyOpened()). */
    bool open = false;
    std::uint64_t openedBefore = 0; ///< the queue's count of opened studies when it was asked
    /** Again from the PACS, also what the store has complete (retrieveMissing's `refresh`). */
    bool refresh = false;
    /** Asked with "Retrieve and open", but a later "Retrieve and open" took its place. */
    bool openSuperseded = false;

    State state = State::Waiting;
    core::pacs::RetrieveProgress progress;
    bool cancelling = false; ///< Running, asked to stop
    QString outcome; ///< in words, once it ended
    std::filesystem::path folder; ///< Done: the study's (series') folder, complete
    bool fromStore = false; ///< Done: complete in the store already, nothing retrieved

    bool ended() const { return state != State::Waiting && state != State::Running; }
};

class RetrieveQueue : public QObject {
    Q_OBJECT
public:
    explicit RetrieveQueue(std::shared_ptr<core::pacs::LocalStore> store,
                           QObject* parent = nullptr);
    ~RetrieveQueue() override; ///< cancels what waits and runs, waits for the running one

    /** Queues `job` (its state and outcome are reset) and returns its id; it starts at once when
     *  nothing runs. When the same study (series) waits or runs already, that job's id, with
     *  `why` saying so: not queued twice, but it now opens when `job.open` (and retrieves anew
     *  when `job.refresh`, if it has not started). With `open`, an earlier job asked to open no
     *  longer does (the latest Retrieve and open is the one opened). */
    int enqueue(RetrieveJob job, QString* why = nullptr);
    /** A waiting job is dropped (Cancelled); the running one is asked to stop, and ends
     *  Cancelled with what arrived kept as a partial study. */
    void cancel(int id);
    void cancelAll();
    /** Forgets the jobs that ended. */
    void clearEnded();

    const std::deque<RetrieveJob>& jobs() const { return m_jobs; }
    const RetrieveJob* job(int id) const;
    const RetrieveJob* running() const;
    int waiting() const;
    /** Whether a job waits or runs. */
    bool busy() const { return running() || waiting() > 0; }
    /** Whether the study (any of its series, or all of it) waits or runs. */
    bool queued(const std::string& studyUid) const;

    /** The window opened a study: a retrieve asked before it no longer opens when it ends. */
    void studyOpened() { ++m_opened; }
    std::uint64_t opened() const { return m_opened; }
    /** Whether a job that ended Done is to be opened now (asked with "Retrieve and open", no
     *  later one asked instead, and nothing opened since it was asked). */
    bool shouldOpen(const RetrieveJob& job) const {
        return job.state == RetrieveJob::State::Done && job.open && job.openedBefore == m_opened;
    }

    const std::shared_ptr<core::pacs::LocalStore>& store() const { return m_store; }

signals:
    /** A job was queued, started, ended or forgotten. */
    void changed();
    /** The running job's images arrived (RetrieveJob::progress). */
    void progressed(int id);
    /** A job ended (Done, Failed or Cancelled; RetrieveJob::outcome says it in words). */
    void ended(int id);
    /** For the Messages panel: outcomes, and text the store could not convert. */
    void message(const QString& text, bool error);

private:
    RetrieveJob* find(int id);
    /** `job` opens when it ends; no other one does. */
    void wantOpen(RetrieveJob& job);
    void startNext();
    void finish(int id, const std::optional<JobError>& error,
                const core::pacs::RetrieveSummary& summary);

    std::shared_ptr<core::pacs::LocalStore> m_store;
    std::deque<RetrieveJob> m_jobs;
    int m_nextId = 1;
    std::uint64_t m_opened = 0;
    std::shared_ptr<core::CancelToken> m_cancel; ///< the running job's
    BackgroundJobs m_work{this}; ///< last: the running retrieve ends before the rest goes
};

/** The main window's status bar while retrieves wait or run: what runs, its images, how many
 *  wait, Cancel, and a link to the PACS dialog's queue. Hidden when the queue is idle. */
class RetrieveStatus : public QWidget {
    Q_OBJECT
public:
    explicit RetrieveStatus(RetrieveQueue& queue, QWidget* parent = nullptr);

    QLabel* label() const { return m_label; }
    QProgressBar* progress() const { return m_progress; }
    QPushButton* cancelButton() const { return m_cancel; }

signals:
    /** "Show": the PACS dialog's retrieve queue. */
    void showQueue();

private:
    void update();

    RetrieveQueue& m_queue;
    QLabel* m_label = nullptr;
    QProgressBar* m_progress = nullptr;
    QPushButton* m_cancel = nullptr;
};

/** The running job's images as a progress bar: "n of m images", or busy while unknown. */
void showRetrieveProgress(QProgressBar& bar, const core::pacs::RetrieveProgress& p);
/** Wide enough for that text on one line. */
void fitRetrieveProgress(QProgressBar& bar);

} // namespace fvr::ui
