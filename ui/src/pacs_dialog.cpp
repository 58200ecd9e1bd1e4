// File ▸ PACS…: query, retrieve with progress and cancel, local studies.
#include <fvr/ui/pacs_dialog.h>

#include <QAction>
#include <QComboBox>
#include <QCoreApplication>
#include <QDate>
#include <QDateEdit>
#include <QDir>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QKeyEvent>
#include <QLabel>
#include <QLineEdit>
#include <QMessageBox>
#include <QPainter>
#include <QProgressBar>
#include <QPushButton>
#include <QSettings>
#include <QSignalBlocker>
#include <QTabWidget>
#include <QTreeWidget>
#include <QVBoxLayout>

#include <map>

#include <algorithm>

#include <fvr/core/errors.h>
#include <fvr/ui/settings_keys.h>
#include <fvr/ui/study.h>

#include "pacs_dialog_internal.h"

namespace fvr::ui {

namespace {

namespace pacs = core::pacs;
using namespace pacs_dialog;

enum LocalColumn { kLocalPatient, kLocalDate, kLocalDescription, kLocalImages, kLocalState };

/** A column's value to sort by where its text does not sort (counts, series numbers). */
constexpr int kSortKey = Qt::UserRole + 32;

/** A row that sorts by its column's kSortKey (a number) where both rows have one, else by the
 *  text as the user's locale orders it: "10" after "9", "Series 10" after "Series 9", ISO dates
 *  in time order. */
class SortedItem : public QTreeWidgetItem {
public:
    using QTreeWidgetItem::QTreeWidgetItem;
    bool operator<(const QTreeWidgetItem& other) const override {
        const int c = treeWidget() ? treeWidget()->sortColumn() : 0;
        const QVariant a = data(c, kSortKey), b = other.data(c, kSortKey);
        if (a.isValid() && b.isValid()) return a.toLongLong() < b.toLongLong();
        return QString::localeAwareCompare(text(c), other.text(c)) < 0;
    }
};

QString count(int n) { return n >= 0 ? QString::number(n) : QString(); }

/** Sets a count's text and its sort key (unknown, -1: empty, first). */
void setCount(QTreeWidgetItem* item, int column, int n) {
    item->setText(column, count(n));
    item->setData(column, kSortKey, n);
}

/** "1 study", "2 studies". */
QString studies(int n) {
    return countOf(n, PacsDialog::tr("1 study"), PacsDialog::tr("%1 studies"));
}

/** The status line: one line whatever its length, elided at the right where it does not fit
 *  (text() and the tooltip keep all of it), so that a long status neither wraps the row nor is
 *  clipped beside the progress bar. */
class ElidedLabel : public QLabel {
public:
    using QLabel::QLabel;
    QSize minimumSizeHint() const override { return {0, QLabel::minimumSizeHint().height()}; }

protected:
    void paintEvent(QPaintEvent*) override {
        QPainter painter(this);
        painter.setPen(palette().color(foregroundRole()));
        const QRect r = contentsRect();
        painter.drawText(r, int(alignment()) | Qt::TextSingleLine,
                         fontMetrics().elidedText(text(), Qt::ElideRight, r.width()));
    }
};

enum DatePreset { kAnyDate, kToday, kYesterday, kLast7, kLast30, kLast365, kRange };

/** The dates a preset (not kRange) stands for, counted back from `today`: both invalid for any
 *  date. */
std::pair<QDate, QDate> presetDates(int preset, const QDate& today) {
    switch (preset) {
    case kToday: return {today, today};
    case kYesterday: return {today.addDays(-1), today.addDays(-1)};
    case kLast7: return {today.addDays(-6), today};
    case kLast30: return {today.addDays(-29), today};
    case kLast365: return {today.addDays(-364), today};
    default: return {};
    }
}

} // namespace

PacsDialog::PacsDialog(RetrieveQueue& queue, QWidget* parent)
    : QDialog(parent), m_queue(queue), m_store(queue.store()) {
    setWindowTitle(tr("PACS"));
    auto* layout = new QVBoxLayout(this);
    auto* nodeRow = new QHBoxLayout;
    m_node = new QComboBox(this);
    m_node->setMinimumContentsLength(24);
    nodeRow->addWidget(new QLabel(tr("PACS node"), this));
    nodeRow->addWidget(m_node, 1);
    m_editNodes = new QPushButton(tr("Edit nodes…"), this);
    m_echo = new QPushButton(tr("Test connection"), this);
    m_echo->setToolTip(tr("C-ECHO, then a C-FIND on a key no study has: whether the node "
                          "answers and knows our AE title"));
    nodeRow->addWidget(m_editNodes);
    nodeRow->addWidget(m_echo);
    layout->addLayout(nodeRow);
    m_tabs = new QTabWidget(this);
    m_tabs->addTab(buildQueryTab(), tr("Search the PACS"));
    m_tabs->addTab(buildLocalTab(), tr("Local studies"));
    m_tabs->addTab(buildQueueTab(), tr("Retrieves"));
    layout->addWidget(m_tabs, 1);
    auto* bottom = new QHBoxLayout;
    m_progress = new QProgressBar(this);
    fitRetrieveProgress(*m_progress);
    m_progress->setVisible(false);
    m_cancel = new QPushButton(tr("Cancel"), this);
    m_cancel->setVisible(false);
    m_status = new ElidedLabel(this);
    bottom->addWidget(m_status, 1);
    bottom->addWidget(m_progress);
    bottom->addWidget(m_cancel);
    layout->addLayout(bottom);

    connect(m_editNodes, &QPushButton::clicked, this, [this] {
        PacsNodesDialog d(PacsSettings::load(), this);
        if (d.exec() != QDialog::Accepted) return;
        d.settings().save();
        emit settingsChanged(); // the listener follows them at once (MainWindow)
        reloadSettings();
    });
    connect(m_echo, &QPushButton::clicked, this, &PacsDialog::testConnection);
    m_cancel->setToolTip(tr("Cancels the running retrieve; the waiting ones then go on"));
    connect(m_cancel, &QPushButton::clicked, this, [this] {
        if (const RetrieveJob* j = m_queue.running()) {
            m_queue.cancel(j->id);
            setStatus(tr("Cancelling…"));
        }
    });
    connect(&m_queue, &RetrieveQueue::changed, this, &PacsDialog::onQueueChanged);
    connect(&m_queue, &RetrieveQueue::progressed, this, &PacsDialog::onQueueChanged);
    connect(&m_queue, &RetrieveQueue::ended, this, &PacsDialog::onRetrieveEnded);
    connect(m_node, &QComboBox::currentTextChanged, this, [](const QString& name) {
        if (!name.isEmpty()) QSettings().setValue(keys::kPacsLastNode, name);
    });
    // The results are another node's: they go with it (a retrieve would ask the new node).
    connect(m_node, &QComboBox::currentIndexChanged, this, [this] {
        m_results->clear();
        // An error was the other node's: it no longer describes what the dialog shows.
        if (m_statusError && !m_queue.running()) setStatus(QString());
        updateButtons();
    });
    reloadSettings();
    refreshLocal();
    onQueueChanged(); // retrieves queued before the dialog was made
    resize(980, 640);
}

// Retrieves belong to the queue, which outlives the dialog. An echo or a query cannot be
// cancelled and may wait for the network timeout: it ends on its own, and its result finds no
// dialog.
PacsDialog::~PacsDialog() = default;

QWidget* PacsDialog::buildQueryTab() {
    auto* tab = new QWidget(this);
    auto* layout = new QVBoxLayout(tab);
    layout->addWidget(buildQueryForm());
    m_results = new QTreeWidget(tab);
    m_results->setHeaderLabels({tr("Patient"), tr("Patient ID"), tr("Study date"),
                                tr("Description"), tr("Modalities"), tr("Series"), tr("Images"),
                                tr("Local")});
    m_results->setSelectionMode(QAbstractItemView::ExtendedSelection);
    m_results->header()->setSectionResizeMode(QHeaderView::ResizeToContents);
    m_results->setSortingEnabled(true);
    m_results->sortByColumn(kDate, Qt::DescendingOrder); // the newest first; a header sorts
    m_results->setToolTip(tr("Expand a study to list its series; retrieve studies or series "
                             "(Ctrl or Shift selects several); a column's header sorts"));
    layout->addWidget(m_results, 1);
    auto* row = new QHBoxLayout;
    row->addStretch(1);
    m_queueRetrieve = new QPushButton(tr("Retrieve"), tab);
    m_queueRetrieve->setToolTip(tr("Queues the selected studies and series into the local "
                                   "store; nothing is opened"));
    m_retrieve = new QPushButton(tr("Retrieve and open"), tab);
    m_retrieve->setToolTip(tr("Queues the selection and opens the first when it is in, unless "
                              "another study was opened meanwhile (double-click, Enter)"));
    for (QPushButton* b : {m_queueRetrieve, m_retrieve}) {
        b->setEnabled(false);
        row->addWidget(b);
    }
    layout->addLayout(row);
    m_results->setContextMenuPolicy(Qt::ActionsContextMenu);
    m_results->addAction(tr("Retrieve"), this, [this] { retrieveSelected(false); });
    m_results->addAction(tr("Retrieve and open"), this, [this] { retrieveSelected(true); });
    m_results->addAction(tr("Retrieve again from the PACS (refresh what is local)"), this,
                         [this] { retrieveSelected(false, true); });
    connect(m_results, &QTreeWidget::itemExpanded, this, &PacsDialog::loadSeries);
    connect(m_results, &QTreeWidget::itemSelectionChanged, this, &PacsDialog::updateButtons);
    connect(m_results, &QTreeWidget::itemDoubleClicked, this, [this] { retrieveSelected(true); });
    connect(m_queueRetrieve, &QPushButton::clicked, this, [this] { retrieveSelected(false); });
    connect(m_retrieve, &QPushButton::clicked, this, [this] { retrieveSelected(true); });
    return tab;
}

QWidget* PacsDialog::buildQueryForm() {
    auto* box = new QWidget(this);
    auto* form = new QFormLayout(box);
    m_patientName = new QLineEdit(box);
    m_patientName->setPlaceholderText(tr("e.g. DOE* (wildcards * and ?)"));
    form->addRow(tr("Patient name"), m_patientName);
    m_patientId = new QLineEdit(box);
    form->addRow(tr("Patient ID"), m_patientId);
    m_accession = new QLineEdit(box);
    form->addRow(tr("Accession number"), m_accession);
    auto* dates = new QHBoxLayout;
    m_datePreset = new QComboBox(box);
    m_datePreset->addItems({tr("Any date"), tr("Today"), tr("Yesterday"), tr("Last 7 days"),
                            tr("Last 30 days"), tr("Last 365 days"), tr("From … to …")});
    m_dateFrom = new QDateEdit(QDate::currentDate().addDays(-7), box);
    m_dateTo = new QDateEdit(QDate::currentDate(), box);
    for (QDateEdit* d : {m_dateFrom, m_dateTo}) {
        d->setCalendarPopup(true);
        d->setDisplayFormat(QStringLiteral("yyyy-MM-dd"));
        d->setEnabled(false);
    }
    dates->addWidget(m_datePreset);
    dates->addWidget(m_dateFrom);
    dates->addWidget(new QLabel(QStringLiteral("–"), box));
    dates->addWidget(m_dateTo);
    dates->addStretch(1);
    form->addRow(tr("Study date"), dates);
    m_modality = new QComboBox(box);
    m_modality->setEditable(true);
    m_modality->addItems({tr("Any"), "CT", "MR", "CR", "DX", "XA", "PT", "NM", "US", "OT"});
    form->addRow(tr("Modality"), m_modality);
    m_search = new QPushButton(tr("Search"), box);
    form->addRow(QString(), m_search);
    connect(m_datePreset, &QComboBox::currentIndexChanged, this, [this](int i) {
        m_dateFrom->setEnabled(i == kRange);
        m_dateTo->setEnabled(i == kRange);
        // The greyed fields show what the preset searches (any date: they keep their dates).
        const auto [from, to] = presetDates(i, QDate::currentDate());
        if (from.isValid()) m_dateFrom->setDate(from), m_dateTo->setDate(to);
    });
    // Enter in a field searches through keyPressEvent() (once: the fields pass it on, and no
    // button is the dialog's default).
    connect(m_search, &QPushButton::clicked, this, &PacsDialog::search);
    return box;
}

QWidget* PacsDialog::buildLocalTab() {
    auto* tab = new QWidget(this);
    auto* layout = new QVBoxLayout(tab);
    layout->addWidget(new QLabel(
        tr("Studies retrieved into %1")
            .arg(QDir::toNativeSeparators(QString::fromStdString(m_store->root().string()))),
        tab));
    m_local = new QTreeWidget(tab);
    m_local->setHeaderLabels(
        {tr("Patient"), tr("Study date"), tr("Description"), tr("Images"), tr("State")});
    m_local->header()->setSectionResizeMode(QHeaderView::ResizeToContents);
    m_local->setSortingEnabled(true);
    m_local->sortByColumn(kLocalDate, Qt::DescendingOrder);
    layout->addWidget(m_local, 1);
    auto* row = new QHBoxLayout;
    auto* refresh = new QPushButton(tr("Refresh"), tab);
    m_resumeLocal = new QPushButton(tr("Resume retrieve"), tab);
    m_resumeLocal->setToolTip(tr("Retrieves what is missing of a partial study from the node"));
    m_openLocal = new QPushButton(tr("Open"), tab);
    m_deleteLocal = new QPushButton(tr("Delete…"), tab);
    m_deleteLocal->setToolTip(tr("Removes the study's files and its entry from the local store "
                                 "(Delete key; also in the list's context menu)"));
    row->addWidget(refresh);
    row->addWidget(m_deleteLocal);
    row->addStretch(1);
    row->addWidget(m_resumeLocal);
    row->addWidget(m_openLocal);
    layout->addLayout(row);
    // The context menu: the buttons' actions; Delete as a key of the list's own.
    m_local->setContextMenuPolicy(Qt::ActionsContextMenu);
    m_local->addAction(tr("Open"), this, &PacsDialog::openLocal);
    m_local->addAction(tr("Resume retrieve"), this, &PacsDialog::resumeLocal);
    QAction* del = m_local->addAction(tr("Delete…"), this, [this] { deleteSelectedLocal(); });
    del->setShortcut(QKeySequence::Delete);
    del->setShortcutContext(Qt::WidgetShortcut);
    connect(m_deleteLocal, &QPushButton::clicked, this, [this] { deleteSelectedLocal(); });
    m_local->installEventFilter(this);
    connect(refresh, &QPushButton::clicked, this, &PacsDialog::refreshLocal);
    connect(m_openLocal, &QPushButton::clicked, this, &PacsDialog::openLocal);
    connect(m_resumeLocal, &QPushButton::clicked, this, &PacsDialog::resumeLocal);
    connect(m_local, &QTreeWidget::itemDoubleClicked, this, &PacsDialog::openLocal);
    connect(m_local, &QTreeWidget::itemSelectionChanged, this, &PacsDialog::updateButtons);
    return tab;
}

void PacsDialog::reloadSettings() {
    m_settings = PacsSettings::load();
    const QString last = QSettings().value(keys::kPacsLastNode).toString();
    const QSignalBlocker block(m_node);
    m_node->clear();
    for (const pacs::Node& n : m_settings.nodes)
        m_node->addItem(QStringLiteral("%1 (%2@%3:%4)")
                            .arg(text(n.name), text(n.calledAe), text(n.host))
                            .arg(n.port),
                        text(n.name));
    const int i = m_node->findData(last);
    if (i >= 0) m_node->setCurrentIndex(i);
    if (m_settings.nodes.empty())
        setStatus(tr("No PACS node yet: Edit nodes… adds one (AE title, host, port)."));
    updateButtons();
}

const pacs::Node* PacsDialog::currentNode() const {
    if (m_node->currentIndex() < 0) return nullptr;
    return m_settings.node(m_node->currentData().toString());
}

std::shared_ptr<core::CancelToken> PacsDialog::run(
    std::function<void(core::CancelToken&)> work,
    std::function<void(const std::optional<JobError>&)> done, bool waitAtClose) {
    ++m_pending;
    updateButtons();
    auto finish = [this, done](const std::optional<JobError>& error) {
        --m_pending;
        done(error);
        updateButtons();
    };
    return m_jobs.run(
        std::move(work), [finish] { finish(std::nullopt); },
        [finish](const JobError& e) { finish(e); },
        waitAtClose ? BackgroundJobs::AtExit::Wait : BackgroundJobs::AtExit::Abandon);
}

void PacsDialog::testConnection() {
    const pacs::Node* node = currentNode();
    if (!node) return;
    const pacs::Node n = *node;
    const pacs::LocalAe local = m_settings.local;
    setStatus(tr("Testing %1…").arg(text(n.name)));
    run([n, local](core::CancelToken&) { pacs::echo(n, local); },
        [this, n](const std::optional<JobError>& error) {
            if (error)
                setStatus(tr("%1: %2").arg(text(n.name), error->message), true);
            else
                verifyAeTitle(n);
        });
}

void PacsDialog::verifyAeTitle(const pacs::Node& n) {
    // A PACS answers C-ECHO from anyone (Orthanc's default), but searches and retrieves only
    // for the AE titles it knows: a C-FIND on a patient ID no study has tells which.
    const pacs::LocalAe local = m_settings.local;
    const QString ae = text(local.aeTitle);
    setStatus(
        tr("%1 answers (C-ECHO); asking whether it knows %2 (C-FIND)…").arg(text(n.name), ae));
    run(
        [n, local](core::CancelToken&) {
            pacs::StudyQuery q;
            q.patientId = "FVR-CONNECTION-TEST"; // no study has it: the answer is empty
            pacs::findStudies(n, local, q);
        },
        [this, n, ae](const std::optional<JobError>& error) {
            if (error) {
                setStatus(tr("%1 answers C-ECHO, but the PACS refused our AE title %2: %3 (the "
                             "PACS must list %2 among its nodes)")
                              .arg(text(n.name), ae, error->message),
                          true);
                return;
            }
            const QString ok = tr("%1 answers (C-ECHO) and accepts %2 as our AE title (C-FIND).")
                                   .arg(text(n.name), ae);
            setStatus(ok);
            emit message(ok, false);
        });
}

core::pacs::StudyQuery PacsDialog::query() const {
    pacs::StudyQuery q;
    q.patientName = m_patientName->text().trimmed().toStdString();
    q.patientId = m_patientId->text().trimmed().toStdString();
    q.accessionNumber = m_accession->text().trimmed().toStdString();
    const QString modality = m_modality->currentText().trimmed();
    if (m_modality->currentIndex() != 0 || modality != m_modality->itemText(0))
        q.modality = modality.toUpper().toStdString();
    auto [from, to] = presetDates(m_datePreset->currentIndex(), QDate::currentDate());
    if (m_datePreset->currentIndex() == kRange) from = m_dateFrom->date(), to = m_dateTo->date();
    if (from.isValid()) q.dateFrom = from.toString(QStringLiteral("yyyyMMdd")).toStdString();
    if (to.isValid()) q.dateTo = to.toString(QStringLiteral("yyyyMMdd")).toStdString();
    return q;
}

void PacsDialog::search() {
    const pacs::Node* node = currentNode();
    if (!node) return;
    const pacs::Node n = *node;
    const pacs::LocalAe local = m_settings.local;
    const pacs::StudyQuery q = query();
    auto found = std::make_shared<std::vector<pacs::StudyRecord>>();
    // A retrieve keeps the status line (its progress): the search speaks through the results,
    // and its failure through Messages.
    if (!m_queue.running()) setStatus(tr("Searching %1…").arg(text(n.name)));
    m_results->clear();
    run([n, local, q, found](core::CancelToken&) { *found = pacs::findStudies(n, local, q); },
        [this, n, found](const std::optional<JobError>& error) {
            if (error) {
                const QString why = tr("Search on %1 failed: %2").arg(text(n.name), error->message);
                if (m_queue.running())
                    emit message(why, true);
                else
                    setStatus(why, true);
                return;
            }
            showStudies(*found);
            if (!m_queue.running())
                setStatus(tr("%1 found on %2").arg(studies(int(found->size())), text(n.name)));
        });
}

void PacsDialog::showStudies(const std::vector<pacs::StudyRecord>& studies) {
    m_results->clear();
    m_results->setSortingEnabled(false); // once, after the rows are in
    for (const pacs::StudyRecord& s : studies) {
        auto* item = new SortedItem(m_results);
        item->setText(kPatient, personName(s.patientName));
        item->setText(kPatientId, text(s.patientId));
        item->setText(kDate, dicomDate(s.studyDate));
        item->setText(kDescription, text(s.description));
        item->setText(kModalities, text(s.modalities));
        setCount(item, kSeries, s.numberOfSeries);
        setCount(item, kImages, s.numberOfInstances);
        item->setData(0, kStudyUid, text(s.studyUid));
        item->setToolTip(0, tr("Study Instance UID %1").arg(text(s.studyUid)));
        item->setChildIndicatorPolicy(QTreeWidgetItem::ShowIndicator);
    }
    m_results->setSortingEnabled(true);
    markLocalState();
    updateButtons();
}

void PacsDialog::markLocalState() {
    std::map<std::string, pacs::LocalStore::Entry> local;
    try {
        for (pacs::LocalStore::Entry& e : m_store->studies())
            if (e.area == pacs::Area::Studies) local.emplace(e.study.studyUid, std::move(e));
    } catch (const std::exception&) {
        return; // the Local studies tab says why
    }
    const auto state = [this](bool complete, int images) {
        return complete ? tr("complete")
                        : tr("partial (%1)").arg(countOf(images, tr("1 image"), tr("%1 images")));
    };
    // Unsorted while the column is written: sorted by it, each row would move under the index.
    m_results->setSortingEnabled(false);
    for (int i = 0; i < m_results->topLevelItemCount(); ++i) {
        QTreeWidgetItem* study = m_results->topLevelItem(i);
        const auto it = local.find(study->data(0, kStudyUid).toString().toStdString());
        const bool known = it != local.end();
        study->setText(kLocal, known ? state(it->second.complete, it->second.instances) : "");
        for (int c = 0; c < study->childCount(); ++c) {
            QTreeWidgetItem* series = study->child(c);
            series->setText(kLocal, QString());
            if (!known) continue;
            for (const auto& s : it->second.series)
                if (text(s.seriesUid) == series->data(0, kSeriesUid).toString())
                    series->setText(kLocal, state(s.complete || it->second.complete, s.instances));
        }
    }
    m_results->setSortingEnabled(true);
}

void PacsDialog::loadSeries(QTreeWidgetItem* study) {
    if (!study || study->parent() || study->data(0, kSeriesLoaded).toBool()) return;
    const pacs::Node* node = currentNode();
    if (!node) return;
    study->setData(0, kSeriesLoaded, true);
    const pacs::Node n = *node;
    const pacs::LocalAe local = m_settings.local;
    const std::string uid = study->data(0, kStudyUid).toString().toStdString();
    auto found = std::make_shared<std::vector<pacs::SeriesRecord>>();
    run([n, local, uid, found](core::CancelToken&) { *found = pacs::findSeries(n, local, uid); },
        [this, uid, found](const std::optional<JobError>& error) {
            // Found again by its UID: a new search may have replaced the results meanwhile.
            QTreeWidgetItem* item = nullptr;
            for (int i = 0; i < m_results->topLevelItemCount() && !item; ++i) {
                QTreeWidgetItem* t = m_results->topLevelItem(i);
                if (t->data(0, kStudyUid).toString().toStdString() == uid &&
                    t->data(0, kSeriesLoaded).toBool() && t->childCount() == 0)
                    item = t;
            }
            if (!item) return;
            addSeries(item, error ? error->message : QString(), *found);
        });
}

void PacsDialog::addSeries(QTreeWidgetItem* study, const QString& error,
                           const std::vector<pacs::SeriesRecord>& found) {
    if (!error.isEmpty()) {
        study->setData(0, kSeriesLoaded, false);
        setStatus(tr("Series query failed: %1").arg(error), true);
        return;
    }
    for (const pacs::SeriesRecord& s : found) {
        auto* item = new SortedItem(study);
        item->setText(kPatient, tr("Series %1").arg(count(s.seriesNumber)));
        item->setData(kPatient, kSortKey, s.seriesNumber);
        item->setText(kDescription, text(s.description));
        item->setText(kModalities, text(s.modality));
        setCount(item, kImages, s.numberOfInstances);
        item->setData(0, kStudyUid, study->data(0, kStudyUid));
        item->setData(0, kSeriesUid, text(s.seriesUid));
        item->setToolTip(0, tr("Series Instance UID %1").arg(text(s.seriesUid)));
    }
    if (found.empty()) study->setChildIndicatorPolicy(QTreeWidgetItem::DontShowIndicator);
    // An earlier failure (this query's last try, say) is not left in red over what worked.
    if (m_statusError && !m_queue.running())
        setStatus(tr("%n series of %1", nullptr, int(found.size())).arg(study->text(kPatient)));
    markLocalState();
}

void PacsDialog::refreshLocal() {
    m_local->clear();
    m_local->setSortingEnabled(false); // once, after the rows are in
    try {
        for (const pacs::LocalStore::Entry& e : m_store->studies()) {
            auto* item = new SortedItem(m_local);
            item->setText(kLocalPatient, personName(e.study.patientName));
            item->setText(kLocalDate, dicomDate(e.study.studyDate));
            item->setText(kLocalDescription, text(e.study.description));
            setCount(item, kLocalImages, e.instances);
            item->setText(kLocalState,
                          (e.area == pacs::Area::Incoming ? tr("incoming, ") : QString()) +
                              (e.complete ? tr("complete") : tr("partial")));
            item->setData(0, kStudyUid, text(e.study.studyUid));
            item->setData(0, kFolder, QString::fromStdString(e.folder.string()));
            item->setData(0, kComplete, e.complete);
            item->setData(0, kIncoming, e.area == pacs::Area::Incoming);
            item->setData(0, kSource, text(e.source));
            for (const pacs::LocalStore::SeriesEntry& s : e.series) {
                auto* child = new SortedItem(item);
                child->setText(kLocalPatient, text(s.modality));
                child->setText(kLocalDescription, text(s.description));
                setCount(child, kLocalImages, s.instances);
                child->setText(kLocalState, s.complete ? tr("complete") : tr("partial"));
                child->setData(0, kStudyUid, text(e.study.studyUid));
                child->setData(0, kSeriesUid, text(s.seriesUid));
                child->setData(0, kFolder, QString::fromStdString(s.folder.string()));
                child->setData(0, kComplete, s.complete);
                child->setData(0, kIncoming, e.area == pacs::Area::Incoming);
                child->setData(0, kSource, text(e.source));
            }
        }
    } catch (const std::exception& e) {
        setStatus(tr("Local studies: %1").arg(QString::fromUtf8(e.what())), true);
    }
    m_local->setSortingEnabled(true);
    markLocalState();
    updateButtons();
}

void PacsDialog::openLocal() {
    const auto selected = m_local->selectedItems();
    if (selected.isEmpty()) return;
    const QTreeWidgetItem* item = selected.front();
    if (!item->data(0, kComplete).toBool()) {
        setStatus(tr("This study is partial: Resume retrieve completes it first."), true);
        return;
    }
    const QTreeWidgetItem* study = item->parent() ? item->parent() : item;
    setStatus(tr("Opening %1 from the local store").arg(study->text(kLocalPatient)));
    emit openRequested(item->data(0, kFolder).toString());
}

void PacsDialog::resumeLocal() {
    const auto selected = m_local->selectedItems();
    if (selected.isEmpty()) return;
    const QTreeWidgetItem* item = selected.front();
    // The node the study came from, not the dropdown's; the dropdown's when the store does not
    // know it (received by the listener, or retrieved before the store recorded it).
    const QString source = item->data(0, kSource).toString();
    const pacs::Node* node = source.isEmpty() ? currentNode() : m_settings.node(source);
    if (!node) {
        setStatus(tr("This study came from the node %1, which is no longer in the settings: "
                     "Edit nodes… adds it again.")
                      .arg(source),
                  true);
        return;
    }
    const QTreeWidgetItem* study = item->parent() ? item->parent() : item;
    // Queued, not opened when it ends: Open does that once it is complete.
    retrieve(*node, item->data(0, kStudyUid).toString().toStdString(),
             item->data(0, kSeriesUid).toString().toStdString(), study->text(kLocalPatient), false);
}

void PacsDialog::setStatus(const QString& t, bool error, bool toMessages) {
    m_status->setText(t);
    m_status->setToolTip(t); // all of it, where the line is elided
    m_status->setStyleSheet(error ? QStringLiteral("color: #c0392b") : QString());
    m_statusError = error;
    if (error && toMessages) emit message(t, true);
}

void PacsDialog::updateButtons() {
    const bool haveNode = currentNode() != nullptr;
    m_echo->setEnabled(haveNode);
    m_search->setEnabled(haveNode);
    const bool results = haveNode && !m_results->selectedItems().isEmpty();
    m_retrieve->setEnabled(results); // queued behind a running retrieve
    m_queueRetrieve->setEnabled(results);
    const auto local = m_local->selectedItems();
    const bool complete = !local.isEmpty() && local.front()->data(0, kComplete).toBool();
    const bool knownSource =
        !local.isEmpty() && !local.front()->data(0, kSource).toString().isEmpty();
    m_openLocal->setEnabled(complete);
    m_resumeLocal->setEnabled((haveNode || knownSource) && !local.isEmpty() && !complete);
    m_deleteLocal->setEnabled(!local.isEmpty());
}

void PacsDialog::deleteSelectedLocal(bool confirm) {
    const auto selected = m_local->selectedItems();
    if (selected.isEmpty()) return;
    const QTreeWidgetItem* study =
        selected.front()->parent() ? selected.front()->parent() : selected.front();
    const std::string uid = study->data(0, kStudyUid).toString().toStdString();
    const pacs::Area area =
        study->data(0, kIncoming).toBool() ? pacs::Area::Incoming : pacs::Area::Studies;
    const QString label =
        tr("%1, %2 (%3 images)")
            .arg(study->text(kLocalPatient), study->text(kLocalDate), study->text(kLocalImages));
    if (area == pacs::Area::Studies && (m_store->retrieving(uid) || m_queue.queued(uid))) {
        setStatus(tr("%1 is being retrieved or waits to be: cancel its retrieve (or let it end) "
                     "before deleting it.")
                      .arg(label),
                  true);
        return;
    }
    if (confirm) {
        QMessageBox ask(
            QMessageBox::Question, tr("Delete local study"),
            tr("Delete %1 from the local store? Its files are removed from %2.")
                .arg(label, QDir::toNativeSeparators(study->data(0, kFolder).toString())),
            QMessageBox::Yes | QMessageBox::No, this);
        ask.setObjectName(QStringLiteral("confirmDelete"));
        ask.setDefaultButton(QMessageBox::No);
        if (ask.exec() != QMessageBox::Yes) return;
    }
    try {
        m_store->deleteStudy(uid, area);
        setStatus(tr("Deleted %1 from the local store").arg(label));
        emit message(tr("Deleted %1 from the local store").arg(label), false);
    } catch (const std::exception& e) {
        setStatus(tr("Cannot delete %1: %2").arg(label, QString::fromUtf8(e.what())), true);
    }
    refreshLocal();
}

bool PacsDialog::eventFilter(QObject* watched, QEvent* event) {
    // Delete in Local studies: the list's shortcut takes it when the window is active; this
    // when the key comes otherwise (the shortcut then never fires, so it is never done twice).
    if (watched == m_local && event->type() == QEvent::KeyPress &&
        static_cast<QKeyEvent*>(event)->key() == Qt::Key_Delete) {
        deleteSelectedLocal();
        return true;
    }
    return QDialog::eventFilter(watched, event);
}

void PacsDialog::keyPressEvent(QKeyEvent* event) {
    // The focus within the dialog (focusWidget(): also while the window is not the active one).
    const auto within = [this](QWidget* w) {
        return focusWidget() && (focusWidget() == w || w->isAncestorOf(focusWidget()));
    };
    const bool enter = event->key() == Qt::Key_Return || event->key() == Qt::Key_Enter;
    if (!enter || (event->modifiers() & ~Qt::KeypadModifier)) {
        QDialog::keyPressEvent(event);
        return;
    }
    if (m_tabs->currentWidget()->isAncestorOf(m_local))
        openLocal();
    else if (within(m_results) && !m_results->selectedItems().isEmpty())
        retrieveSelected(true);
    else
        search();
}

} // namespace fvr::ui
