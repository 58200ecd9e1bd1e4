// Our storage SCP (DCMTK's DcmSCP) on its own thread, writing into a LocalStore.
#include "listener_trust.h"
#include "pacs_internal.h"

#include <fvr/core/errors.h>
#include <fvr/core/pacs/storage_listener.h>

#include <dcmtk/dcmnet/scp.h>

#include <arpa/inet.h>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fcntl.h>
#include <filesystem>
#include <map>
#include <mutex>
#include <netinet/in.h>
#include <set>
#include <sys/socket.h>
#include <thread>
#include <unistd.h>

namespace fvr::core::pacs {
namespace {

std::mutex g_registryMutex;
std::map<int, StorageListener*> g_registry; // running listeners by port

OFList<OFString> acceptedSyntaxes() {
    OFList<OFString> ts = detail::uncompressedSyntaxes();
    for (const char* uid :
         {UID_JPEGProcess14SV1TransferSyntax, UID_JPEGProcess14TransferSyntax,
          UID_JPEGProcess1TransferSyntax, UID_JPEGLSLosslessTransferSyntax,
          UID_JPEG2000LosslessOnlyTransferSyntax, UID_JPEG2000TransferSyntax,
          UID_RLELosslessTransferSyntax, UID_DeflatedExplicitVRLittleEndianTransferSyntax,
          UID_BigEndianExplicitTransferSyntax})
        ts.push_back(uid);
    return ts;
}

/** The address the listener binds, as a sockaddr (empty or 0.0.0.0: every interface). */
sockaddr_in bindAddress(const LocalAe& local) {
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(local.listenPort));
    addr.sin_addr.s_addr = htonl(INADDR_ANY);
    if (!local.listenAddress.empty())
        ::inet_pton(AF_INET, local.listenAddress.c_str(), &addr.sin_addr); // validated
    return addr;
}

/** A connection opened and closed at once: the thread, waiting for an association (1 s polls),
 *  sees stop() now rather than at its next poll. */
void wakeUp(const LocalAe& local) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return;
    sockaddr_in addr = bindAddress(local);
    if (addr.sin_addr.s_addr == htonl(INADDR_ANY)) addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
    ::close(fd);
}

std::string listenName(const LocalAe& local) {
    return (local.listenAddress.empty() ? std::string("0.0.0.0") : local.listenAddress) + ":" +
           std::to_string(local.listenPort);
}

// --- Binding one address ---
// DCMTK 3.6.7's DUL binds its listening socket to INADDR_ANY and has no setting for the address
// (its dcmExternalSocketHandle is an accepted connection, not a listening socket). So we bind
// and listen ourselves, let DCMTK open its network on an ephemeral port (0), and put our socket
// in place of its one (dup3 onto the same descriptor): DCMTK then accepts on our address and
// closes it when its network goes. Our socket is bound before DCMTK's, so the port is never
// free in between. The mutex keeps two listeners of this process from taking each other's.
std::mutex g_bindMutex;

/** Binds and listens on the listener's address; returns the socket. Throws PacsError. */
int boundSocket(const LocalAe& local) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        throw PacsError("cannot listen on " + listenName(local) + ": " + std::strerror(errno));
    const int on = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
    const sockaddr_in addr = bindAddress(local);
    if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0 ||
        ::listen(fd, 64) != 0) {
        const int err = errno;
        ::close(fd);
        throw PacsError("cannot listen on " + listenName(local) + ": " + std::strerror(err) +
                        (err == EADDRINUSE ? " (another program listens there: choose another port)"
                         : err == EADDRNOTAVAIL ? " (no interface of this machine has that address)"
                                                : ""));
    }
    return fd;
}

/** The descriptors of this process that are listening TCP sockets. */
std::set<int> listeningSockets() {
    std::set<int> out;
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator("/proc/self/fd", ec)) {
        const int fd = std::atoi(entry.path().filename().c_str());
        int listening = 0;
        socklen_t size = sizeof listening;
        if (::getsockopt(fd, SOL_SOCKET, SO_ACCEPTCONN, &listening, &size) == 0 && listening)
            out.insert(fd);
    }
    return out;
}

/** scp->openListenPort() with `fd` (boundSocket) in place of DCMTK's socket, which it takes
 *  over (closed here on failure). Throws PacsError. */
void openOn(DcmSCP& scp, int fd, const LocalAe& local) {
    std::lock_guard lock(g_bindMutex);
    const std::set<int> before = listeningSockets();
    scp.setPort(0);
    const OFCondition cond = scp.openListenPort();
    if (cond.bad()) {
        ::close(fd);
        throw PacsError("cannot listen on " + listenName(local) + ": " + cond.text());
    }
    std::vector<int> added;
    for (int s : listeningSockets())
        if (!before.count(s) && s != fd) added.push_back(s);
    if (added.size() != 1 || ::dup3(fd, added[0], O_CLOEXEC) < 0) {
        ::close(fd);
        throw PacsError("cannot listen on " + listenName(local) +
                        ": the DICOM network's socket cannot be bound to that address");
    }
    ::close(fd); // added[0] is the same socket now
    scp.setPort(static_cast<Uint16>(local.listenPort));
}
// --- end of binding one address ---

std::string peerName(const std::string& ae, const std::string& ip) { return ae + " at " + ip; }

} // namespace

// --- C-MOVE expectations ---
/** The C-MOVEs in progress that the listener takes instances for. */
struct StorageListener::Expectations {
    struct Record {
        std::string ae;
        std::vector<std::string> ips; ///< the node's addresses
        std::string study, series; ///< series empty: the whole study
        std::set<std::string> taken; ///< SOP instances taken into the study during this move
        std::string problem; ///< why the last instance was not taken
    };

    bool fromNode(const Record& r, const std::string& ae, const std::string& ip) const {
        return r.ae == ae && std::find(r.ips.begin(), r.ips.end(), ip) != r.ips.end();
    }
    /** Whether a C-MOVE expects anything from `ae` at `ip`. */
    bool admits(const std::string& ae, const std::string& ip) const {
        std::lock_guard lock(mutex);
        for (const auto& [id, r] : records)
            if (fromNode(r, ae, ip)) return true;
        return false;
    }
    /** The moves an instance belongs to: those from that node for its study (series). Moves of
     *  the same study at once cannot be told apart (DIMSE does not say which C-MOVE a store
     *  serves), so each of them counts it: it arrived while each of them ran. */
    std::vector<std::uint64_t> match(const std::string& ae, const std::string& ip,
                                     const std::string& study, const std::string& series) const {
        std::lock_guard lock(mutex);
        std::vector<std::uint64_t> out;
        for (const auto& [id, r] : records)
            if (fromNode(r, ae, ip) && r.study == study && (r.series.empty() || r.series == series))
                out.push_back(id);
        return out;
    }
    void taken(std::uint64_t id, const std::string& sop) {
        std::lock_guard lock(mutex);
        if (auto it = records.find(id); it != records.end()) it->second.taken.insert(sop);
    }
    void problem(std::uint64_t id, const std::string& text) {
        std::lock_guard lock(mutex);
        if (auto it = records.find(id); it != records.end()) it->second.problem = text;
    }
    /** "ORTHANC@127.0.0.1 (study 1.2.3)", for messages; "none" when no move runs. */
    std::string describeAll() const {
        std::lock_guard lock(mutex);
        std::string out;
        for (const auto& [id, r] : records)
            out += (out.empty() ? "" : ", ") + r.ae + "@" + (r.ips.empty() ? "?" : r.ips[0]) +
                   " (" + (r.series.empty() ? "study " + r.study : "series " + r.series) + ")";
        return out.empty() ? "none" : out;
    }

    mutable std::mutex mutex;
    std::map<std::uint64_t, Record> records;
    std::uint64_t next = 1;
};

StorageListener::Expectation::Expectation(std::shared_ptr<Expectations> table, std::uint64_t id)
    : m_table(std::move(table)), m_id(id) {}

StorageListener::Expectation::Expectation(Expectation&& other) noexcept
    : m_table(std::move(other.m_table)), m_id(other.m_id) {
    other.m_id = 0;
}

StorageListener::Expectation& StorageListener::Expectation::operator=(
    Expectation&& other) noexcept {
    if (this != &other) {
        end();
        m_table = std::move(other.m_table);
        m_id = other.m_id;
        other.m_id = 0;
    }
    return *this;
}

StorageListener::Expectation::~Expectation() { end(); }

int StorageListener::Expectation::received() const {
    if (!m_table) return 0;
    std::lock_guard lock(m_table->mutex);
    const auto it = m_table->records.find(m_id);
    return it == m_table->records.end() ? 0 : static_cast<int>(it->second.taken.size());
}

std::string StorageListener::Expectation::lastProblem() const {
    if (!m_table) return "";
    std::lock_guard lock(m_table->mutex);
    const auto it = m_table->records.find(m_id);
    return it == m_table->records.end() ? "" : it->second.problem;
}

void StorageListener::Expectation::end() {
    if (!m_table) return;
    {
        std::lock_guard lock(m_table->mutex);
        m_table->records.erase(m_id);
    }
    m_table.reset();
    m_id = 0;
}
// --- end of C-MOVE expectations ---

/** What the listener's thread and its SCP share. */
struct ListenerState {
    ListenerState(LocalAe l, LocalStore& s, StorageListener::EventFn fn)
        : local(std::move(l)), store(s), onEvent(std::move(fn)),
          expectations(std::make_shared<StorageListener::Expectations>()) {}

    void setError(const std::string& text) {
        std::lock_guard lock(mutex);
        error = text;
    }

    /** Records an event (and, but for Incoming, the last error) and tells onEvent. */
    void event(StorageListener::Event::Kind kind, const std::string& text) {
        {
            std::lock_guard lock(mutex);
            if (kind != StorageListener::Event::Kind::Incoming) error = text;
            events.push_back({kind, text});
            if (events.size() > 200) events.pop_front();
        }
        if (onEvent) onEvent({kind, text});
    }

    /** Whether `ae` at `ip` is one of local.allowedPeers. */
    bool allowed(const std::string& ae, const std::string& ip) const {
        for (const Peer& p : local.allowedPeers)
            if (detail::trimAe(p.aeTitle) == ae && detail::hostMatches(p.host, ip)) return true;
        return false;
    }

    std::string allowedText() const {
        std::string out;
        for (const Peer& p : local.allowedPeers) out += (out.empty() ? "" : ", ") + describe(p);
        return out.empty() ? "none" : out;
    }

    LocalAe local;
    LocalStore& store;
    StorageListener::EventFn onEvent;
    std::shared_ptr<StorageListener::Expectations> expectations;
    std::unique_ptr<detail::WatchedLayer> layer; // plain or TLS; outlives the SCP that uses it
    /** Fired by stop(): a peer that has gone silent mid-association is left within a second
     *  instead of at the timeout (a retrieve's listener stops when its cancel ends it). */
    std::unique_ptr<CancelToken> stopping;
    std::unique_ptr<DcmSCP> scp;
    std::thread thread;
    std::atomic<bool> stop{false}, running{false};
    mutable std::mutex mutex;
    std::string error;
    std::deque<StorageListener::Event> events;
};

struct StorageListener::Impl : ListenerState {
    using ListenerState::ListenerState;
};

/** The SCP: C-ECHO by DcmSCP, C-STORE into the store; called AE = ours only, calling AE = an
 *  allowed or expected peer only. */
class ListenerScp : public DcmSCP {
public:
    explicit ListenerScp(ListenerState& impl) : m_impl(impl) {}

protected:
    OFCondition handleIncomingCommand(T_DIMSE_Message* msg,
                                      const DcmPresentationContextInfo& info) override {
        if (msg->CommandField != DIMSE_C_STORE_RQ) return DcmSCP::handleIncomingCommand(msg, info);
        T_DIMSE_C_StoreRQ& req = msg->msg.CStoreRQ;
        DcmDataset* received = nullptr;
        OFCondition cond = receiveSTORERequest(req, info.presentationContextID, received);
        std::unique_ptr<DcmDataset> owned(received);
        if (cond.bad()) {
            m_impl.setError(std::string("receiving an instance from ") + peer() +
                            " failed: " + cond.text());
            return cond;
        }
        Uint16 status = STATUS_STORE_Error_CannotUnderstand;
        if (!owned)
            m_impl.event(StorageListener::Event::Kind::Failed,
                         peer() + " sent a C-STORE request without a dataset");
        else
            status = take(*owned);
        return sendSTOREResponse(info.presentationContextID, req, status);
    }

    OFBool checkCalledAETitleAccepted(const OFString& calledAe) override {
        return detail::trimAe(calledAe.c_str()) == m_impl.local.aeTitle;
    }

    // --- Whom the listener trusts ---
    /** The association's peer: an allowed peer (its own stores go to Incoming) or a PACS that a
     *  C-MOVE expects (only what the move asked for); anyone else is rejected now. */
    OFBool checkCallingAETitleAccepted(const OFString& callingAe) override {
        m_ae = detail::trimAe(callingAe.c_str());
        m_ip = getPeerIP().c_str();
        m_allowed = m_impl.allowed(m_ae, m_ip);
        if (m_allowed || m_impl.expectations->admits(m_ae, m_ip)) return OFTrue;
        m_impl.event(
            StorageListener::Event::Kind::Refused,
            "storage listener " + listenName(m_impl.local) + ": refused an association from " +
                peer() +
                ": calling AE title not recognised (allowed peers: " + m_impl.allowedText() +
                "; expected for a C-MOVE: " + m_impl.expectations->describeAll() + ")");
        return OFFalse;
    }
    // --- end of whom the listener trusts ---

    /** The studies this association brought into Incoming, for the user: "12 of DOE^JANE,
     *  20240102, CHEST (complete)", joined by "; ". */
    std::string arrivedText() const {
        std::string out;
        for (const auto& [study, n] : m_incomingCount) {
            std::string what = "study " + study;
            try {
                if (const auto e = m_impl.store.find(study, Area::Incoming)) {
                    const StudyRecord& r = e->study;
                    what = r.patientName.empty() ? "an unnamed patient" : r.patientName;
                    for (const std::string* f : {&r.studyDate, &r.description})
                        if (!f->empty()) what += ", " + *f;
                    what += e->complete ? " (complete)" : " (partial)";
                }
            } catch (const std::exception&) { // the index unreadable: the UID says which
            }
            out += (out.empty() ? "" : "; ") + std::to_string(n) + " of " + what;
        }
        return out;
    }

    void notifyReleaseRequest() override {
        // The sender ended normally: what it sent into Incoming is complete there.
        int count = 0;
        for (const auto& [study, series] : m_incoming) {
            try {
                markIncoming(study, series);
            } catch (const std::exception& e) {
                m_impl.setError(e.what());
            }
        }
        for (const auto& [study, n] : m_incomingCount) count += n;
        if (count > 0)
            m_impl.event(StorageListener::Event::Kind::Incoming,
                         peer() + " sent " + std::to_string(count) +
                             " instance(s): " + arrivedText() + "; in Local studies (Incoming)");
        m_incoming.clear();
        m_incomingCount.clear();
        DcmSCP::notifyReleaseRequest();
    }

    void notifyAssociationTermination() override {
        m_incoming.clear(); // aborted: what arrived stays partial
        m_incomingCount.clear();
        DcmSCP::notifyAssociationTermination();
    }

    OFBool stopAfterConnectionTimeout() override { return m_impl.stop.load(); }
    OFBool stopAfterCurrentAssociation() override { return m_impl.stop.load(); }

private:
    std::string peer() const { return peerName(m_ae, m_ip); }

    Uint16 take(DcmDataset& dataset);
    Uint16 store(DcmDataset& dataset, bool incoming, std::string& problem);
    void markIncoming(const std::string& study, const std::set<std::string>& series);

    ListenerState& m_impl;
    std::string m_ae, m_ip; // this association's peer
    bool m_allowed = false; // an allowed peer (not only expected for a C-MOVE)
    std::map<std::string, std::set<std::string>> m_incoming; // this association's, into Incoming
    std::map<std::string, int> m_incomingCount;
};

/** One received instance: into the study a C-MOVE asked for it, into Incoming from an allowed
 *  peer, refused otherwise. Returns the C-STORE status. */
Uint16 ListenerScp::take(DcmDataset& dataset) {
    OFString study, series, sop;
    dataset.findAndGetOFString(DCM_StudyInstanceUID, study);
    dataset.findAndGetOFString(DCM_SeriesInstanceUID, series);
    dataset.findAndGetOFString(DCM_SOPInstanceUID, sop);
    const std::vector<std::uint64_t> moves =
        m_impl.expectations->match(m_ae, m_ip, study.c_str(), series.c_str());
    if (moves.empty() && !m_allowed) {
        // A PACS accepted for a C-MOVE only, sending what the move did not ask for.
        m_impl.event(StorageListener::Event::Kind::NotAuthorized,
                     peer() + " sent instance " + sop.c_str() + " of study " + study.c_str() +
                         ", which no retrieve asked it for: refused");
        return STATUS_STORE_Refused_NotAuthorized;
    }
    std::string problem;
    const Uint16 status = store(dataset, moves.empty(), problem);
    for (const std::uint64_t move : moves) {
        if (status == STATUS_Success)
            m_impl.expectations->taken(move, sop.c_str());
        else
            m_impl.expectations->problem(move, problem);
    }
    if (moves.empty() && status == STATUS_Success) {
        m_incoming[study.c_str()].insert(series.c_str());
        ++m_incomingCount[study.c_str()];
    }
    return status;
}

// --- Storing into the store's areas ---
/** PS3.7 Annex C's general failure "Duplicate SOP Instance" (DCMTK names it for the N-services
 *  only: STATUS_N_DuplicateSOPInstance). */
constexpr Uint16 kStatusDuplicateSopInstance = 0x0111;

/** Writes the instance (into Incoming when `incoming`). Identical bytes again: success (the
 *  sender's copy is ours). Other bytes under a stored SOP Instance UID: the store keeps its file
 *  and quarantines these; the sender hears 0x0111 (Duplicate SOP Instance, PS3.7 C), a
 *  failure, so that it does not count the instance as delivered. */
Uint16 ListenerScp::store(DcmDataset& dataset, bool incoming, std::string& problem) {
    try {
        const detail::StoredDataset stored =
            detail::storeDataset(m_impl.store, dataset, incoming ? Area::Incoming : Area::Studies);
        if (stored.outcome.result != StoreResult::Quarantined) return STATUS_Success;
        problem = stored.outcome.message;
        m_impl.event(StorageListener::Event::Kind::Quarantined, peer() + ": " + problem);
        return kStatusDuplicateSopInstance;
    } catch (const WriteError& e) {
        problem = e.what();
        m_impl.event(StorageListener::Event::Kind::Failed, peer() + ": " + problem);
        return STATUS_STORE_Refused_OutOfResources;
    } catch (const std::exception& e) {
        problem = e.what();
        m_impl.event(StorageListener::Event::Kind::Failed, peer() + ": " + problem);
        return STATUS_STORE_Error_CannotUnderstand;
    }
}

void ListenerScp::markIncoming(const std::string& study, const std::set<std::string>& series) {
    m_impl.store.markReceived(study, series, Area::Incoming);
}
// --- end of storing into the store's areas ---

StorageListener::StorageListener(LocalAe local, LocalStore& store, EventFn onEvent)
    : m_impl(std::make_unique<Impl>(std::move(local), store, std::move(onEvent))) {
    validateListener(m_impl->local);
    detail::prepareNetwork();
}

StorageListener::~StorageListener() { stop(); }

void StorageListener::start() {
    if (running()) return;
    const int port = m_impl->local.listenPort;
    {
        std::lock_guard lock(g_registryMutex);
        if (g_registry.count(port))
            throw PacsError("cannot listen on port " + std::to_string(port) +
                            ": another storage listener of this program uses it");
    }
    auto scp = std::make_unique<ListenerScp>(*m_impl);
    scp->setPort(static_cast<Uint16>(port));
    scp->setAETitle(m_impl->local.aeTitle.c_str());
    scp->setConnectionBlockingMode(DUL_NOBLOCK);
    scp->setConnectionTimeout(1); // how often the thread looks at stop()
    scp->setDIMSEBlockingMode(DIMSE_NONBLOCKING);
    scp->setDIMSETimeout(static_cast<Uint32>(m_impl->local.timeoutSeconds));
    scp->setACSETimeout(static_cast<Uint32>(m_impl->local.timeoutSeconds));
    scp->setMaxReceivePDULength(ASC_MAXIMUMPDUSIZE);
    scp->setHostLookupEnabled(OFFalse);
    // Our transport: TLS only when local.listenTls (else plain only), every wait bounded.
    m_impl->layer = detail::makeLayer(m_impl->local, m_impl->local.listenTls, NET_ACCEPTOR);
    scp->getConfig().setTransportLayer(m_impl->layer.get());
    m_impl->stopping = std::make_unique<CancelToken>();
    m_impl->layer->setCancel(m_impl->stopping.get());
    const OFList<OFString> syntaxes = acceptedSyntaxes();
    scp->addPresentationContext(UID_VerificationSOPClass, detail::uncompressedSyntaxes());
    for (int i = 0; i < numberOfDcmLongSCUStorageSOPClassUIDs; ++i)
        scp->addPresentationContext(dcmLongSCUStorageSOPClassUIDs[i], syntaxes);
    openOn(*scp, boundSocket(m_impl->local), m_impl->local);
    m_impl->scp = std::move(scp);
    m_impl->stop = false;
    m_impl->running = true;
    {
        std::lock_guard lock(g_registryMutex);
        g_registry[port] = this;
    }
    m_impl->thread = std::thread([impl = static_cast<ListenerState*>(m_impl.get())] {
        const OFCondition result = impl->scp->acceptAssociations();
        if (result.bad() && result != NET_EC_StopAfterConnectionTimeout &&
            result != NET_EC_StopAfterAssociation)
            impl->setError(std::string("the listener stopped: ") + result.text());
        impl->running = false;
    });
}

void StorageListener::stop() {
    if (!m_impl->thread.joinable()) return;
    m_impl->stop = true;
    m_impl->stopping->cancel();
    wakeUp(m_impl->local);
    m_impl->thread.join();
    m_impl->scp.reset(); // closes the port
    m_impl->running = false;
    std::lock_guard lock(g_registryMutex);
    auto it = g_registry.find(m_impl->local.listenPort);
    if (it != g_registry.end() && it->second == this) g_registry.erase(it);
}

bool StorageListener::running() const { return m_impl->running.load(); }
const LocalAe& StorageListener::local() const { return m_impl->local; }
LocalStore& StorageListener::store() const { return m_impl->store; }

std::string StorageListener::lastError() const {
    std::lock_guard lock(m_impl->mutex);
    return m_impl->error;
}

std::vector<StorageListener::Event> StorageListener::events() const {
    std::lock_guard lock(m_impl->mutex);
    return {m_impl->events.begin(), m_impl->events.end()};
}

StorageListener::Expectation StorageListener::expect(const Node& node, const std::string& studyUid,
                                                     const std::string& seriesUid) {
    Expectations::Record r;
    r.ae = detail::trimAe(node.calledAe);
    r.ips = detail::ipv4Addresses(node.host);
    if (r.ips.empty())
        throw PacsError(describe(node) + ": the host \"" + node.host +
                        "\" does not resolve to an IPv4 address: our listener could not tell "
                        "its C-MOVE from anyone else's stores");
    r.study = studyUid;
    r.series = seriesUid;
    auto& table = *m_impl->expectations;
    std::lock_guard lock(table.mutex);
    const std::uint64_t id = table.next++;
    table.records.emplace(id, std::move(r));
    return Expectation(m_impl->expectations, id);
}

StorageListener* StorageListener::runningOn(int port) {
    std::lock_guard lock(g_registryMutex);
    auto it = g_registry.find(port);
    return it == g_registry.end() ? nullptr : it->second;
}

} // namespace fvr::core::pacs
