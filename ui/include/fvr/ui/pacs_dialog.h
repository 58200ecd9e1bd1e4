#pragma once
/** File ▸ PACS…: find studies on a PACS node (C-FIND); queue retrieves of studies and series
 *  into the local study store (C-GET or C-MOVE; RetrieveQueue, which goes on while the dialog is
 *  closed) with progress and cancel; the queue; the local studies (open again without the
 *  network, resume a partial retrieve, delete). Network work runs on worker threads, never on
 *  the GUI thread (BackgroundJobs); results and progress come back on the GUI thread. */
#include <QDialog>

#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/ui/background_job.h>
#include <fvr/ui/pacs_settings.h>
#include <fvr/ui/retrieve_queue.h>

class QComboBox;
class QKeyEvent;
class QDateEdit;
class QLabel;
class QLineEdit;
class QProgressBar;
class QPushButton;
class QTabWidget;
class QTreeWidget;
class QTreeWidgetItem;

namespace fvr::ui {

class PacsDialog : public QDialog {
    Q_OBJECT
public:
    /** `queue`: the retrieves, and through it the local study store, shared with the storage
     *  listener (one object per process: it serialises their writes). It outlives the dialog. */
    explicit PacsDialog(RetrieveQueue& queue, QWidget* parent = nullptr);
    ~PacsDialog() override;

    /** Reloads the nodes from the settings (after Edit nodes or elsewhere). */
    void reloadSettings();
    /** Whether a network job (echo, find) runs, or a retrieve waits or runs. */
    bool busy() const { return m_pending > 0 || m_queue.busy(); }
    /** Shows the Retrieves tab (the queue). */
    void showQueue();

    // For tests, which drive the dialog as a user does.
    QComboBox* nodeCombo() const { return m_node; }
    QLineEdit* patientNameEdit() const { return m_patientName; }
    QLineEdit* patientIdEdit() const { return m_patientId; }
    QComboBox* datePresetCombo() const { return m_datePreset; }
    QDateEdit* dateFromEdit() const { return m_dateFrom; }
    QDateEdit* dateToEdit() const { return m_dateTo; }
    QComboBox* modalityCombo() const { return m_modality; }
    QPushButton* echoButton() const { return m_echo; }
    QPushButton* editNodesButton() const { return m_editNodes; }
    QPushButton* deleteLocalButton() const { return m_deleteLocal; }
    QPushButton* resumeLocalButton() const { return m_resumeLocal; }
    QTabWidget* tabs() const { return m_tabs; }
    QPushButton* searchButton() const { return m_search; }
    QPushButton* retrieveButton() const { return m_retrieve; } ///< "Retrieve and open"
    QPushButton* queueButton() const { return m_queueRetrieve; } ///< "Retrieve" (no open)
    QPushButton* cancelButton() const { return m_cancel; }
    QTreeWidget* results() const { return m_results; }
    QTreeWidget* localStudies() const { return m_local; }
    QTreeWidget* queueList() const { return m_queueList; }
    QProgressBar* progress() const { return m_progress; }
    QLabel* status() const { return m_status; }
    /** Whether the status line says what failed (drawn in red). */
    bool statusIsError() const { return m_statusError; }
    /** The query the form describes. */
    core::pacs::StudyQuery query() const;
    /** Deletes the study selected in Local studies (files and index entry), after asking when
     *  `confirm` (a question box named "confirmDelete"). Refused, saying why, while a retrieve
     *  runs on it. */
    void deleteSelectedLocal(bool confirm = true);

signals:
    /** A complete study or series in the local store, to open like a folder. */
    void openRequested(const QString& folder);
    /** For the Messages panel. */
    void message(const QString& text, bool error);
    /** Edit nodes… saved new settings: the listener is to follow them at once. */
    void settingsChanged();

protected:
    /** Enter: retrieves and opens the selected result when the results have the focus, opens
     *  the selected local study in Local studies, else searches (once: no default button). */
    void keyPressEvent(QKeyEvent* event) override;
    /** The Delete key in Local studies. */
    bool eventFilter(QObject* watched, QEvent* event) override;

private:
    QWidget* buildQueryTab();
    QWidget* buildQueryForm();
    QWidget* buildLocalTab();
    QWidget* buildQueueTab();
    /** Runs `work` on a worker thread; `done` runs on the GUI thread with its error (none on
     *  success) unless the dialog is gone. The dialog's destructor waits for the jobs with
     *  `waitAtClose` (retrieves, cancelled first), not for the others (an echo or a query may
     *  wait for the network timeout). Returns the job's cancel token. */
    std::shared_ptr<core::CancelToken> run(std::function<void(core::CancelToken&)> work,
                                           std::function<void(const std::optional<JobError>&)> done,
                                           bool waitAtClose = false);
    const core::pacs::Node* currentNode() const;
    void testConnection();
    /** After a good C-ECHO: a C-FIND on a key no study has, which a PACS that does not know our
     *  AE title refuses. */
    void verifyAeTitle(const core::pacs::Node& n);
    void search();
    void showStudies(const std::vector<core::pacs::StudyRecord>& studies);
    void loadSeries(QTreeWidgetItem* study);
    /** The series found for `study` (or the query's error) as its children. */
    void addSeries(QTreeWidgetItem* study, const QString& error,
                   const std::vector<core::pacs::SeriesRecord>& found);
    /** Queues each selected result (a series alone when its study is not selected too); with
     *  `open`, the first opens when it ends (RetrieveQueue::shouldOpen). `refresh`: again from
     *  the PACS, what the store has complete too. */
    void retrieveSelected(bool open, bool refresh = false);
    void retrieve(const core::pacs::Node& node, const std::string& studyUid,
                  const std::string& seriesUid, const QString& label, bool open,
                  bool refresh = false);
    /** The bottom strip and the Retrieves tab follow the queue. */
    void onQueueChanged();
    void onRetrieveEnded(int id);
    void fillQueueList();
    void refreshLocal();
    /** The results' Local column: complete or partial for what the store holds. */
    void markLocalState();
    void openLocal();
    void resumeLocal();
    /** The status line; an error goes to the Messages panel too unless `toMessages` is false
     *  (what the queue reports itself). */
    void setStatus(const QString& text, bool error = false, bool toMessages = true);
    void updateButtons();

    RetrieveQueue& m_queue;
    std::shared_ptr<core::pacs::LocalStore> m_store;
    PacsSettings m_settings;
    int m_pending = 0; ///< echo and find jobs whose outcome has not been handled
    bool m_statusError = false; ///< the status line says what failed (in red)

    QTabWidget* m_tabs = nullptr;
    QComboBox* m_node = nullptr;
    QPushButton* m_echo = nullptr;
    QPushButton* m_editNodes = nullptr;
    QPushButton* m_deleteLocal = nullptr;
    QLineEdit* m_patientName = nullptr;
    QLineEdit* m_patientId = nullptr;
    QLineEdit* m_accession = nullptr;
    QComboBox* m_datePreset = nullptr;
    QDateEdit* m_dateFrom = nullptr;
    QDateEdit* m_dateTo = nullptr;
    QComboBox* m_modality = nullptr;
    QPushButton* m_search = nullptr;
    QTreeWidget* m_results = nullptr;
    QPushButton* m_retrieve = nullptr;
    QPushButton* m_queueRetrieve = nullptr;
    QPushButton* m_cancel = nullptr;
    QProgressBar* m_progress = nullptr;
    QLabel* m_status = nullptr;
    QTreeWidget* m_local = nullptr;
    QPushButton* m_openLocal = nullptr;
    QPushButton* m_resumeLocal = nullptr;
    QTreeWidget* m_queueList = nullptr;
    QPushButton* m_cancelQueued = nullptr;
    BackgroundJobs m_jobs{this}; ///< echoes and finds (abandoned at close)
};

} // namespace fvr::ui
