#pragma once
// Shared by the DIMSE sources (private to core): the configured DcmSCU, failures in words, and
// records and store writes from received datasets.
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>

#include "transport.h"

#include <dcmtk/config/osconfig.h> // first DCMTK include
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmnet/scu.h>

#include <memory>
#include <string>
#include <vector>

namespace fvr::core::pacs::detail {

/** Before any association: DCMTK's log off (dicom_detail::initDcmtk), Nagle's algorithm off
 *  (TCP_NODELAY=1 unless set). */
void prepareNetwork();

/** DcmSCU set up for a node: our AE title, our transport layer (plain or TLS, every wait for
 *  the peer bounded: see WatchedLayer), non-blocking DIMSE. Throws PacsError for unusable TLS
 *  settings. */
class Scu : public DcmSCU {
public:
    Scu(const Node& node, const LocalAe& local);
    ~Scu() override;
    /** initNetwork() and negotiateAssociation(); throws PacsError in words (the rejection with
     *  its reason, refused, aborted, timeout; `what` names the service for "accepts none"). */
    void connect(const std::string& what);
    /** The accepted presentation context for `abstractSyntax` (any transfer syntax), or throws
     *  PacsError "the PACS does not offer <what>". */
    T_ASC_PresentationContextID context(const char* abstractSyntax, const std::string& what);
    /** Throws PacsError for a failed DIMSE exchange (in words); no-op when good. */
    void check(const OFCondition& cond, const std::string& what) const;
    /** Releases the association (or aborts it when `abort`); never throws. */
    void close(bool abort);
    /** `cancel` ends every wait for the peer once it fires (WatchedLayer::setCancel); connect()
     *  and check() then throw core::Cancelled. */
    void setCancel(const CancelToken* cancel);
    /** Whether the user's cancel ended the connection (see setCancel). */
    bool cancelledByUser() const;
    /** The connection's failure in words ("ORTHANC@h:p: the PACS stopped answering ..."): it went
     *  silent, was lost, or TLS failed; "" when it saw none of these. */
    std::string linkFailure() const;

    const Node& node() const { return m_node; }
    const LocalAe& local() const { return m_local; }

private:
    Node m_node;
    LocalAe m_local;
    std::unique_ptr<WatchedLayer> m_layer; // DcmSCU points to it: closed in ~Scu, before it goes
};

/** The failure of a network operation in words, prefixed with the node ("ORTHANC@h:p: ..."),
 *  from what the connection saw first (silent, TLS, lost) and DCMTK's condition. The AE title
 *  is suggested only for an abort at association (`atAssociation`), never after a crash. */
std::string failureText(const OFCondition& cond, const Node& node, const LocalAe& local,
                        const LinkReport& link, bool atAssociation);
/** An A-ASSOCIATE-RJ PDU's reason and result in words: "called AE title not recognised
 *  (permanent)". */
std::string rejectionText(const std::vector<unsigned char>& pdu);

/** Converts the item's strings to UTF-8 per its SpecificCharacterSet
 *  (dicom_detail::convertTextToUtf8: U+FFFD for what cannot be converted); returns that problem
 *  in words, "" when there was none. */
std::string toUtf8(DcmItem& item);

/** Records from a dataset (C-FIND response or received instance), strings in UTF-8. */
StudyRecord studyRecordFrom(DcmItem& item);
SeriesRecord seriesRecordFrom(DcmItem& item);

/** A received dataset as the store took it: its UIDs and what the store did. */
struct StoredDataset {
    std::string studyUid, seriesUid, sopInstanceUid;
    StoreOutcome outcome;
};

/** Writes a received dataset into the store's `area` (LocalStore::storeInstance: DICOM file
 *  with meta header in the dataset's transfer syntax, never replacing a stored instance).
 *  Throws PacsError for missing UIDs or ones isValidUid() refuses (naming which and why), and
 *  WriteError. A quarantined instance is no error: see the outcome. */
StoredDataset storeDataset(LocalStore& store, DcmDataset& dataset, Area area = Area::Studies);

/** One C-GET or C-MOVE (the node's method) with `keys`, into `store`: what came is checked
 *  against studyUid (and seriesUid when given), `what` names it in messages. `bookkeeping`:
 *  beginRetrieve/finishRetrieve around it (else the caller's). Returns the instances received;
 *  throws as retrieve() does. */
int retrieveWith(const Node& node, const LocalAe& local, const std::string& studyUid,
                 const std::string& seriesUid, DcmDataset& keys, const std::string& what,
                 LocalStore& store, const RetrieveProgressFn& progress, const CancelToken* cancel,
                 bool bookkeeping);

/** The C-GET/C-STORE transfer syntaxes we take: explicit and implicit VR little endian. */
OFList<OFString> uncompressedSyntaxes();

} // namespace fvr::core::pacs::detail
