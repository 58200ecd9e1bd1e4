#pragma once
// The transport layer of every association we make or accept (private to core): plain TCP or
// DICOM TLS, with every wait for the peer bounded by one deadline, and a report of what the
// connection saw, from which failures are named ("stopped answering", "connection lost", the
// TLS error, the rejection's reason).
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/render/preprocess.h> // CancelToken

#include <dcmtk/config/osconfig.h> // first DCMTK include
#include <dcmtk/dcmnet/assoc.h>
#include <dcmtk/dcmnet/dcmlayer.h>

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

class DcmTLSTransportLayer;

namespace fvr::core::pacs::detail {

/** What one connection saw, kept after DCMTK has deleted it. */
struct LinkReport {
    bool made = false; ///< a connection was opened (the TCP connect succeeded)
    bool tls = false;
    bool handshakeDone = false; ///< TLS: the handshake succeeded (plain: no handshake)
    bool silent = false; ///< we waited `timeout` seconds and the peer sent nothing
    bool lost = false; ///< the peer closed the connection or it broke while we used it
    std::string tlsError; ///< the handshake's failure, or a TLS error after it (OpenSSL's words)
    std::vector<unsigned char> firstBytes; ///< the first 10 bytes the peer sent after the handshake
    std::size_t received = 0; ///< bytes from the peer after the handshake
    /** The user cancelled while we waited for the peer, and nothing moved for kCancelGraceMs
     *  after: the connection was ended (not the peer's failure). */
    bool cancelled = false;
};

/** After a cancel, how long a wait for the peer goes on: a peer that answers (the next message,
 *  the C-CANCEL's response) is heard; a silent one is left at once after. */
constexpr int kCancelGraceMs = 300;

/**
 * DCMTK's transport layer (DcmTransportLayer), plain or TLS, whose connections bound the waits
 * for the peer: a wait for a byte to read or for room to write ends `timeoutSeconds` after it
 * began, counting every wait since the last byte that moved (one deadline, however DCMTK splits
 * its waits into polls, reads and the release that follows a failure). The connection is then
 * dead: every later read or write fails at once, so the whole operation ends within the
 * timeout. DCMTK's own timeouts stay a little longer, as a backstop.
 * A connection we accept (the listener) has one more deadline, which no byte moves: its whole
 * A-ASSOCIATE-RQ must arrive within the timeout of the connection's start, so that a peer that
 * reaches the port cannot hold the listener (one association at a time) by sending the request
 * a byte at a time.
 */
class WatchedLayer : public DcmTransportLayer {
public:
    /** `tls`: the TLS layer to wrap (its connections), null for plain TCP; `acceptor`: the
     *  listener's (the association request's own deadline). */
    WatchedLayer(int timeoutSeconds, std::unique_ptr<DcmTLSTransportLayer> tls,
                 bool acceptor = false);
    ~WatchedLayer() override;
    WatchedLayer(const WatchedLayer&) = delete;
    WatchedLayer& operator=(const WatchedLayer&) = delete;

    DcmTransportConnection* createConnection(DcmNativeSocketType socket,
                                             OFBool useSecureLayer) override;
    bool tls() const { return m_tls != nullptr; }
    /** A token whose cancel ends every wait of this layer's connections (opened before or
     *  after) within kCancelGraceMs + one poll (100 ms), the report then `cancelled`. */
    void setCancel(const CancelToken* cancel);
    /** What the most recent connection saw (a default report when none was opened). */
    LinkReport lastReport() const;

    struct Shared;

private:
    std::shared_ptr<Shared> m_shared;
    std::unique_ptr<DcmTLSTransportLayer> m_tls;
    int m_timeoutMs;
    std::shared_ptr<const CancelToken*> m_cancel = std::make_shared<const CancelToken*>(nullptr);
    bool m_acceptor;
};

/** The layer of our associations with `node` (TLS when node.tls) or of the listener (role
 *  NET_ACCEPTOR, TLS when local.listenTls). Throws PacsError naming the file and the problem
 *  for unusable TLS settings: a file that cannot be read, that is not PEM, a key that does not
 *  match its certificate, verification asked for without a trusted CA. */
std::unique_ptr<WatchedLayer> makeLayer(const LocalAe& local, bool tls, T_ASC_NetworkRole role);

} // namespace fvr::core::pacs::detail
