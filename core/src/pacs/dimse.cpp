// Associations with a PACS (DCMTK's DcmSCU) and their failures in words; C-ECHO.
#include "pacs_internal.h"

#include "../dicom/dicom_internal.h"

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

/** DcmSCU's negotiateAssociation() keeps the A-ASSOCIATE-RJ parameters to itself: ask again
 *  at the ASC level (a Verification context only) to read them. */
std::string probeRejection(const Node& node, const LocalAe& local) {
    T_ASC_Network* net = nullptr;
    if (ASC_initializeNetwork(NET_REQUESTOR, 0, local.timeoutSeconds, &net).bad())
        return "rejected";
    T_ASC_Parameters* params = nullptr;
    ASC_createAssociationParameters(&params, ASC_DEFAULTMAXPDU);
    ASC_setAPTitles(params, local.aeTitle.c_str(), node.calledAe.c_str(), nullptr);
    const std::string peer = node.host + ":" + std::to_string(node.port);
    ASC_setPresentationAddresses(params, OFStandard::getHostName().c_str(), peer.c_str());
    const char* syntaxes[] = {UID_LittleEndianImplicitTransferSyntax};
    ASC_addPresentationContext(params, 1, UID_VerificationSOPClass, syntaxes, 1);
    T_ASC_Association* assoc = nullptr;
    const OFCondition cond = ASC_requestAssociation(net, params, &assoc);
    std::string text = "rejected";
    if (cond == DUL_ASSOCIATIONREJECTED) {
        T_ASC_RejectParameters rej;
        ASC_getRejectParameters(params, &rej);
        text = detail::rejectionText(rej);
    } else if (cond.good()) {
        ASC_releaseAssociation(assoc);
    }
    if (assoc)
        ASC_destroyAssociation(&assoc); // owns params
    else
        ASC_destroyAssociationParameters(&params);
    ASC_dropNetwork(&net);
    return text;
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

std::string rejectionText(const T_ASC_RejectParameters& rej) {
    const char* result = rej.result == ASC_RESULT_REJECTEDTRANSIENT ? "rejected (transient)"
                                                                    : "rejected (permanent)";
    const char* source = rej.source == ASC_SOURCE_SERVICEUSER ? "the service user (the PACS)"
                                                              : "the service provider";
    return std::string(result) + " by " + source + ": " + reasonText(rej.reason);
}

std::string failureText(const OFCondition& cond, const Node& node, const LocalAe& local) {
    const std::string peer = describe(node) + ": ";
    const std::string address = node.host + ":" + std::to_string(node.port);
    if (cond == DUL_ASSOCIATIONREJECTED) return peer + "association " + probeRejection(node, local);
    if (textHas(cond, "Connection refused"))
        return peer + "connection refused (nothing listens at " + address + ")";
    if (textHas(cond, "Unknown host") || textHas(cond, "unknown host"))
        return peer + "unknown host \"" + node.host + "\"";
    if (cond == DUL_PEERABORTEDASSOCIATION)
        return peer + "the PACS aborted the association (is our AE title " + local.aeTitle +
               " known to it?)";
    if (cond == DIMSE_NODATAAVAILABLE || cond == DUL_READTIMEOUT || textHas(cond, "imeout") ||
        textHas(cond, "timed out"))
        return peer + "no answer within " + std::to_string(local.timeoutSeconds) + " s";
    if (cond == DUL_PEERREQUESTEDRELEASE || cond == DUL_NETWORKCLOSED ||
        cond == DIMSE_READPDVFAILED)
        return peer + "the PACS closed the connection (" + cond.text() + ")";
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
    setAETitle(local.aeTitle.c_str());
    setPeerAETitle(node.calledAe.c_str());
    setPeerHostName(node.host.c_str());
    setPeerPort(static_cast<Uint16>(node.port));
    setACSETimeout(static_cast<Uint32>(local.timeoutSeconds));
    setDIMSETimeout(static_cast<Uint32>(local.timeoutSeconds));
    setConnectionTimeout(local.timeoutSeconds);
    setDIMSEBlockingMode(DIMSE_NONBLOCKING);
    setMaxReceivePDULength(ASC_MAXIMUMPDUSIZE);
}

Scu::~Scu() { close(true); }

void Scu::connect(const std::string& what) {
    OFCondition cond = initNetwork();
    if (cond.bad())
        throw PacsError(describe(m_node) + ": cannot set up the network: " + cond.text());
    cond = negotiateAssociation();
    if (cond == NET_EC_NoAcceptablePresentationContexts)
        throw PacsError(describe(m_node) + ": the PACS accepts none of what we proposed (" + what +
                        ")");
    if (cond.bad()) throw PacsError(failureText(cond, m_node, m_local));
}

T_ASC_PresentationContextID Scu::context(const char* abstractSyntax, const std::string& what) {
    const T_ASC_PresentationContextID id = findAnyPresentationContextID(abstractSyntax, "");
    if (id == 0) throw PacsError(describe(m_node) + ": the PACS does not offer " + what);
    return id;
}

void Scu::check(const OFCondition& cond, const std::string& what) const {
    if (cond.bad()) throw PacsError(failureText(cond, m_node, m_local) + " (during " + what + ")");
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
