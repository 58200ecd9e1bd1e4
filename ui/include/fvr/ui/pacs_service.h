#pragma once
/** The workstation's PACS state beside the dialog: the local study store (one per process,
 *  shared by retrieves and the listener), the retrieve queue, the storage listener that the
 *  settings start and stop, and sends (C-STORE) on worker threads. */
#include <QObject>

#include <filesystem>
#include <memory>
#include <vector>

#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/storage_listener.h>
#include <fvr/ui/background_job.h>
#include <fvr/ui/retrieve_queue.h>

namespace fvr::ui {

struct PacsSettings;

class PacsService : public QObject {
    Q_OBJECT
public:
    /** `storeRoot` empty: core::pacs::defaultLocalStoreRoot(). */
    explicit PacsService(std::filesystem::path storeRoot = {}, QObject* parent = nullptr);
    ~PacsService() override; ///< stops the listener, waits for sends

    const std::shared_ptr<core::pacs::LocalStore>& store() const { return m_store; }
    /** The retrieves into the store, one after another, whether the PACS dialog is open or not. */
    RetrieveQueue& retrieves() { return *m_retrieves; }
    /** Starts or stops the listener as `s` says (restarted when any of what it is made from
     *  changed: AE title, port, address, allowed peers, TLS, timeout). Returns what happened, for
     * the Messages panel; `ok` false when it could not start. What it refuses or quarantines comes
     * as listenerEvent(). */
    QString applyListener(const PacsSettings& s, bool* ok = nullptr);
    bool listening() const { return m_listener && m_listener->running(); }
    /** Sends `files` to `node` on a worker thread, then removes `cleanup` (a temporary folder, if
     *  not empty); sent() tells the outcome. */
    void send(const core::pacs::Node& node, const core::pacs::LocalAe& local,
              std::vector<std::filesystem::path> files, std::filesystem::path cleanup = {});
    bool sending() const { return m_sending > 0; }

signals:
    void sent(bool ok, const QString& message);
    /** The listener refused a peer or an instance, quarantined one, or received a study into
     *  Incoming (`problem` false), in words that name the peer. */
    void listenerEvent(bool problem, const QString& message);

private:
    std::shared_ptr<core::pacs::LocalStore> m_store;
    std::unique_ptr<core::pacs::StorageListener> m_listener;
    std::unique_ptr<RetrieveQueue> m_retrieves;
    int m_sending = 0;
    BackgroundJobs m_jobs{this}; ///< sends; waited for before the store goes
};

} // namespace fvr::ui
