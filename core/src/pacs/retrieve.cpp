// C-GET and C-MOVE into the local store, with progress and cancel (C-CANCEL).
#include "pacs_internal.h"

#include <fvr/core/errors.h>
#include <fvr/core/pacs/storage_listener.h>

#include <dcmtk/dcmnet/diutil.h>

#include <map>
#include <memory>
#include <mutex>
#include <optional>

namespace fs = std::filesystem;

namespace fvr::core::pacs {
namespace {

/** The SCU of one retrieve: stores what C-GET brings, follows the responses' counts, sends
 *  C-CANCEL when the token fires and then ends the session. */
class RetrieveScu : public detail::Scu {
public:
    RetrieveScu(const Node& node, const LocalAe& local, LocalStore& store,
                const RetrieveProgressFn& progressFn, const CancelToken* cancel)
        : Scu(node, local), m_store(store), m_progressFn(progressFn), m_cancel(cancel) {
        setCancel(cancel); // a silent PACS is left within a second of the cancel
    }

    OFCondition handleSTORERequest(const T_ASC_PresentationContextID, DcmDataset* incoming,
                                   OFBool& continueSession, Uint16& status) override {
        std::unique_ptr<DcmDataset> owned(incoming);
        if (cancelRequested(continueSession)) {
            status = STATUS_STORE_Refused_OutOfResources;
            return EC_Normal;
        }
        if (!asked(*owned)) {
            // Not what this C-GET asked for: refused as the listener refuses what no retrieve
            // asked for (0x0124, Not Authorized), never stored, counted for the message.
            status = STATUS_STORE_Refused_NotAuthorized;
            report(std::nullopt);
            return EC_Normal;
        }
        try {
            const auto stored = detail::storeDataset(m_store, *owned);
            if (stored.outcome.result == StoreResult::Quarantined) ++quarantined;
            status = STATUS_Success;
            ++m_gotten;
        } catch (const std::exception& e) {
            m_storeError = e.what();
            status = STATUS_STORE_Refused_OutOfResources;
            continueSession = OFFalse;
        }
        report(std::nullopt);
        return EC_Normal;
    }

    OFCondition handleCGETResponse(const T_ASC_PresentationContextID presID,
                                   RetrieveResponse* response, OFBool& cont) override {
        const OFCondition cond = DcmSCU::handleCGETResponse(presID, response, cont);
        follow(*response, cont);
        return cond;
    }

    OFCondition handleMOVEResponse(const T_ASC_PresentationContextID presID,
                                   RetrieveResponse* response, OFBool& cont) override {
        const OFCondition cond = DcmSCU::handleMOVEResponse(presID, response, cont);
        follow(*response, cont);
        return cond;
    }

    T_ASC_PresentationContextID pc = 0;
    /** What the C-GET asks for: instances of other studies (series) are refused. */
    std::string studyUid, seriesUid;
    int otherStudy = 0, otherSeries = 0; ///< instances C-GET brought that it did not ask for
    /** C-MOVE: the listener's count of what it took for this move (C-GET counts its own). */
    const StorageListener::Expectation* expectation = nullptr;
    RetrieveProgress progress;
    std::optional<Uint16> finalStatus;
    std::string m_storeError;
    int quarantined = 0; ///< instances whose bytes differed from the stored ones
    bool cancelSent = false;

private:
    /** Whether the instance is of the requested study (and series, when one was asked for);
     *  counts it in otherStudy / otherSeries when not. */
    bool asked(DcmDataset& dataset) {
        OFString study, series;
        dataset.findAndGetOFString(DCM_StudyInstanceUID, study);
        dataset.findAndGetOFString(DCM_SeriesInstanceUID, series);
        if (study.c_str() != studyUid) {
            ++otherStudy;
            return false;
        }
        if (!seriesUid.empty() && series.c_str() != seriesUid) {
            ++otherSeries;
            return false;
        }
        return true;
    }

    bool cancelRequested(OFBool& cont) {
        if (!m_cancel || !m_cancel->cancelled()) return false;
        if (!cancelSent) {
            sendCANCELRequest(pc);
            cancelSent = true;
        }
        cont = OFFalse;
        return true;
    }

    void follow(const RetrieveResponse& r, OFBool& cont) {
        if (!DICOM_PENDING_STATUS(r.m_status)) finalStatus = r.m_status;
        const int total = r.m_numberOfRemainingSubops + r.m_numberOfCompletedSubops +
                          r.m_numberOfFailedSubops + r.m_numberOfWarningSubops;
        report(total > 0 ? std::optional<int>(total) : std::nullopt);
        progress.failed = r.m_numberOfFailedSubops;
        if (DICOM_PENDING_STATUS(r.m_status)) cancelRequested(cont);
    }

    void report(std::optional<int> expected) {
        if (expected) progress.expected = *expected;
        progress.received = expectation ? expectation->received() : m_gotten;
        if (m_progressFn) m_progressFn(progress);
    }

    LocalStore& m_store;
    RetrieveProgressFn m_progressFn;
    const CancelToken* m_cancel;
    int m_gotten = 0; // instances C-GET brought and the store took
};

void addGetContexts(RetrieveScu& scu) {
    scu.addPresentationContext(UID_GETStudyRootQueryRetrieveInformationModel,
                               detail::uncompressedSyntaxes());
    // Storage sub-operations on the same association: we take the SCP role (as getscu does).
    for (int i = 0; i < numberOfDcmLongSCUStorageSOPClassUIDs; ++i)
        scu.addPresentationContext(dcmLongSCUStorageSOPClassUIDs[i], detail::uncompressedSyntaxes(),
                                   ASC_SC_ROLE_SCP);
}

// --- The listener a C-MOVE sends to ---
/** The listeners started for retrieves, by port, with the number of retrieves using each:
 *  shared by the retrieves that run at once, stopped when the last of them ends. */
struct SharedListener {
    std::unique_ptr<StorageListener> listener;
    int users = 0;
};
std::mutex g_moveListenersMutex;
std::map<int, SharedListener> g_moveListeners;

/** The listener of one C-MOVE: the one running on our port (the workstation's, or one that
 *  another retrieve started), else one started for it. Either trusts the node for this move
 *  only (StorageListener::expect): one started here allows no other peer than what
 *  local.allowedPeers lists. */
class MoveListener {
public:
    MoveListener(const LocalAe& local, LocalStore& store) : m_port(local.listenPort) {
        std::lock_guard lock(g_moveListenersMutex);
        if (auto it = g_moveListeners.find(m_port); it != g_moveListeners.end()) {
            m_listener = it->second.listener.get();
            ++it->second.users;
            m_shared = true;
        } else if (StorageListener* running = StorageListener::runningOn(m_port)) {
            m_listener = running; // the program's own: it outlives the retrieve
        } else {
            auto listener = std::make_unique<StorageListener>(local, store);
            listener->start();
            m_listener = listener.get();
            g_moveListeners[m_port] = {std::move(listener), 1};
            m_shared = true;
        }
        if (&m_listener->store() != &store) {
            release();
            throw PacsError("the storage listener on port " + std::to_string(m_port) +
                            " writes into " + m_listener->store().root().string() + ", not into " +
                            store.root().string());
        }
    }
    ~MoveListener() { release(); }
    MoveListener(const MoveListener&) = delete;
    MoveListener& operator=(const MoveListener&) = delete;
    StorageListener& operator*() const { return *m_listener; }

private:
    void release() {
        if (!m_shared) return;
        m_shared = false;
        std::lock_guard lock(g_moveListenersMutex);
        auto it = g_moveListeners.find(m_port);
        if (it != g_moveListeners.end() && --it->second.users == 0)
            g_moveListeners.erase(it); // stops it
    }

    int m_port;
    StorageListener* m_listener = nullptr;
    bool m_shared = false;
};
// --- end of the listener a C-MOVE sends to ---

/** Runs the C-GET or C-MOVE; the SCU's state says how it ended. */
void runRetrieve(RetrieveScu& scu, const Node& node, const LocalAe& local, DcmDataset& keys) {
    const bool move = node.retrieve == RetrieveMethod::Move;
    const std::string what = move ? "Study Root C-MOVE" : "Study Root C-GET";
    if (move)
        scu.addPresentationContext(UID_MOVEStudyRootQueryRetrieveInformationModel,
                                   detail::uncompressedSyntaxes());
    else
        addGetContexts(scu);
    scu.connect(what);
    scu.pc = scu.context(move ? UID_MOVEStudyRootQueryRetrieveInformationModel
                              : UID_GETStudyRootQueryRetrieveInformationModel,
                         what);
    const OFCondition cond =
        move ? scu.sendMOVERequest(scu.pc, local.aeTitle.c_str(), &keys, nullptr)
             : scu.sendCGETRequest(scu.pc, &keys, nullptr);
    if (scu.cancelledByUser()) scu.cancelSent = true; // the wait for the PACS ended by it
    if (scu.cancelSent || !scu.m_storeError.empty()) {
        scu.close(true);
        return;
    }
    scu.check(cond, move ? "C-MOVE" : "C-GET");
    scu.close(false);
}

[[noreturn]] void failed(const RetrieveScu& scu, const Node& node, const std::string& what,
                         bool move) {
    if (!scu.m_storeError.empty())
        throw PacsError("retrieve from " + describe(node) + " stopped: " + scu.m_storeError);
    const std::string problem = scu.expectation ? scu.expectation->lastProblem() : "";
    const char* op = move ? "C-MOVE" : "C-GET";
    const std::string partial = "; what arrived is kept as partial: retrieve again to complete it";
    // No final status: the PACS went silent or away (a status that never came is not one).
    if (const std::string link = scu.linkFailure(); !link.empty())
        throw PacsError(link + " (during " + op + " of " + what + ")" + partial);
    if (!scu.finalStatus)
        throw PacsError(describe(node) + ": " + op + " of " + what +
                        " ended without the PACS's final response" + partial);
    const Uint16 status = *scu.finalStatus;
    std::string text = describe(node) + ": " + op + " of " + what;
    if (scu.progress.failed > 0)
        text += ": " + std::to_string(scu.progress.failed) + " of " +
                std::to_string(scu.progress.expected) + " instances failed" +
                (problem.empty() ? "" : " (the last: " + problem + ")");
    else
        text += " ended with status " +
                std::string(move ? DU_cmoveStatusString(status) : DU_cgetStatusString(status));
    if (move && status == STATUS_MOVE_Failed_MoveDestinationUnknown)
        text += " (the PACS does not know our AE title as a destination)";
    throw PacsError(text + partial);
}

/** The C-GET brought instances it did not ask for (refused, not stored): says how many. What
 *  it asked for stays partial; an entry begun for it that got nothing goes. */
[[noreturn]] void unasked(const RetrieveScu& scu, LocalStore& store, const Node& node,
                          const std::string& studyUid, const std::string& what) {
    std::string text = describe(node) + ": C-GET of " + what + ": the PACS sent ";
    if (scu.otherStudy > 0)
        text += std::to_string(scu.otherStudy) + " instance(s) of another study";
    if (scu.otherStudy > 0 && scu.otherSeries > 0) text += " and ";
    if (scu.otherSeries > 0)
        text += std::to_string(scu.otherSeries) + " instance(s) of another series";
    text += ", which were refused (not stored)";
    if (scu.progress.received > 0) {
        text += "; the " + std::to_string(scu.progress.received) + " instance(s) of " + what +
                " it sent are kept as partial";
    } else {
        if (const auto entry = store.find(studyUid); entry && entry->instances == 0)
            store.remove(studyUid);
        text += "; it sent nothing of " + what;
    }
    throw PacsError(text);
}

/** Nothing came: an unknown UID (Orthanc then fails the C-GET) or an empty study. The empty
 *  entry begun for it goes. */
[[noreturn]] void nothingArrived(const RetrieveScu& scu, LocalStore& store, const Node& node,
                                 const std::string& studyUid, const std::string& what, bool move) {
    if (const auto entry = store.find(studyUid); entry && entry->instances == 0)
        store.remove(studyUid);
    if (const std::string link = scu.linkFailure(); !link.empty())
        throw PacsError(link + " (during " + (move ? "C-MOVE" : "C-GET") + " of " + what + ")");
    std::string text = describe(node) + ": the PACS has no instances of " + what;
    if (scu.finalStatus && *scu.finalStatus != STATUS_Success)
        text += " (" +
                std::string(move ? DU_cmoveStatusString(*scu.finalStatus)
                                 : DU_cgetStatusString(*scu.finalStatus)) +
                ")";
    throw PacsError(text);
}

} // namespace

namespace detail {

int retrieveWith(const Node& node, const LocalAe& local, const std::string& studyUid,
                 const std::string& seriesUid, DcmDataset& keys, const std::string& what,
                 LocalStore& store, const RetrieveProgressFn& progress, const CancelToken* cancel,
                 bool bookkeeping) {
    const bool move = node.retrieve == RetrieveMethod::Move;
    RetrieveScu scu(node, local, store, progress, cancel);
    scu.studyUid = studyUid;
    scu.seriesUid = seriesUid;
    // C-MOVE: the listener takes the node's instances of this study (series) into the study
    // until the move ends (the expectation's end), and nothing else into it.
    std::optional<MoveListener> listener;
    StorageListener::Expectation expectation;
    if (move) {
        listener.emplace(local, store);
        expectation = (**listener).expect(node, studyUid, seriesUid);
        scu.expectation = &expectation;
    }
    if (bookkeeping) store.beginRetrieve(StudyRecord{studyUid}, seriesUid);
    try {
        runRetrieve(scu, node, local, keys);
    } catch (...) {
        if (bookkeeping) store.finishRetrieve(studyUid, seriesUid, false);
        throw;
    }
    const bool unaskedCame = scu.otherStudy + scu.otherSeries > 0;
    const bool ok = !scu.cancelSent && scu.m_storeError.empty() && scu.quarantined == 0 &&
                    !unaskedCame && scu.finalStatus == STATUS_Success && scu.progress.failed == 0;
    if (bookkeeping) store.finishRetrieve(studyUid, seriesUid, ok && scu.progress.received > 0);
    if (scu.cancelSent) throw Cancelled();
    if (unaskedCame && scu.m_storeError.empty()) unasked(scu, store, node, studyUid, what);
    if (scu.progress.received == 0 && scu.m_storeError.empty())
        nothingArrived(scu, store, node, studyUid, what, move);
    if (scu.quarantined > 0)
        throw PacsError("retrieve of " + what + " from " + describe(node) + ": " +
                        std::to_string(scu.quarantined) +
                        " instance(s) differed from the stored copies, which are kept; the "
                        "received ones are in " +
                        store.quarantineFolder().string() + "; the study stays partial");
    if (!ok) failed(scu, node, what, move);
    return scu.progress.received;
}

} // namespace detail

fs::path retrieve(const Node& node, const LocalAe& local, const std::string& studyUid,
                  const std::string& seriesUid, LocalStore& store,
                  const RetrieveProgressFn& progress, const CancelToken* cancel) {
    const std::string what = seriesUid.empty() ? "study " + studyUid : "series " + seriesUid;
    const fs::path folder =
        seriesUid.empty() ? store.studyFolder(studyUid) : store.seriesFolder(studyUid, seriesUid);
    DcmDataset keys;
    keys.putAndInsertString(DCM_QueryRetrieveLevel, seriesUid.empty() ? "STUDY" : "SERIES");
    keys.putAndInsertString(DCM_StudyInstanceUID, studyUid.c_str());
    if (!seriesUid.empty()) keys.putAndInsertString(DCM_SeriesInstanceUID, seriesUid.c_str());
    detail::retrieveWith(node, local, studyUid, seriesUid, keys, what, store, progress, cancel,
                         true);
    return folder;
}

} // namespace fvr::core::pacs
