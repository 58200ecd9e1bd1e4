#pragma once
/** Our storage SCP (C-STORE, and C-ECHO): the destination of C-MOVE retrieves and of studies a
 *  PACS pushes to us. */
#include <memory>
#include <string>

#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>

namespace fvr::core::pacs {

/**
 * Listens on local.listenPort (all interfaces) on its own thread, accepts associations whose
 * called AE title is local.aeTitle (others are rejected: "called AE title not recognised"),
 * and writes every instance atomically into `store` (LocalStore::storeInstance). One
 * association at a time. The store must outlive the listener.
 */
class StorageListener {
public:
    StorageListener(LocalAe local, LocalStore& store);
    ~StorageListener(); ///< stop()
    StorageListener(const StorageListener&) = delete;
    StorageListener& operator=(const StorageListener&) = delete;

    /** Opens the port and starts the thread. Throws PacsError ("cannot listen on port 11112:
     *  Address already in use"). No-op when running. */
    void start();
    /** Stops accepting (at once: the thread's wait is woken), lets an association in progress
     *  finish (each of its messages bounded by the timeout), joins the thread. */
    void stop();
    bool running() const;
    const LocalAe& local() const;
    LocalStore& store() const;
    /** The last error of the thread (a failed write, a broken association), empty if none. */
    std::string lastError() const;

    /** The listener running in this process on `port`, or nullptr (retrieve's C-MOVE uses it). */
    static StorageListener* runningOn(int port);

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace fvr::core::pacs
