// PACS retrieves one after another, beside any window, and their progress in the status bar.
#include <fvr/ui/retrieve_queue.h>

#include <fvr/ui/study.h>

#include <QDir>
#include <QHBoxLayout>
#include <QLabel>
#include <QProgressBar>
#include <QPushButton>

#include <algorithm>

namespace fvr::ui {

namespace pacs = core::pacs;

RetrieveQueue::RetrieveQueue(std::shared_ptr<pacs::LocalStore> store, QObject* parent)
    : QObject(parent), m_store(std::move(store)) {}

RetrieveQueue::~RetrieveQueue() {
    // What waits never starts; the running retrieve is cancelled and waited for by m_work (it
    // writes into the store, which outlives it).
    m_jobs.clear();
}

RetrieveJob* RetrieveQueue::find(int id) {
    const auto it = std::find_if(m_jobs.begin(), m_jobs.end(),
                                 [id](const RetrieveJob& j) { return j.id == id; });
    return it == m_jobs.end() ? nullptr : &*it;
}

const RetrieveJob* RetrieveQueue::job(int id) const {
    return const_cast<RetrieveQueue*>(this)->find(id);
}

const RetrieveJob* RetrieveQueue::running() const {
    for (const RetrieveJob& j : m_jobs)
        if (j.state == RetrieveJob::State::Running) return &j;
    return nullptr;
}

int RetrieveQueue::waiting() const {
    return int(std::count_if(m_jobs.begin(), m_jobs.end(), [](const RetrieveJob& j) {
        return j.state == RetrieveJob::State::Waiting;
    }));
}

bool RetrieveQueue::queued(const std::string& studyUid) const {
    return std::any_of(m_jobs.begin(), m_jobs.end(),
                       [&](const RetrieveJob& j) { return !j.ended() && j.studyUid == studyUid; });
}

void RetrieveQueue::wantOpen(RetrieveJob& job) {
    // The latest "Retrieve and open" is what the user wants to see: an earlier one, still on
    // its way, no longer opens.
    for (RetrieveJob& j : m_jobs)
        if (&j != &job && !j.ended() && j.open) {
            j.open = false;
            j.openSuperseded = true;
        }
    job.open = true;
    job.openSuperseded = false;
    job.openedBefore = m_opened;
}

int RetrieveQueue::enqueue(RetrieveJob job, QString* why) {
    for (RetrieveJob& j : m_jobs)
        if (!j.ended() && j.studyUid == job.studyUid &&
            (j.seriesUid.empty() || j.seriesUid == job.seriesUid)) {
            // Asked again: not twice, but what was asked now holds (open it, refresh it).
            const bool waiting = j.state == RetrieveJob::State::Waiting;
            if (job.open) wantOpen(j);
            if (waiting && job.refresh) j.refresh = true;
            if (why)
                *why = (waiting ? tr("%1 is already waiting to be retrieved")
                                : tr("%1 is already being retrieved"))
                           .arg(job.label) +
                       (job.open ? tr(": it opens when it is in") : QString());
            emit changed();
            return j.id;
        }
    job.id = m_nextId++;
    job.state = RetrieveJob::State::Waiting;
    job.progress = {};
    job.outcome.clear();
    job.folder.clear();
    job.fromStore = false;
    job.cancelling = false;
    m_jobs.push_back(std::move(job));
    RetrieveJob& added = m_jobs.back();
    if (added.open) wantOpen(added);
    const int id = added.id;
    emit changed();
    startNext();
    return id;
}

void RetrieveQueue::cancel(int id) {
    RetrieveJob* j = find(id);
    if (!j || j->ended()) return;
    if (j->state == RetrieveJob::State::Running) {
        if (m_cancel) m_cancel->cancel(); // finish() reports it when the retrieve stops
        j->cancelling = true;
        emit changed();
        return;
    }
    j->state = RetrieveJob::State::Cancelled;
    j->outcome = tr("Retrieve of %1 cancelled before it started").arg(j->label);
    emit ended(id);
    emit changed();
}

void RetrieveQueue::cancelAll() {
    std::vector<int> ids;
    for (const RetrieveJob& j : m_jobs)
        if (!j.ended()) ids.push_back(j.id);
    // The waiting ones first: the running one's end would otherwise start the next.
    std::reverse(ids.begin(), ids.end());
    for (int id : ids) cancel(id);
}

void RetrieveQueue::clearEnded() {
    std::erase_if(m_jobs, [](const RetrieveJob& j) { return j.ended(); });
    emit changed();
}

void RetrieveQueue::startNext() {
    if (running()) return;
    const auto next = std::find_if(m_jobs.begin(), m_jobs.end(), [](const RetrieveJob& j) {
        return j.state == RetrieveJob::State::Waiting;
    });
    if (next == m_jobs.end()) return;
    next->state = RetrieveJob::State::Running;
    const RetrieveJob job = *next; // the worker's own copy
    QPointer<RetrieveQueue> self(this);
    auto progress = [self, id = job.id](const pacs::RetrieveProgress& p) {
        postToGui(self, [self, id, p] {
            if (RetrieveJob* j = self->find(id); j && j->state == RetrieveJob::State::Running) {
                j->progress = p;
                emit self->progressed(id);
            }
        });
    };
    auto summary = std::make_shared<pacs::RetrieveSummary>();
    auto store = m_store;
    m_cancel = m_work.run(
        [job, store, summary, progress](core::CancelToken& token) {
            *summary = pacs::retrieveMissing(job.node, job.local, job.studyUid, job.seriesUid,
                                             *store, progress, &token, job.refresh);
        },
        [this, id = job.id, summary] { finish(id, std::nullopt, *summary); },
        [this, id = job.id, summary](const JobError& e) { finish(id, e, *summary); });
    emit changed();
}

void RetrieveQueue::finish(int id, const std::optional<JobError>& error,
                           const pacs::RetrieveSummary& summary) {
    m_cancel.reset();
    RetrieveJob* j = find(id);
    if (!j) return;
    try { // for Resume: the node it came from (nothing when no entry was begun)
        m_store->setSource(j->studyUid, j->node.name);
    } catch (const std::exception& e) {
        emit message(QString::fromUtf8(e.what()), true);
    }
    for (const std::string& problem : m_store->takeTextProblems())
        emit message(QString::fromStdString(problem), true);
    const QString folder =
        QDir::toNativeSeparators(QString::fromStdString(summary.folder.string()));
    if (error && error->cancelled()) {
        j->state = RetrieveJob::State::Cancelled;
        j->outcome = tr("Retrieve of %1 cancelled: the images received are kept as a partial "
                        "study (Local studies ▸ Resume retrieve), never opened as complete.")
                         .arg(j->label);
    } else if (error) {
        j->state = RetrieveJob::State::Failed;
        j->outcome = tr("Retrieve of %1 failed: %2").arg(j->label, error->message);
    } else {
        j->state = RetrieveJob::State::Done;
        j->folder = summary.folder;
        j->fromStore = summary.fromStore;
        j->outcome =
            summary.fromStore
                ? tr("%1 is complete in the local store (%2): nothing retrieved")
                      .arg(j->label, folder)
                : tr("Retrieved %1: %2 received")
                          .arg(j->label, countOf(summary.fetched, tr("1 image"), tr("%1 images"))) +
                      (summary.present > 0 ? tr(", %1 already local").arg(summary.present)
                                           : QString()) +
                      tr(", into %1").arg(folder);
    }
    emit message(j->outcome, j->state == RetrieveJob::State::Failed);
    emit ended(id);
    emit changed();
    startNext();
}

void showRetrieveProgress(QProgressBar& bar, const pacs::RetrieveProgress& p) {
    if (p.expected > 0) {
        bar.setRange(0, p.expected);
        bar.setValue(std::min(p.received, p.expected));
        bar.setFormat(RetrieveQueue::tr("%1 of %2 images").arg(p.received).arg(p.expected));
    } else {
        bar.setRange(0, 0);
    }
}

void fitRetrieveProgress(QProgressBar& bar) {
    bar.setTextVisible(true);
    // Its widest text on one line, whatever the layout beside it.
    bar.setMinimumWidth(bar.fontMetrics().horizontalAdvance(
                            RetrieveQueue::tr("%1 of %2 images").arg(99999).arg(99999)) +
                        32);
}

RetrieveStatus::RetrieveStatus(RetrieveQueue& queue, QWidget* parent)
    : QWidget(parent), m_queue(queue) {
    setObjectName(QStringLiteral("retrieveStatus"));
    auto* row = new QHBoxLayout(this);
    row->setContentsMargins(0, 0, 0, 0);
    m_label = new QLabel(this);
    m_progress = new QProgressBar(this);
    fitRetrieveProgress(*m_progress);
    m_cancel = new QPushButton(tr("Cancel"), this);
    m_cancel->setToolTip(tr("Cancels the running retrieve (what arrived is kept as a partial "
                            "study); the waiting ones then go on"));
    auto* show = new QPushButton(tr("Queue…"), this);
    show->setToolTip(tr("The PACS dialog's retrieve queue"));
    row->addWidget(m_label);
    row->addWidget(m_progress);
    row->addWidget(m_cancel);
    row->addWidget(show);
    connect(m_cancel, &QPushButton::clicked, this, [this] {
        if (const RetrieveJob* j = m_queue.running()) m_queue.cancel(j->id);
    });
    connect(show, &QPushButton::clicked, this, &RetrieveStatus::showQueue);
    connect(&m_queue, &RetrieveQueue::changed, this, &RetrieveStatus::update);
    connect(&m_queue, &RetrieveQueue::progressed, this, &RetrieveStatus::update);
    update();
}

void RetrieveStatus::update() {
    const RetrieveJob* j = m_queue.running();
    setVisible(j != nullptr);
    if (!j) return;
    m_cancel->setEnabled(!j->cancelling);
    if (j->cancelling) {
        m_label->setText(tr("Cancelling the retrieve of %1…").arg(j->label));
        return;
    }
    const int waiting = m_queue.waiting();
    m_label->setText(waiting > 0
                         ? tr("Retrieving %1 (%n more waiting)", nullptr, waiting).arg(j->label)
                         : tr("Retrieving %1").arg(j->label));
    showRetrieveProgress(*m_progress, j->progress);
}

} // namespace fvr::ui
