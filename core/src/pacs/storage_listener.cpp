// Our storage SCP (DCMTK's DcmSCP) on its own thread, writing into a LocalStore.
#include "pacs_internal.h"

#include <fvr/core/pacs/storage_listener.h>

#include <dcmtk/dcmnet/scp.h>

#include <arpa/inet.h>
#include <atomic>
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

/** A connection opened and closed at once: the thread, waiting for an association (1 s polls),
 *  sees stop() now rather than at its next poll. */
void wakeUp(int port) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return;
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
    ::close(fd);
}

} // namespace

/** What the listener's thread and its SCP share. */
struct ListenerState {
    ListenerState(LocalAe l, LocalStore& s) : local(std::move(l)), store(s) {}

    void setError(const std::string& text) {
        std::lock_guard lock(mutex);
        error = text;
    }

    LocalAe local;
    LocalStore& store;
    std::unique_ptr<detail::WatchedLayer> layer; // plain or TLS; outlives the SCP that uses it
    std::unique_ptr<DcmSCP> scp;
    std::thread thread;
    std::atomic<bool> stop{false}, running{false};
    mutable std::mutex mutex;
    std::string error;
};

struct StorageListener::Impl : ListenerState {
    using ListenerState::ListenerState;
};

/** The SCP: C-ECHO by DcmSCP, C-STORE into the store; called AE = ours only. */
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
            m_impl.setError(std::string("receiving an instance failed: ") + cond.text());
            return cond;
        }
        Uint16 status = STATUS_STORE_Refused_OutOfResources;
        try {
            if (!owned) throw PacsError("a C-STORE request came without a dataset");
            const auto stored = detail::storeDataset(m_impl.store, *owned);
            m_received[stored.studyUid].insert(stored.seriesUid);
            status = STATUS_Success;
        } catch (const std::exception& e) {
            m_impl.setError(e.what());
        }
        return sendSTOREResponse(info.presentationContextID, req, status);
    }

    OFBool checkCalledAETitleAccepted(const OFString& calledAe) override {
        std::string trimmed = calledAe.c_str();
        while (!trimmed.empty() && trimmed.back() == ' ') trimmed.pop_back();
        return trimmed == m_impl.local.aeTitle;
    }

    void notifyReleaseRequest() override {
        // The sender ended normally: what it sent is complete (LocalStore::markReceived).
        for (const auto& [study, series] : m_received) {
            try {
                m_impl.store.markReceived(study, series);
            } catch (const std::exception& e) {
                m_impl.setError(e.what());
            }
        }
        m_received.clear();
        DcmSCP::notifyReleaseRequest();
    }

    void notifyAssociationTermination() override {
        m_received.clear(); // aborted: what arrived stays partial
        DcmSCP::notifyAssociationTermination();
    }

    OFBool stopAfterConnectionTimeout() override { return m_impl.stop.load(); }
    OFBool stopAfterCurrentAssociation() override { return m_impl.stop.load(); }

private:
    ListenerState& m_impl;
    std::map<std::string, std::set<std::string>> m_received; // this association's
};

StorageListener::StorageListener(LocalAe local, LocalStore& store)
    : m_impl(std::make_unique<Impl>(std::move(local), store)) {
    validate(m_impl->local);
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
    const OFList<OFString> syntaxes = acceptedSyntaxes();
    scp->addPresentationContext(UID_VerificationSOPClass, detail::uncompressedSyntaxes());
    for (int i = 0; i < numberOfDcmLongSCUStorageSOPClassUIDs; ++i)
        scp->addPresentationContext(dcmLongSCUStorageSOPClassUIDs[i], syntaxes);
    const OFCondition cond = scp->openListenPort();
    if (cond.bad())
        throw PacsError("cannot listen on port " + std::to_string(port) + ": " + cond.text() +
                        (std::string(cond.text()).find("in use") != std::string::npos
                             ? " (another program listens there: choose another port)"
                             : ""));
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
    wakeUp(m_impl->local.listenPort);
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

StorageListener* StorageListener::runningOn(int port) {
    std::lock_guard lock(g_registryMutex);
    auto it = g_registry.find(port);
    return it == g_registry.end() ? nullptr : it->second;
}

} // namespace fvr::core::pacs
