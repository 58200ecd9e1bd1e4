// The PACS dialog's retrieves: queued from the results (several at once), the Retrieves tab, and
// the bottom strip that follows the running one.
#include <fvr/ui/pacs_dialog.h>

#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QProgressBar>
#include <QPushButton>
#include <QSet>
#include <QTabWidget>
#include <QTreeWidget>
#include <QVBoxLayout>

#include <fvr/ui/study.h>

#include "pacs_dialog_internal.h"

namespace fvr::ui {

namespace pacs = core::pacs;
using namespace pacs_dialog;

namespace {

enum QueueColumn { kQueueWhat, kQueueNode, kQueueState, kQueueImages };

QString stateName(const RetrieveJob& j) {
    switch (j.state) {
    case RetrieveJob::State::Waiting: return PacsDialog::tr("waiting");
    case RetrieveJob::State::Running:
        return j.cancelling ? PacsDialog::tr("cancelling") : PacsDialog::tr("retrieving");
    case RetrieveJob::State::Done:
        return j.fromStore ? PacsDialog::tr("complete (was local)") : PacsDialog::tr("done");
    case RetrieveJob::State::Failed: return PacsDialog::tr("failed");
    case RetrieveJob::State::Cancelled: return PacsDialog::tr("cancelled");
    }
    return {};
}

QString method(const pacs::Node& n) {
    return n.retrieve == pacs::RetrieveMethod::Move ? PacsDialog::tr("C-MOVE")
                                                    : PacsDialog::tr("C-GET");
}

} // namespace

QWidget* PacsDialog::buildQueueTab() {
    auto* tab = new QWidget(this);
    auto* layout = new QVBoxLayout(tab);
    layout->addWidget(new QLabel(tr("Retrieves run one after another, also while this dialog is "
                                    "closed (the main window's status bar shows them)."),
                                 tab));
    m_queueList = new QTreeWidget(tab);
    m_queueList->setRootIsDecorated(false);
    m_queueList->setSelectionMode(QAbstractItemView::ExtendedSelection);
    m_queueList->setHeaderLabels({tr("Study or series"), tr("Node"), tr("State"), tr("Images")});
    m_queueList->header()->setSectionResizeMode(QHeaderView::ResizeToContents);
    layout->addWidget(m_queueList, 1);
    auto* row = new QHBoxLayout;
    m_cancelQueued = new QPushButton(tr("Cancel selected"), tab);
    m_cancelQueued->setToolTip(tr("A waiting retrieve is dropped; the running one stops, keeping "
                                  "what arrived as a partial study"));
    auto* clear = new QPushButton(tr("Clear ended"), tab);
    row->addWidget(m_cancelQueued);
    row->addStretch(1);
    row->addWidget(clear);
    layout->addLayout(row);
    connect(m_cancelQueued, &QPushButton::clicked, this, [this] {
        // The ids first: each cancel changes the queue, and the list follows it.
        std::vector<int> ids;
        for (const QTreeWidgetItem* item : m_queueList->selectedItems())
            ids.push_back(item->data(0, Qt::UserRole).toInt());
        for (int id : ids) m_queue.cancel(id);
    });
    connect(clear, &QPushButton::clicked, &m_queue, &RetrieveQueue::clearEnded);
    return tab;
}

void PacsDialog::showQueue() { m_tabs->setCurrentWidget(m_queueList->parentWidget()); }

void PacsDialog::retrieveSelected(bool open, bool refresh) {
    const pacs::Node* node = currentNode();
    const auto selected = m_results->selectedItems();
    if (selected.isEmpty() || !node) return;
    // A series whose study is selected too comes with its study.
    QSet<const QTreeWidgetItem*> studies;
    for (const QTreeWidgetItem* item : selected)
        if (!item->parent()) studies.insert(item);
    // In the list's order (as sorted), not the order of clicking.
    std::vector<const QTreeWidgetItem*> ordered;
    for (QTreeWidgetItemIterator it(m_results); *it; ++it)
        if ((*it)->isSelected() && !((*it)->parent() && studies.contains((*it)->parent())))
            ordered.push_back(*it);
    bool first = true;
    for (const QTreeWidgetItem* item : ordered) {
        const QTreeWidgetItem* study = item->parent() ? item->parent() : item;
        const QString label = item->parent()
                                  ? tr("%1, %2").arg(study->text(kPatient), item->text(kPatient))
                                  : study->text(kPatient);
        retrieve(*node, item->data(0, kStudyUid).toString().toStdString(),
                 item->data(0, kSeriesUid).toString().toStdString(), label, open && first, refresh);
        first = false;
    }
}

void PacsDialog::retrieve(const pacs::Node& n, const std::string& studyUid,
                          const std::string& seriesUid, const QString& label, bool open,
                          bool refresh) {
    RetrieveJob job;
    job.node = n;
    job.local = m_settings.local;
    job.studyUid = studyUid;
    job.seriesUid = seriesUid;
    job.label = label;
    job.open = open;
    job.refresh = refresh;
    QString why;
    m_queue.enqueue(std::move(job), &why);
    if (!why.isEmpty()) { // asked again: said here and kept in Messages
        setStatus(why);
        emit message(why, false);
    }
}

void PacsDialog::onQueueChanged() {
    const RetrieveJob* j = m_queue.running();
    m_progress->setVisible(j != nullptr);
    m_cancel->setVisible(j != nullptr);
    if (j) {
        showRetrieveProgress(*m_progress, j->progress);
        const int waiting = m_queue.waiting();
        QString what =
            tr("Retrieving %1 from %2 (%3)…").arg(j->label, text(j->node.name), method(j->node));
        if (waiting > 0) what += tr(" %n more waiting.", nullptr, waiting);
        if (j->progress.failed > 0)
            setStatus(what + tr(" %1 failed so far.")
                                 .arg(countOf(j->progress.failed, tr("1 image"), tr("%1 images"))),
                      true, false);
        else if (j->cancelling)
            setStatus(tr("Cancelling the retrieve of %1…").arg(j->label));
        else if (m_status->text() != what)
            setStatus(what);
    }
    fillQueueList();
    updateButtons();
}

void PacsDialog::onRetrieveEnded(int id) {
    const RetrieveJob* j = m_queue.job(id);
    if (!j) return;
    refreshLocal();
    // The queue tells the Messages panel itself; the next running one then speaks here.
    setStatus(j->outcome, j->state == RetrieveJob::State::Failed, false);
}

void PacsDialog::fillQueueList() {
    const auto& jobs = m_queue.jobs();
    const auto row = [](QTreeWidgetItem* item, const RetrieveJob& j) {
        item->setText(kQueueWhat, j.label);
        item->setText(kQueueNode, text(j.node.name));
        item->setText(kQueueState, stateName(j));
        item->setText(
            kQueueImages,
            j.progress.expected > 0
                ? PacsDialog::tr("%1 of %2").arg(j.progress.received).arg(j.progress.expected)
                : QString());
        item->setData(0, Qt::UserRole, j.id);
        item->setToolTip(kQueueState, j.outcome);
    };
    // The same jobs: their rows in place (selection, current row and scrolling stay).
    bool same = m_queueList->topLevelItemCount() == int(jobs.size());
    for (int i = 0; same && i < int(jobs.size()); ++i)
        same = m_queueList->topLevelItem(i)->data(0, Qt::UserRole).toInt() == jobs[i].id;
    if (same) {
        for (int i = 0; i < int(jobs.size()); ++i) row(m_queueList->topLevelItem(i), jobs[i]);
    } else {
        QSet<int> selected;
        for (const QTreeWidgetItem* item : m_queueList->selectedItems())
            selected.insert(item->data(0, Qt::UserRole).toInt());
        m_queueList->clear();
        for (const RetrieveJob& j : jobs) {
            auto* item = new QTreeWidgetItem(m_queueList);
            row(item, j);
            item->setSelected(selected.contains(j.id));
        }
    }
    m_cancelQueued->setEnabled(m_queue.busy());
}

} // namespace fvr::ui
