// Associations with a PACS (DCMTK's DcmSCU) and their failures in words; C-ECHO.
#include "pacs_internal.h"

#include "../dicom/dicom_internal.h"

#include <fvr/core/errors.h>
#include <fvr/core/pacs/dicom_url.h>

#include <dcmtk/dcmnet/diutil.h>

#include <algorithm>
#include <cstdlib>
#include <mutex>

namespace fvr::core::pacs {
namespace {

void validateAe(const std::string& ae, const std::string& what) {
    if (ae.empty() || ae.size() > 16)
        throw PacsError(what + " \"" + ae + "\" must have 1 to 16 characters");
    if (std::all_of(ae.begin(), ae.end(), [](char c) { return c == ' '; }))
        throw PacsError(what + " must not be all spaces");
    for (char c : ae)
        if (c == '\\' || static_cast<unsigned char>(c) < 0x20 ||
            static_cast<unsigned char>(c) > 0x7e)
            throw PacsError(what + " \"" + ae +
                            "\" may hold only printable ASCII characters other than '\\'");
}

void validatePort(int port, const std::string& what) {
    if (port < 1 || port > 65535)
        throw PacsError(what + " " + std::to_string(port) + " is not in 1..65535");
}

std::string reasonText(T_ASC_RejectParametersReason reason) {
    switch (reason) {
    case ASC_REASON_SU_NOREASON:
    case ASC_REASON_SP_ACSE_NOREASON: return "no reason given";
    case ASC_REASON_SU_APPCONTEXTNAMENOTSUPPORTED: return "application context name not supported";
    case ASC_REASON_SU_CALLINGAETITLENOTRECOGNIZED: return "calling AE title not recognised";
    case ASC_REASON_SU_CALLEDAETITLENOTRECOGNIZED: return "called AE title not recognised";
    case ASC_REASON_SP_ACSE_PROTOCOLVERSIONNOTSUPPORTED: return "protocol version not supported";
    case ASC_REASON_SP_PRES_TEMPORARYCONGESTION: return "temporary congestion";
    case ASC_REASON_SP_PRES_LOCALLIMITEXCEEDED:
        return "local limit exceeded (too many associations)";
    }
    return "reason code " + std::to_string(static_cast<int>(reason));
}

/** Debian's DCMTK leaves Nagle's algorithm on unless TCP_NODELAY=1 is in the environment (dul.cc
 *  reads it at every association): with it on, each C-STORE waits for a delayed ACK, 90 ms an
 *  instance on loopback instead of 4. Set once, before our first association, unless the user
 *  set it. */
void disableNagle() {
    static std::once_flag once;
    std::call_once(once, [] { ::setenv("TCP_NODELAY", "1", 0); });
}

bool textHas(const OFCondition& cond, const char* what) {
    return std::string(cond.text()).find(what) != std::string::npos;
}

} // namespace

namespace detail {

void prepareNetwork() {
    dicom_detail::initDcmtk(); // DCMTK's console log off, codecs registered
    disableNagle();
}

std::string rejectionText(const std::vector<unsigned char>& pdu) {
    // A-ASSOCIATE-RJ: type 3, reserved, length (4 bytes), reserved, result, source, reason.
    if (pdu.size() < 10 || pdu[0] != 0x03) return "no reason given";
    const auto reason = static_cast<T_ASC_RejectParametersReason>((pdu[8] << 8) | pdu[9]);
    return reasonText(reason) + (pdu[7] == ASC_RESULT_REJECTEDTRANSIENT
                                     ? " (transient: try again later)"
                                     : " (permanent)");
}

namespace {

/** A TLS failure in words, with what to look at. */
std::string tlsText(const LinkReport& link, const Node& node, const LocalAe& local) {
    const std::string& e = link.tlsError;
    const auto has = [&](const char* what) { return e.find(what) != std::string::npos; };
    std::string hint;
    if (has("certificate verify failed"))
        hint = " (the PACS's certificate is not signed by a CA we trust)";
    else if (has("unknown ca") || has("bad certificate") || has("certificate unknown") ||
             has("certificate required") || has("access denied"))
        hint = local.tls.certificateFile.empty() ? " (the PACS wants our certificate: we have none)"
                                                 : " (the PACS does not accept our certificate " +
                                                       local.tls.certificateFile + ")";
    else if (!link.handshakeDone &&
             (has("wrong version number") || has("unexpected eof") || has("packet length") ||
              has("record layer") || has("I/O error") || has("http request")))
        hint = " (is " + node.host + ":" + std::to_string(node.port) +
               " a DICOM TLS port? a plain DICOM port answers like this)";
    const bool closed = has("I/O error") || has("unexpected eof");
    return (link.handshakeDone ? "TLS with " : "TLS handshake with ") + describe(node) +
           " failed: " + (closed ? "the PACS closed the connection (" + e + ")" : e) + hint;
}

/** A connection that broke (read 0 bytes or an error) in words: at association, before the PACS
 *  said anything, the likely reasons; later, lost. */
std::string lostText(const LinkReport& link, const Node& node, const LocalAe& local,
                     bool atAssociation) {
    if (link.tls && link.handshakeDone && link.received == 0)
        return "the PACS closed the TLS connection after the handshake without a word" +
               (local.tls.certificateFile.empty()
                    ? std::string(" (it may want our certificate: we have none)")
                    : " (it may not accept our certificate " + local.tls.certificateFile + ")");
    if (atAssociation && link.received == 0)
        return "the PACS closed the connection without answering the association request" +
               (link.tls ? std::string()
                         : " (if " + node.host + ":" + std::to_string(node.port) +
                               " is a DICOM TLS port, turn TLS on for this node)");
    return "the connection was lost (the PACS closed it or died)";
}

} // namespace

std::string failureText(const OFCondition& cond, const Node& node, const LocalAe& local,
                        const LinkReport& link, bool atAssociation) {
    const std::string peer = describe(node) + ": ";
    const std::string address = node.host + ":" + std::to_string(node.port);
    const std::string silent = "the PACS stopped answering (no reply within " +
                               std::to_string(local.timeoutSeconds) + " s)";
    if (link.silent) return peer + silent;
    if (!link.tlsError.empty()) return tlsText(link, node, local);
    if (cond == DUL_ASSOCIATIONREJECTED)
        return peer + "the association was rejected by the PACS: " + rejectionText(link.firstBytes);
    if (textHas(cond, "Connection refused"))
        return peer + "connection refused (nothing listens at " + address + ")";
    if (textHas(cond, "Unknown host") || textHas(cond, "unknown host"))
        return peer + "unknown host \"" + node.host + "\"";
    if (!link.made && (textHas(cond, "imeout") || textHas(cond, "timed out")))
        return peer + "no connection to " + address + " within " +
               std::to_string(local.timeoutSeconds) + " s";
    if (!link.tls && !link.firstBytes.empty() &&
        (link.firstBytes[0] == 0x15 || link.firstBytes[0] == 0x16))
        return peer + "the PACS answered in TLS: " + address +
               " is a DICOM TLS port (turn TLS on for this node)";
    if (link.lost) return peer + lostText(link, node, local, atAssociation);
    if (cond == DUL_PEERABORTEDASSOCIATION)
        return peer + "the PACS aborted the association" +
               (atAssociation ? " (is our AE title " + local.aeTitle + " known to it?)" : "");
    if (cond == DIMSE_NODATAAVAILABLE || cond == DUL_READTIMEOUT || textHas(cond, "imeout") ||
        textHas(cond, "timed out"))
        return peer + silent;
    if (cond == DUL_PEERREQUESTEDRELEASE)
        return peer + "the PACS ended the association before the operation was done";
    if (cond == DUL_NETWORKCLOSED || cond == DIMSE_READPDVFAILED)
        return peer + "the connection was lost (the PACS closed it or died)";
    return peer + cond.text();
}

OFList<OFString> uncompressedSyntaxes() {
    OFList<OFString> ts;
    ts.push_back(UID_LittleEndianExplicitTransferSyntax);
    ts.push_back(UID_LittleEndianImplicitTransferSyntax);
    return ts;
}

Scu::Scu(const Node& node, const LocalAe& local) : m_node(node), m_local(local) {
    prepareNetwork();
    validate(node);
    validate(local);
    m_layer = makeLayer(local, node.tls, NET_REQUESTOR);
    setAETitle(local.aeTitle.c_str());
    setPeerAETitle(node.calledAe.c_str());
    setPeerHostName(node.host.c_str());
    setPeerPort(static_cast<Uint16>(node.port));
    // The layer ends every wait at the timeout; DCMTK's own timers a second later are a backstop
    // (they restart with each message: alone they let an operation run to 2 or 3 timeouts).
    setACSETimeout(static_cast<Uint32>(local.timeoutSeconds + 1));
    setDIMSETimeout(static_cast<Uint32>(local.timeoutSeconds + 1));
    setConnectionTimeout(local.timeoutSeconds);
    setDIMSEBlockingMode(DIMSE_NONBLOCKING);
    setMaxReceivePDULength(ASC_MAXIMUMPDUSIZE);
}

Scu::~Scu() {
    close(true);
    freeNetwork(); // DCMTK's connections go while our layer is still there
}

void Scu::connect(const std::string& what) {
    OFCondition cond = initNetwork();
    if (cond.bad())
        throw PacsError(describe(m_node) + ": cannot set up the network: " + cond.text());
    cond = useSecureConnection(m_layer.get()); // ours, plain or TLS (the name is DCMTK's)
    if (cond.bad())
        throw PacsError(describe(m_node) + ": cannot set up the transport: " + cond.text());
    cond = negotiateAssociation();
    if (cond.bad() && cancelledByUser()) throw Cancelled();
    if (cond == NET_EC_NoAcceptablePresentationContexts)
        throw PacsError(describe(m_node) + ": the PACS accepts none of what we proposed (" + what +
                        ")");
    if (cond.bad())
        throw PacsError(failureText(cond, m_node, m_local, m_layer->lastReport(), true));
}

T_ASC_PresentationContextID Scu::context(const char* abstractSyntax, const std::string& what) {
    const T_ASC_PresentationContextID id = findAnyPresentationContextID(abstractSyntax, "");
    if (id == 0) throw PacsError(describe(m_node) + ": the PACS does not offer " + what);
    return id;
}

void Scu::setCancel(const CancelToken* cancel) { m_layer->setCancel(cancel); }

bool Scu::cancelledByUser() const { return m_layer->lastReport().cancelled; }

void Scu::check(const OFCondition& cond, const std::string& what) const {
    if (cond.bad() && cancelledByUser()) throw Cancelled();
    if (cond.bad())
        throw PacsError(failureText(cond, m_node, m_local, m_layer->lastReport(), false) +
                        " (during " + what + ")");
}

std::string Scu::linkFailure() const {
    const LinkReport link = m_layer->lastReport();
    if (!link.silent && !link.lost && link.tlsError.empty()) return "";
    return failureText(EC_Normal, m_node, m_local, link, false);
}

void Scu::close(bool abort) {
    if (isConnected())
        closeAssociation(abort ? DCMSCU_ABORT_ASSOCIATION : DCMSCU_RELEASE_ASSOCIATION);
}

} // namespace detail

std::string describe(const Node& node) {
    return node.calledAe + "@" + node.host + ":" + std::to_string(node.port);
}

void validate(const Node& node) {
    validateAe(node.calledAe, "the called AE title");
    if (node.host.empty()) throw PacsError("the PACS host is empty");
    validatePort(node.port, "the PACS port");
}

void validate(const LocalAe& local) {
    validateAe(local.aeTitle, "our AE title");
    validatePort(local.listenPort, "our listener port");
    if (local.timeoutSeconds < 1) throw PacsError("the network timeout must be at least 1 s");
}

void echo(const Node& node, const LocalAe& local) {
    detail::Scu scu(node, local);
    scu.addPresentationContext(UID_VerificationSOPClass, detail::uncompressedSyntaxes());
    scu.connect("Verification");
    const OFCondition cond = scu.sendECHORequest(0);
    scu.check(cond, "C-ECHO");
    scu.close(false);
}

} // namespace fvr::core::pacs
