#pragma once
/** Our storage SCP (C-STORE, and C-ECHO): the destination of C-MOVE retrieves and of studies a
 *  PACS pushes to us. */
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>

namespace fvr::core::pacs {

/**
 * Listens on local.listenAddress:local.listenPort (127.0.0.1 unless told otherwise) on its own
 * thread, and writes what it accepts atomically into `store`. One association at a time. The
 * store must outlive the listener.
 *
 * Whom it trusts:
 * - the called AE title must be local.aeTitle ("called AE title not recognised" otherwise);
 * - the calling AE title (and host, by address) must be one of local.allowedPeers, or a PACS
 *   that a running C-MOVE expects (expect()); anyone else is rejected when it asks for the
 *   association ("calling AE title not recognised"), and an Event names it.
 *
 * Where an instance goes:
 * - of the study (series) a C-MOVE asked for, from the PACS it asked: into the study;
 * - anything else from an allowed peer: into the store's Incoming area (never into a study);
 * - anything else from a PACS accepted only for a C-MOVE: refused (status 0x0124, "Refused:
 *   Not Authorized"), since nobody asked for it;
 * - an instance whose SOP Instance UID the store already holds with other bytes: quarantined by
 *   the store, answered with status 0x0111 ("Duplicate SOP Instance"), and an Event.
 */
class StorageListener {
public:
    /** What the listener did not simply take, or a study it received into Incoming: for the
     *  user (the workstation's Messages panel). */
    struct Event {
        enum class Kind {
            Refused, ///< an association from a peer that is not allowed
            NotAuthorized, ///< an instance nobody asked for, from a PACS allowed for a move only
            Quarantined, ///< a different instance under a stored SOP Instance UID
            Failed, ///< an instance that could not be stored (disk full, bad UID, ...)
            Incoming, ///< an allowed peer's association ended: what it sent is in Incoming
        };
        Kind kind;
        std::string text; ///< in words; names the peer ("ATTACKER at 10.0.0.7")
    };
    using EventFn = std::function<void(const Event&)>;

    struct Expectations; // shared by the listener's thread and every Expectation

    /** A C-MOVE in progress, as the listener knows it (expect()): while the object lives, the
     *  node's AE title, from the node's host, may store instances of the study (the series when
     *  given) into the study. Ends when destroyed. Stays valid if the listener stops first. */
    class Expectation {
    public:
        Expectation() = default;
        Expectation(std::shared_ptr<Expectations> table, std::uint64_t id);
        Expectation(Expectation&& other) noexcept;
        Expectation& operator=(Expectation&& other) noexcept;
        ~Expectation(); ///< end()
        /** Distinct instances of the study (series) taken into it from the node while this
         *  move ran (moves of the same study at once each count what arrives). */
        int received() const;
        /** Why the last instance of this move was not taken (quarantined, not written), empty
         *  if none. */
        std::string lastProblem() const;
        void end();

    private:
        std::shared_ptr<Expectations> m_table;
        std::uint64_t m_id = 0;
    };

    /** Throws PacsError when `local` is not valid (validateListener). `onEvent` is called on
     *  the listener's thread (keep it short; it must not call back into the listener). */
    StorageListener(LocalAe local, LocalStore& store, EventFn onEvent = {});
    ~StorageListener(); ///< stop()
    StorageListener(const StorageListener&) = delete;
    StorageListener& operator=(const StorageListener&) = delete;

    /** Opens the port and starts the thread. Throws PacsError ("cannot listen on
     *  127.0.0.1:11112: Address already in use"). No-op when running. */
    void start();
    /** Stops accepting (at once: the thread's wait is woken), lets an association in progress
     *  finish (each of its messages bounded by the timeout), joins the thread. */
    void stop();
    bool running() const;
    const LocalAe& local() const;
    LocalStore& store() const;
    /** The last error of the thread (a failed write, a broken association, a refused peer or
     *  instance), empty if none. */
    std::string lastError() const;
    /** The most recent events (at most 200), oldest first. */
    std::vector<Event> events() const;

    /** A C-MOVE from `node` of the study (seriesUid empty) or series starts: see Expectation.
     *  Throws PacsError when the node's host does not resolve. */
    Expectation expect(const Node& node, const std::string& studyUid, const std::string& seriesUid);

    /** The listener running in this process on `port`, or nullptr (retrieve's C-MOVE uses it). */
    static StorageListener* runningOn(int port);

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace fvr::core::pacs
