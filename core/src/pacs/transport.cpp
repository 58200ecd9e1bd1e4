// Our transport layer: DCMTK's plain or TLS connections wrapped so that every wait for the peer
// ends at one deadline, and what each connection saw is kept for the failure's words.
#include "transport.h"

#include <dcmtk/dcmnet/dcmtrans.h>
#include <dcmtk/dcmtls/tlscond.h>
#include <dcmtk/dcmtls/tlslayer.h>

#include <openssl/err.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <fstream>
#include <mutex>
#include <optional>
#include <thread>

#include <poll.h>
#include <sys/socket.h>
#include <sys/time.h>

namespace fvr::core::pacs::detail {
namespace {

using Clock = std::chrono::steady_clock;

/** How long one blocking socket call may take once poll() said it may proceed (a TLS record
 *  arriving in pieces, a write larger than the room): the deadline is checked between them. */
constexpr int kSliceMs = 250;

void setSocketTimeouts(DcmNativeSocketType socket, int ms) {
    timeval tv{};
    tv.tv_sec = ms / 1000;
    tv.tv_usec = (ms % 1000) * 1000;
    ::setsockopt(socket, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    ::setsockopt(socket, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
}

/** OpenSSL's reason for its last error ("certificate verify failed"), empty when none. */
std::string lastOpenSslReason() {
    const unsigned long e = ERR_peek_last_error();
    if (e == 0) return "";
    const char* reason = ERR_reason_error_string(e);
    return reason ? reason : "";
}

} // namespace

class WatchedConnection;

struct WatchedLayer::Shared {
    std::mutex mutex;
    std::shared_ptr<LinkReport> last;
};

/** One connection: DCMTK's (plain or TLS) inside, each wait bounded (see WatchedLayer). */
class WatchedConnection : public DcmTransportConnection {
public:
    WatchedConnection(DcmNativeSocketType socket, DcmTransportConnection* inner,
                      std::shared_ptr<WatchedLayer::Shared> shared, int timeoutMs, bool tls,
                      bool acceptor, std::shared_ptr<const CancelToken*> cancel)
        : DcmTransportConnection(socket), m_inner(inner), m_shared(std::move(shared)),
          m_report(std::make_shared<LinkReport>()), m_timeout(timeoutMs), m_socket(socket),
          m_cancel(std::move(cancel)) {
        if (acceptor) m_requestDeadline = Clock::now() + m_timeout;
        m_report->made = true;
        m_report->tls = tls;
        setSocketTimeouts(socket, kSliceMs); // after DCMTK's (60 s, set by the constructors)
        std::lock_guard lock(m_shared->mutex);
        m_shared->last = m_report;
    }
    ~WatchedConnection() override { delete m_inner; }

    OFCondition serverSideHandshake() override { return handshake(true); }
    OFCondition clientSideHandshake() override { return handshake(false); }
    OFCondition renegotiate(const char* suite) override { return m_inner->renegotiate(suite); }
    ssize_t read(void* buf, size_t nbyte) override;
    ssize_t write(void* buf, size_t nbyte) override;
    void close() override {
        forget();
        m_inner->close();
    }
    void closeTransportConnection() override {
        forget();
        m_inner->closeTransportConnection();
    }
    unsigned long getPeerCertificateLength() override {
        return m_inner->getPeerCertificateLength();
    }
    unsigned long getPeerCertificate(void* buf, unsigned long len) override {
        return m_inner->getPeerCertificate(buf, len);
    }
    OFBool networkDataAvailable(int timeout) override {
        if (m_dead) return OFTrue; // the read that follows fails at once
        return waitFor(POLLIN, timeout < 0 ? -1 : timeout * 1000) ? OFTrue : OFFalse;
    }
    OFBool isTransparentConnection() override { return m_inner->isTransparentConnection(); }
    using DcmTransportConnection::dumpConnectionParameters;
    OFString& dumpConnectionParameters(OFString& str) override {
        return m_inner->dumpConnectionParameters(str);
    }

private:
    OFCondition handshake(bool server);
    OFCondition boundedHandshake(bool server);
    bool waitFor(short events, int callerMs = -1);
    bool cancelDue();
    void died(int err);
    void received(const void* buf, ssize_t n);

    /** The socket is closed by the inner connection: ours forgets it too (DCMTK's select on
     *  transparent connections reads it). */
    void forget() {
        m_dead = true;
        setSocket(OFstatic_cast(DcmNativeSocketType, -1));
    }

    DcmTransportConnection* m_inner;
    std::shared_ptr<WatchedLayer::Shared> m_shared;
    std::shared_ptr<LinkReport> m_report;
    std::chrono::milliseconds m_timeout;
    DcmNativeSocketType m_socket;
    std::optional<Clock::time_point> m_waitingSince; ///< since the last byte moved
    /** Accepted connections: when the A-ASSOCIATE-RQ must have arrived whole (bytes do not
     *  move it); cleared once it has. */
    std::optional<Clock::time_point> m_requestDeadline;
    bool m_dead = false; ///< silent, lost or closed: every read and write fails at once
    std::shared_ptr<const CancelToken*> m_cancel; ///< the layer's token (null: none)
    std::optional<Clock::time_point> m_cancelSeen; ///< when a wait first saw the cancel
};

OFCondition WatchedConnection::handshake(bool server) {
    // OpenSSL blocks in the socket calls: the whole timeout for them, then slices again.
    setSocketTimeouts(m_socket, int(m_timeout.count()));
    ERR_clear_error();
    const auto start = Clock::now();
    const OFCondition cond = m_requestDeadline ? boundedHandshake(server)
                             : server          ? m_inner->serverSideHandshake()
                                               : m_inner->clientSideHandshake();
    setSocketTimeouts(m_socket, kSliceMs);
    if (cond.good() || !m_report->tls) {
        m_report->handshakeDone = cond.good();
        return cond;
    }
    if (cond == DCMTLS_EC_TLSReadOperationDidNotComplete ||
        cond == DCMTLS_EC_TLSWriteOperationDidNotComplete || Clock::now() - start >= m_timeout) {
        m_report->silent = true;
    } else {
        std::string reason = lastOpenSslReason();
        if (reason.empty()) reason = cond.text(); // DCMTK took it from the queue: its words
        if (reason.rfind("TLS error: ", 0) == 0) reason.erase(0, 11);
        m_report->tlsError = reason;
    }
    m_dead = true;
    return cond;
}

/** An accepted connection's handshake, ended by the association request's deadline however
 *  slowly the peer sends it (OpenSSL's reads each wait the socket's timeout afresh): at the
 *  deadline a watchdog shuts the socket down, and OpenSSL's read fails at once. */
OFCondition WatchedConnection::boundedHandshake(bool server) {
    std::mutex mutex;
    std::condition_variable cv;
    bool done = false;
    std::thread watchdog([&, deadline = *m_requestDeadline] {
        std::unique_lock lock(mutex);
        if (!cv.wait_until(lock, deadline, [&] { return done; })) ::shutdown(m_socket, SHUT_RDWR);
    });
    const OFCondition cond =
        server ? m_inner->serverSideHandshake() : m_inner->clientSideHandshake();
    {
        std::lock_guard lock(mutex);
        done = true;
    }
    cv.notify_one();
    watchdog.join();
    return cond;
}

/** Waits until the socket is ready for `events`, within what is left of the deadline (and
 *  within callerMs when DCMTK asks for less). False when the time is up: at the deadline, the
 *  peer is silent and the connection dead. */
bool WatchedConnection::waitFor(short events, int callerMs) {
    if (m_dead) return false;
    if (m_requestDeadline && Clock::now() >= *m_requestDeadline) { // bytes came, too slowly
        m_report->silent = true;
        m_dead = true;
        return false;
    }
    if (events == POLLIN && m_inner->networkDataAvailable(0)) return true; // TLS: buffered
    const auto now = Clock::now();
    if (!m_waitingSince) m_waitingSince = now;
    auto deadline = *m_waitingSince + m_timeout;
    if (m_requestDeadline) deadline = std::min(deadline, *m_requestDeadline);
    auto until = deadline;
    const bool callers = callerMs >= 0 && now + std::chrono::milliseconds(callerMs) < deadline;
    if (callers) until = now + std::chrono::milliseconds(callerMs);
    for (;;) {
        if (m_dead) return false;
        if (cancelDue()) return false;
        const auto left =
            std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now()).count();
        pollfd p{m_socket, events, 0};
        const int r = ::poll(&p, 1, int(std::max<long long>(0, std::min<long long>(left, 100))));
        if (r > 0 || (r < 0 && errno != EINTR)) return true; // ready, or the call says why not
        if (r == 0 && Clock::now() >= until) break;
    }
    if (!callers) {
        m_report->silent = true;
        m_dead = true;
    }
    return false;
}

/** Whether the user's cancel ends the connection now: it came kCancelGraceMs ago and the peer
 *  has not moved a byte since (a peer that answers is heard, so that a C-CANCEL's exchange can
 *  end the operation in order). Then the connection is dead, the report `cancelled`. */
bool WatchedConnection::cancelDue() {
    const CancelToken* token = *m_cancel;
    if (!token || !token->cancelled()) return false;
    const auto now = Clock::now();
    if (!m_cancelSeen || (m_waitingSince && *m_waitingSince > *m_cancelSeen)) m_cancelSeen = now;
    if (now - *m_cancelSeen < std::chrono::milliseconds(kCancelGraceMs)) return false;
    m_report->cancelled = true;
    m_dead = true;
    return true;
}

void WatchedConnection::died(int err) {
    if (m_report->tls) {
        const std::string reason = lastOpenSslReason();
        if (!reason.empty() && m_report->tlsError.empty()) m_report->tlsError = reason;
    }
    if (!m_dead) m_report->lost = true; // not silent before: the peer went
    m_dead = true;
    errno = err ? err : ECONNRESET;
}

void WatchedConnection::received(const void* buf, ssize_t n) {
    m_waitingSince.reset();
    const auto* b = static_cast<const unsigned char*>(buf);
    for (ssize_t i = 0; i < n && m_report->firstBytes.size() < 10; ++i)
        m_report->firstBytes.push_back(b[i]);
    m_report->received += std::size_t(n);
    // The first PDU (the A-ASSOCIATE-RQ) is whole: 6 bytes of head, then the length they give.
    if (m_requestDeadline && m_report->firstBytes.size() >= 6) {
        const auto& h = m_report->firstBytes;
        const std::size_t length = (std::size_t(h[2]) << 24) | (std::size_t(h[3]) << 16) |
                                   (std::size_t(h[4]) << 8) | std::size_t(h[5]);
        if (m_report->received >= 6 + length) m_requestDeadline.reset();
    }
}

ssize_t WatchedConnection::read(void* buf, size_t nbyte) {
    for (;;) {
        if (!waitFor(POLLIN)) {
            errno = ETIMEDOUT;
            return -1;
        }
        ERR_clear_error();
        errno = 0;
        const ssize_t r = m_inner->read(buf, nbyte);
        if (r > 0) {
            received(buf, r);
            return r;
        }
        const int err = errno;
        if (r < 0 && (err == EINTR || err == EAGAIN || err == EWOULDBLOCK)) continue;
        died(err);
        return r < 0 ? -1 : 0;
    }
}

ssize_t WatchedConnection::write(void* buf, size_t nbyte) {
    auto* p = static_cast<char*>(buf);
    size_t done = 0;
    while (done < nbyte) { // a TLS write is whole or retried with the same arguments
        if (!waitFor(POLLOUT)) {
            errno = ETIMEDOUT;
            return -1;
        }
        ERR_clear_error();
        errno = 0;
        const ssize_t r = m_inner->write(p + done, nbyte - done);
        if (r > 0) {
            done += size_t(r);
            m_waitingSince.reset();
            continue;
        }
        const int err = errno;
        if (r < 0 && (err == EINTR || err == EAGAIN || err == EWOULDBLOCK)) continue;
        died(err);
        return -1;
    }
    return ssize_t(nbyte);
}

WatchedLayer::WatchedLayer(int timeoutSeconds, std::unique_ptr<DcmTLSTransportLayer> tls,
                           bool acceptor)
    : m_shared(std::make_shared<Shared>()), m_tls(std::move(tls)),
      m_timeoutMs(timeoutSeconds * 1000), m_acceptor(acceptor) {}

WatchedLayer::~WatchedLayer() = default;

DcmTransportConnection* WatchedLayer::createConnection(DcmNativeSocketType socket, OFBool) {
    DcmTransportConnection* inner = m_tls ? m_tls->createConnection(socket, OFTrue)
                                          : DcmTransportLayer::createConnection(socket, OFFalse);
    if (!inner) return nullptr;
    return new WatchedConnection(socket, inner, m_shared, m_timeoutMs, m_tls != nullptr, m_acceptor,
                                 m_cancel);
}

void WatchedLayer::setCancel(const CancelToken* cancel) { *m_cancel = cancel; }

LinkReport WatchedLayer::lastReport() const {
    std::lock_guard lock(m_shared->mutex);
    return m_shared->last ? *m_shared->last : LinkReport{};
}

namespace {

/** A file the TLS settings name: readable, else PacsError "the <what> <file> cannot be read:
 *  <reason>". */
void checkReadable(const std::string& file, const std::string& what) {
    if (file.empty()) throw PacsError("the " + what + " is not set");
    errno = 0;
    std::ifstream in(file, std::ios::binary);
    char c;
    if (!in || !in.get(c))
        throw PacsError("the " + what + " " + file +
                        " cannot be read: " + (errno ? std::strerror(errno) : "it is empty"));
}

/** DCMTK's condition for a file it refused, as "<what> <file> is not ... (<OpenSSL's
 *  reason>)". */
[[noreturn]] void refused(const std::string& what, const std::string& file,
                          const std::string& isNot, const OFCondition& cond) {
    const std::string reason = lastOpenSslReason();
    throw PacsError("the " + what + " " + file + " is not " + isNot + " (" +
                    (reason.empty() ? std::string(cond.text()) : reason) + ")");
}

void loadIdentity(DcmTLSTransportLayer& layer, const TlsSettings& tls) {
    checkReadable(tls.certificateFile, "TLS certificate file");
    checkReadable(tls.privateKeyFile, "TLS private key file");
    ERR_clear_error();
    OFCondition cond = layer.setCertificateFile(tls.certificateFile.c_str(), DCF_Filetype_PEM);
    if (cond.bad()) refused("TLS certificate file", tls.certificateFile, "a PEM certificate", cond);
    layer.setPrivateKeyPasswd(""); // an encrypted key fails here instead of asking on a console
    ERR_clear_error();
    cond = layer.setPrivateKeyFile(tls.privateKeyFile.c_str(), DCF_Filetype_PEM);
    const bool mismatch =
        cond.bad() && (std::string(cond.text()).find("mismatch") != std::string::npos ||
                       lastOpenSslReason().find("mismatch") != std::string::npos);
    if (cond.bad() && !mismatch)
        refused("TLS private key file", tls.privateKeyFile, "an unencrypted PEM private key", cond);
    if (mismatch || !layer.checkPrivateKeyMatchesCertificate())
        throw PacsError("the TLS private key file " + tls.privateKeyFile +
                        " does not match the certificate " + tls.certificateFile);
}

} // namespace

std::unique_ptr<WatchedLayer> makeLayer(const LocalAe& local, bool tls, T_ASC_NetworkRole role) {
    const bool listener = role == NET_ACCEPTOR;
    if (!tls) return std::make_unique<WatchedLayer>(local.timeoutSeconds, nullptr, listener);
    const TlsSettings& s = local.tls;
    if (listener && s.certificateFile.empty())
        throw PacsError("the TLS listener needs our certificate and private key (PEM files)");
    if (s.certificateFile.empty() != s.privateKeyFile.empty())
        throw PacsError("TLS: our certificate and its private key go together: set both or "
                        "neither (certificate \"" +
                        s.certificateFile + "\", private key \"" + s.privateKeyFile + "\")");
    if (s.verifyPeer && s.trustedCaFiles.empty())
        throw PacsError(std::string("TLS: checking the ") + (listener ? "peer's" : "PACS's") +
                        " certificate needs a trusted CA certificate file (or turn the check "
                        "off)");
    auto layer = std::make_unique<DcmTLSTransportLayer>(role, nullptr, OFTrue);
    if (!*layer) throw PacsError("TLS: OpenSSL could not be set up");
    if (!s.certificateFile.empty()) loadIdentity(*layer, s);
    for (const std::string& ca : s.trustedCaFiles) {
        checkReadable(ca, "trusted CA certificate file");
        ERR_clear_error();
        const OFCondition cond = layer->addTrustedCertificateFile(ca.c_str(), DCF_Filetype_PEM);
        if (cond.bad()) refused("trusted CA certificate file", ca, "a PEM certificate", cond);
    }
    OFCondition cond = layer->setTLSProfile(TSP_Profile_BCP195_ND); // DCMTK tools' default
    if (cond.good()) cond = layer->activateCipherSuites();
    if (cond.bad()) throw PacsError(std::string("TLS: the cipher suites: ") + cond.text());
    layer->setCertificateVerification(s.verifyPeer ? DCV_requireCertificate
                                                   : DCV_ignoreCertificate);
    return std::make_unique<WatchedLayer>(local.timeoutSeconds, std::move(layer), listener);
}

} // namespace fvr::core::pacs::detail

namespace fvr::core::pacs {

void checkTls(const LocalAe& local) {
    detail::makeLayer(local, true, NET_REQUESTOR);
    if (local.listenTls) detail::makeLayer(local, true, NET_ACCEPTOR);
}

} // namespace fvr::core::pacs
