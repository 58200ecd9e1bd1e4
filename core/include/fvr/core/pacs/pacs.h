#pragma once
/** DICOM networking with a PACS (DIMSE over TCP, DCMTK dcmnet): verification (C-ECHO), query
 *  (C-FIND, Study Root), retrieve (C-GET, or C-MOVE to our own StorageListener) into a
 *  LocalStore, and send (C-STORE). No Qt: fvr-render and the workstation share it. Every call
 *  blocks (run it off the UI thread) and throws PacsError with a message in plain words that
 *  names the peer ("ORTHANC@127.0.0.1:4242: ..."). */
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <fvr/core/render/preprocess.h> // CancelToken

namespace fvr::core::pacs {

enum class RetrieveMethod { Get, Move };

/** A remote PACS (Application Entity). */
struct Node {
    std::string name; ///< the user's label (may be empty)
    std::string calledAe; ///< its AE title (the "called AE" of our associations)
    std::string host;
    int port = 104;
    RetrieveMethod retrieve = RetrieveMethod::Get;
    bool tls = false; ///< DICOM TLS to this node, with LocalAe::tls (else plain TCP)
};

/** DICOM TLS (DCMTK's TLS layer over OpenSSL, the BCP 195 profile: TLS 1.2 or 1.3): the
 *  certificate we show and its private key (PEM files, the key not encrypted), the CA
 *  certificates we trust (PEM), and whether a peer must show a certificate that one of them
 *  signed. A PACS's certificate is checked against the CAs, not against its host name. A client
 *  may go without a certificate (when the PACS does not ask for one); the listener may not. */
struct TlsSettings {
    std::string certificateFile, privateKeyFile;
    std::vector<std::string> trustedCaFiles;
    bool verifyPeer = true; ///< refuse a peer without a certificate signed by a trusted CA
    bool operator==(const TlsSettings&) const = default;
};

// --- The storage listener's trust (StorageListener) ---
/** A peer our storage listener accepts associations from: its calling AE title, and the host
 *  it connects from (a name or an IPv4 address, compared by address; empty = any host). */
struct Peer {
    std::string aeTitle;
    std::string host;
    bool operator==(const Peer&) const = default;
};
// --- end of the listener's trust ---

/** Us: our AE title (the "calling AE"), the port of our StorageListener (C-MOVE destination,
 *  the PACS must know us under aeTitle at this port), and the network timeout: every wait for
 *  the peer (connection, TLS handshake, association, each message, release) ends after
 *  timeoutSeconds without a byte from it, the whole operation then within timeout + 1 s. */
struct LocalAe {
    std::string aeTitle = "FVR";
    int listenPort = 11112;
    int timeoutSeconds = 10;
    // --- The storage listener's trust (StorageListener) ---
    /** The IPv4 address the listener binds: this machine only by default; "0.0.0.0" (or "")
     *  = every interface, to be asked for explicitly. */
    std::string listenAddress = "127.0.0.1";
    /** Peers whose own stores (not asked for by a retrieve) the listener takes, into the
     *  store's Incoming area. A PACS we C-MOVE from is accepted for that move only, whether
     *  or not it is listed here. */
    std::vector<Peer> allowedPeers;
    // --- end of the listener's trust ---
    // DICOM TLS: our certificate and the CAs we trust, for nodes with tls set and for the
    // listener when listenTls is set (a listener speaks TLS only, or plain DICOM only).
    TlsSettings tls;
    bool listenTls = false;
};

/** A network operation failed; the message says why in plain words and names the peer. */
struct PacsError : std::runtime_error {
    using runtime_error::runtime_error;
};

/** "ORTHANC@127.0.0.1:4242": how messages name a node. */
std::string describe(const Node& node);

/** Checks AE titles (1..16 characters, no backslash or control characters, not all spaces),
 *  host (non-empty) and port (1..65535). Throws PacsError naming the field. */
void validate(const Node& node);
void validate(const LocalAe& local);
/** Loads local.tls as a TLS connection would (and as the listener would, when listenTls): files
 *  read and parsed, the key against its certificate, a CA when the peer is checked. Throws
 *  PacsError naming the file and the problem (the settings dialog checks with it). */
void checkTls(const LocalAe& local);

// --- The storage listener's trust (StorageListener) ---
/** "AE" or "AE@host" (the workstation's settings: the dialog's "Accept studies sent by" list
 *  and the saved allowed peers; fvr-render has none: its --retrieve move listener trusts only
 *  the node, while the move runs) as a Peer; throws PacsError naming the text when the AE
 *  title is not valid or the host is empty after '@'. */
Peer parsePeer(const std::string& text);
/** "ORTHANC@10.0.0.5", or "ORTHANC" (any host). */
std::string describe(const Peer& peer);
/** validate(local) and the listener's own fields: listenAddress an IPv4 address (or empty),
 *  every allowed peer's AE title valid. Throws PacsError naming the field. */
void validateListener(const LocalAe& local);
/** Whether `address` ("", "0.0.0.0", "127.0.0.1", ...) binds more than this machine's
 *  loopback interface. */
bool listensBeyondLoopback(const std::string& address);
// --- end of the listener's trust ---

/**
 * C-ECHO. Returns normally when the PACS answers; throws PacsError otherwise. Every operation
 * names its failure the same way, e.g.
 * "ORTHANC@127.0.0.1:4242: connection refused (nothing listens at 127.0.0.1:4242)",
 * "... the association was rejected by the PACS: called AE title not recognised (permanent)",
 * "... the PACS aborted the association" (at association: "is our AE title FVR known to it?"),
 * "... the PACS stopped answering (no reply within 10 s)",
 * "... the connection was lost (the PACS closed it or died)",
 * "... TLS handshake failed: certificate verify failed (...)",
 * "the TLS certificate file /x/our.pem cannot be read: No such file or directory".
 */
void echo(const Node& node, const LocalAe& local);

/** Study-level query keys; empty = any. Name and IDs may hold the wildcards * and ?. Dates are
 *  YYYYMMDD; dateFrom only = from then on, dateTo only = up to then. */
struct StudyQuery {
    std::string patientName, patientId, accessionNumber;
    std::string dateFrom, dateTo; ///< YYYYMMDD or empty
    std::string modality; ///< e.g. "CT" (matched against ModalitiesInStudy)
};

/** The query's StudyDate matching value ("from-to", "from-", "-to", one day, or empty). Throws
 *  PacsError for a date that is not a calendar day YYYYMMDD or a range that ends before it
 *  begins (the one rule of the PACS dialog, fvr-render --query and findStudies). */
std::string studyDateMatch(const StudyQuery& q);

/** A study as the PACS describes it; strings in UTF-8 (SpecificCharacterSet converted).
 *  Person names in DICOM form ("DOE^JOHN"). -1: the PACS did not say. */
struct StudyRecord {
    std::string studyUid, patientName, patientId, patientBirthDate, studyDate, studyTime,
        accessionNumber, description, modalities; ///< modalities: "CT\\MR" as in the tag
    int numberOfSeries = -1, numberOfInstances = -1;
};

/** A text field of StudyRecord under the name that the local store's index and fvr-render
 *  --query's JSON give it: one list for both (studyUid and the counts aside). */
struct StudyTextField {
    const char* name; ///< e.g. "patientName"
    std::string StudyRecord::*member;
};
const std::vector<StudyTextField>& studyTextFields();

struct SeriesRecord {
    std::string seriesUid, modality, description;
    int seriesNumber = -1, numberOfInstances = -1;
};

/** C-FIND at STUDY level (Study Root). Throws PacsError (bad date, network, a failed status). */
std::vector<StudyRecord> findStudies(const Node& node, const LocalAe& local,
                                     const StudyQuery& query);
/** C-FIND at SERIES level within one study, sorted by series number. */
std::vector<SeriesRecord> findSeries(const Node& node, const LocalAe& local,
                                     const std::string& studyUid);

/** An instance as a C-FIND at IMAGE level names it. */
struct InstanceRecord {
    std::string seriesUid, sopInstanceUid;
};
/** C-FIND at IMAGE level: the instances of a study (of one series when seriesUid is given),
 *  sorted by series and SOP Instance UID. */
std::vector<InstanceRecord> findInstances(const Node& node, const LocalAe& local,
                                          const std::string& studyUid,
                                          const std::string& seriesUid = {});

/** Progress of a retrieve: instances received (stored in the store), expected (from the PACS's
 *  responses; -1 until it says), failed (sub-operations the PACS reports as failed). */
struct RetrieveProgress {
    int received = 0, expected = -1, failed = 0;
};
using RetrieveProgressFn = std::function<void(const RetrieveProgress&)>;

class LocalStore;

/**
 * Retrieves a study (seriesUid empty) or one series into `store` with the node's method:
 * C-GET on one association, or C-MOVE to our AE title, received by the StorageListener running
 * on local.listenPort in this process (one is started for the retrieve when none runs). Returns
 * the folder of the study (or of the series), complete: every sub-operation succeeded. Throws
 * PacsError (network, refused, some instances failed: the entry stays partial, a second
 * retrieve completes it) or core::Cancelled when `cancel` fires (looked at on each response and
 * each instance received; C-CANCEL sent, the association aborted, the entry stays partial).
 * `progress` is called on the calling thread after each of them. Files are written atomically;
 * nothing half-written is listed as complete. Only what was asked for is taken: an instance of
 * another study (or series) is refused (C-GET: status 0x0124, Not Authorized; C-MOVE: by the
 * listener), never stored, and a C-GET that brought any fails saying how many.
 */
std::filesystem::path retrieve(const Node& node, const LocalAe& local, const std::string& studyUid,
                               const std::string& seriesUid, LocalStore& store,
                               const RetrieveProgressFn& progress = {},
                               const CancelToken* cancel = nullptr);

/** What retrieveMissing() did. */
struct RetrieveSummary {
    std::filesystem::path folder; ///< the study's (or the series') folder, complete
    bool fromStore = false; ///< it was complete in the store: no network used
    int fetched = 0; ///< instances received (what the PACS sent)
    int present = 0; ///< instances the PACS lists that the store had already
};

/**
 * A retrieve that takes only what the store lacks: a study (series) the store lists as complete
 * is returned as it is, without the network, unless `refresh`; otherwise the PACS's instances
 * (C-FIND at IMAGE level) that have no file in the store are retrieved at IMAGE level, series by
 * series (at most 500 SOP Instance UIDs a request), and the study (series) is complete when
 * they all arrived. With nothing of it in the store (or `refresh`), it is retrieve(). Throws as
 * retrieve() does.
 */
RetrieveSummary retrieveMissing(const Node& node, const LocalAe& local, const std::string& studyUid,
                                const std::string& seriesUid, LocalStore& store,
                                const RetrieveProgressFn& progress = {},
                                const CancelToken* cancel = nullptr, bool refresh = false);

/** C-STORE of DICOM files on one association (their SOP classes and transfer syntaxes
 *  proposed). Throws PacsError naming the file the PACS refused, or a file that is not DICOM. */
void sendFiles(const Node& node, const LocalAe& local,
               const std::vector<std::filesystem::path>& files);

} // namespace fvr::core::pacs
