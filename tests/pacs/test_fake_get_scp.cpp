// A PACS that misbehaves in a C-GET, which Orthanc never does: a small DCMTK C-GET SCP of our
// own that answers a C-GET of one study with C-STORE sub-operations over the same association,
// sending the study's instances and also one instance of another study. What the retrieve did
// not ask for must not land in the store, and the retrieve must say so.
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmnet/scp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

#include "orthanc_server.h"
#include "pacs_environment.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace fvr::core::pacs;

namespace {

constexpr const char* kFakeAe = "FAKEPACS";
constexpr const char* kOtherStudy = "1.2.826.0.1.3680043.8.498.27027027";

/** A C-GET SCP that sends `datasets` (CT images) as C-STORE sub-operations for any C-GET, and
 *  keeps the statuses our SCU answered with. */
class FakeGetScp : public DcmSCP {
public:
    std::vector<std::unique_ptr<DcmDataset>> datasets;
    std::vector<Uint16> storeStatuses; ///< the SCU's answer to each sub-operation
    std::atomic<bool> stop{false};

protected:
    /** Remembers the presentation context the SCU proposed for CT Image Storage (in the SCP
     *  role for itself, as C-GET needs). */
    void notifyAssociationRequest(const T_ASC_Parameters& params,
                                  DcmSCPActionType& action) override {
        auto* p = const_cast<T_ASC_Parameters*>(&params);
        for (int i = 0; i < ASC_countPresentationContexts(p); ++i) {
            T_ASC_PresentationContext pc;
            ASC_getPresentationContext(p, i, &pc);
            if (std::strcmp(pc.abstractSyntax, UID_CTImageStorage) == 0)
                m_storePc = pc.presentationContextID;
        }
        DcmSCP::notifyAssociationRequest(params, action);
    }

    OFCondition handleIncomingCommand(T_DIMSE_Message* msg,
                                      const DcmPresentationContextInfo& info) override {
        if (msg->CommandField == DIMSE_C_FIND_RQ) return findWithoutFinalResponse(*msg, info);
        if (msg->CommandField != DIMSE_C_GET_RQ) return DcmSCP::handleIncomingCommand(msg, info);
        const T_DIMSE_C_GetRQ req = msg->msg.CGetRQ;
        T_ASC_PresentationContextID id = info.presentationContextID;
        DcmDataset* keys = nullptr;
        OFCondition cond = receiveDIMSEDataset(&id, &keys);
        delete keys;
        if (cond.bad()) return cond;
        Uint16 done = 0, failed = 0;
        for (auto& ds : datasets) {
            cond = sendStore(*ds);
            if (cond.bad()) return cond;
            (storeStatuses.back() == STATUS_Success ? done : failed)++;
        }
        T_DIMSE_Message rsp{};
        rsp.CommandField = DIMSE_C_GET_RSP;
        T_DIMSE_C_GetRSP& r = rsp.msg.CGetRSP;
        r.MessageIDBeingRespondedTo = req.MessageID;
        r.DimseStatus =
            failed ? STATUS_GET_Warning_SubOperationsCompleteOneOrMoreFailures : STATUS_Success;
        OFStandard::strlcpy(r.AffectedSOPClassUID, req.AffectedSOPClassUID,
                            sizeof r.AffectedSOPClassUID);
        r.DataSetType = DIMSE_DATASET_NULL;
        r.NumberOfCompletedSubOperations = done;
        r.NumberOfFailedSubOperations = failed;
        r.NumberOfWarningSubOperations = 0;
        r.opts = O_GET_AFFECTEDSOPCLASSUID | O_GET_NUMBEROFCOMPLETEDSUBOPERATIONS |
                 O_GET_NUMBEROFFAILEDSUBOPERATIONS | O_GET_NUMBEROFWARNINGSUBOPERATIONS;
        return sendDIMSEMessage(info.presentationContextID, &rsp, nullptr);
    }

    OFBool stopAfterConnectionTimeout() override { return stop.load(); }
    OFBool stopAfterCurrentAssociation() override { return stop.load(); }

public:
    /** What a C-FIND gets after its one pending match: silence (false) or an A-ABORT. */
    bool abortAfterMatch = false;

private:
    /** A C-FIND answered with one pending match and then never finished: the PACS goes silent
     *  until the test ends, or aborts the association. */
    OFCondition findWithoutFinalResponse(const T_DIMSE_Message& msg,
                                         const DcmPresentationContextInfo& info) {
        const T_DIMSE_C_FindRQ req = msg.msg.CFindRQ;
        T_ASC_PresentationContextID id = info.presentationContextID;
        DcmDataset* keys = nullptr;
        OFCondition cond = receiveDIMSEDataset(&id, &keys);
        delete keys;
        if (cond.bad()) return cond;
        DcmDataset match;
        match.putAndInsertString(DCM_QueryRetrieveLevel, "STUDY");
        match.putAndInsertString(DCM_StudyInstanceUID, kOtherStudy);
        T_DIMSE_Message rsp{};
        rsp.CommandField = DIMSE_C_FIND_RSP;
        T_DIMSE_C_FindRSP& r = rsp.msg.CFindRSP;
        r.MessageIDBeingRespondedTo = req.MessageID;
        r.DimseStatus = STATUS_Pending;
        OFStandard::strlcpy(r.AffectedSOPClassUID, req.AffectedSOPClassUID,
                            sizeof r.AffectedSOPClassUID);
        r.DataSetType = DIMSE_DATASET_PRESENT;
        r.opts = O_FIND_AFFECTEDSOPCLASSUID;
        cond = sendDIMSEMessage(info.presentationContextID, &rsp, &match);
        if (cond.bad()) return cond;
        if (abortAfterMatch) return DIMSE_ILLEGALASSOCIATION; // DcmSCP then aborts it
        while (!stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
        return DUL_PEERABORTEDASSOCIATION;
    }

    /** One C-STORE sub-operation; its response's status goes to storeStatuses. */
    OFCondition sendStore(DcmDataset& ds) {
        OFString sopClass, sop;
        ds.findAndGetOFString(DCM_SOPClassUID, sopClass);
        ds.findAndGetOFString(DCM_SOPInstanceUID, sop);
        T_DIMSE_Message msg{};
        msg.CommandField = DIMSE_C_STORE_RQ;
        T_DIMSE_C_StoreRQ& rq = msg.msg.CStoreRQ;
        rq.MessageID = ++m_messageId;
        OFStandard::strlcpy(rq.AffectedSOPClassUID, sopClass.c_str(),
                            sizeof rq.AffectedSOPClassUID);
        OFStandard::strlcpy(rq.AffectedSOPInstanceUID, sop.c_str(),
                            sizeof rq.AffectedSOPInstanceUID);
        rq.Priority = DIMSE_PRIORITY_MEDIUM;
        rq.DataSetType = DIMSE_DATASET_PRESENT;
        OFCondition cond = sendDIMSEMessage(m_storePc, &msg, &ds);
        if (cond.bad()) return cond;
        T_ASC_PresentationContextID id = m_storePc;
        T_DIMSE_Message answer{};
        DcmDataset* detail = nullptr;
        cond = receiveDIMSECommand(&id, &answer, &detail, nullptr, 20);
        delete detail;
        if (cond.bad()) return cond;
        if (answer.CommandField != DIMSE_C_STORE_RSP) return DIMSE_BADCOMMANDTYPE;
        storeStatuses.push_back(answer.msg.CStoreRSP.DimseStatus);
        return EC_Normal;
    }

    T_ASC_PresentationContextID m_storePc = 0;
    DIC_US m_messageId = 0;
};

/** The fake PACS on a free loopback port, on its own thread while the object lives. */
class FakePacs {
public:
    FakePacs() : m_port(fvr::test::freeLoopbackPort()) {
        m_scp.setPort(static_cast<Uint16>(m_port));
        m_scp.setAETitle(kFakeAe);
        m_scp.setConnectionBlockingMode(DUL_NOBLOCK);
        m_scp.setConnectionTimeout(1);
        m_scp.setACSETimeout(20);
        m_scp.setDIMSETimeout(20);
        OFList<OFString> syntaxes;
        syntaxes.push_back(UID_LittleEndianExplicitTransferSyntax);
        syntaxes.push_back(UID_LittleEndianImplicitTransferSyntax);
        m_scp.addPresentationContext(UID_VerificationSOPClass, syntaxes);
        m_scp.addPresentationContext(UID_GETStudyRootQueryRetrieveInformationModel, syntaxes);
        m_scp.addPresentationContext(UID_FINDStudyRootQueryRetrieveInformationModel, syntaxes);
        // C-GET: the SCU takes the storage SCP role, so we take the SCU role of storage.
        m_scp.addPresentationContext(UID_CTImageStorage, syntaxes, ASC_SC_ROLE_SCP);
    }
    ~FakePacs() {
        m_scp.stop = true;
        if (m_thread.joinable()) m_thread.join();
    }
    FakeGetScp& scp() { return m_scp; }
    /** Listens (the port is open when it returns), then serves on its thread. */
    void start() {
        ASSERT_TRUE(m_scp.openListenPort().good()) << "cannot listen on port " << m_port;
        m_thread = std::thread([this] { m_scp.acceptAssociations(); });
    }
    Node node() const {
        Node n;
        n.calledAe = kFakeAe;
        n.host = "127.0.0.1";
        n.port = m_port;
        n.retrieve = RetrieveMethod::Get;
        return n;
    }

private:
    int m_port;
    FakeGetScp m_scp;
    std::thread m_thread;
};

std::unique_ptr<DcmDataset> loadDataset(const fs::path& file) {
    DcmFileFormat ff;
    EXPECT_TRUE(ff.loadFile(file.c_str()).good()) << file;
    return std::unique_ptr<DcmDataset>(ff.getAndRemoveDataset());
}

/** A fresh store folder of this program's own (these tests do not need Orthanc). */
fs::path freshRoot(const std::string& name) {
    const fs::path root = fvr::test::tmpDir() / ("fake-get-" + std::to_string(::getpid())) / name;
    fs::remove_all(root);
    return root;
}

std::string tagOf(DcmDataset& ds, const DcmTagKey& key) {
    OFString v;
    ds.findAndGetOFString(key, v);
    return v.c_str();
}

} // namespace

// The PACS answers a C-GET of study S with S's instances and one of another study: that one is
// refused (0x0124, Not Authorized, as the listener refuses what no retrieve asked for) and not
// stored; the retrieve fails saying how many instances of another study came, and S stays
// partial.
TEST(PacsFakeGetScp, InstancesOfAnotherStudyAreRefusedNotStored) {
    FVR_REQUIRE_DATA(fvr::test::kSlicer);
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer))
        files.push_back(e.path());
    std::sort(files.begin(), files.end());
    files.resize(4); // three of the study, the fourth made another study's
    FakePacs pacs;
    for (const fs::path& f : files) pacs.scp().datasets.push_back(loadDataset(f));
    DcmDataset& foreign = *pacs.scp().datasets.back();
    const std::string study = tagOf(*pacs.scp().datasets.front(), DCM_StudyInstanceUID);
    const std::string foreignSop = tagOf(foreign, DCM_SOPInstanceUID);
    ASSERT_FALSE(study.empty());
    ASSERT_TRUE(foreign.putAndInsertString(DCM_StudyInstanceUID, kOtherStudy).good());
    pacs.start();

    LocalStore store(freshRoot("study"));
    LocalAe local;
    local.aeTitle = fvr::test::kOurAe;
    local.timeoutSeconds = 20;
    std::string message;
    try {
        retrieve(pacs.node(), local, study, "", store);
    } catch (const PacsError& e) {
        message = e.what();
    }
    std::printf("[ message  ] %s\n", message.c_str());
    EXPECT_NE(message.find("1 instance(s) of another study"), std::string::npos) << message;
    EXPECT_NE(message.find("refused (not stored); the 3 instance(s) of study " + study +
                           " it sent are kept as partial"),
              std::string::npos)
        << message;
    EXPECT_NE(message.find(kFakeAe), std::string::npos) << message;
    // The SCU answered the foreign one 0x0124 and the study's three success.
    ASSERT_EQ(pacs.scp().storeStatuses.size(), 4u);
    EXPECT_EQ(pacs.scp().storeStatuses[3], STATUS_STORE_Refused_NotAuthorized);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(pacs.scp().storeStatuses[i], STATUS_Success) << i;
    // Nothing of the other study anywhere in the store; the study has its three, partial.
    EXPECT_FALSE(store.find(kOtherStudy));
    EXPECT_FALSE(store.find(kOtherStudy, Area::Incoming));
    EXPECT_FALSE(fs::exists(store.studyFolder(kOtherStudy)));
    for (const auto& e : fs::recursive_directory_iterator(store.root()))
        EXPECT_EQ(e.path().filename().string().find(foreignSop), std::string::npos) << e.path();
    const auto entry = store.find(study);
    ASSERT_TRUE(entry);
    EXPECT_EQ(entry->instances, 3);
    EXPECT_FALSE(entry->complete);
}

// A C-GET of one series: an instance of another series of the same study is refused too.
TEST(PacsFakeGetScp, InstancesOfAnotherSeriesAreRefusedNotStored) {
    FVR_REQUIRE_DATA(fvr::test::kSlicer);
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer))
        files.push_back(e.path());
    std::sort(files.begin(), files.end());
    files.resize(3);
    FakePacs pacs;
    for (const fs::path& f : files) pacs.scp().datasets.push_back(loadDataset(f));
    const std::string study = tagOf(*pacs.scp().datasets.front(), DCM_StudyInstanceUID);
    const std::string series = tagOf(*pacs.scp().datasets.front(), DCM_SeriesInstanceUID);
    ASSERT_TRUE(pacs.scp()
                    .datasets.back()
                    ->putAndInsertString(DCM_SeriesInstanceUID, "1.2.826.0.1.3680043.8.498.2727")
                    .good());
    pacs.start();

    LocalStore store(freshRoot("series"));
    std::string message;
    try {
        LocalAe local;
        local.aeTitle = fvr::test::kOurAe;
        retrieve(pacs.node(), local, study, series, store);
    } catch (const PacsError& e) {
        message = e.what();
    }
    std::printf("[ message  ] %s\n", message.c_str());
    EXPECT_NE(message.find("1 instance(s) of another series"), std::string::npos) << message;
    ASSERT_EQ(pacs.scp().storeStatuses.size(), 3u);
    EXPECT_EQ(pacs.scp().storeStatuses[2], STATUS_STORE_Refused_NotAuthorized);
    EXPECT_FALSE(fs::exists(store.seriesFolder(study, "1.2.826.0.1.3680043.8.498.2727")));
    const auto entry = store.find(study);
    ASSERT_TRUE(entry);
    EXPECT_EQ(entry->instances, 2);
    ASSERT_EQ(entry->series.size(), 1u);
    EXPECT_FALSE(entry->series[0].complete);
}

// The PACS sends nothing but another study's instance: refused, and no entry is left for the
// study asked for (nothing of it came).
TEST(PacsFakeGetScp, OnlyAnotherStudysInstanceLeavesNothing) {
    FVR_REQUIRE_DATA(fvr::test::kSlicer);
    const fs::path file = *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer);
    FakePacs pacs;
    pacs.scp().datasets.push_back(loadDataset(file));
    const std::string study = tagOf(*pacs.scp().datasets.front(), DCM_StudyInstanceUID);
    ASSERT_TRUE(
        pacs.scp().datasets.front()->putAndInsertString(DCM_StudyInstanceUID, kOtherStudy).good());
    pacs.start();

    LocalStore store(freshRoot("only-foreign"));
    LocalAe local;
    local.aeTitle = fvr::test::kOurAe;
    std::string message;
    try {
        retrieve(pacs.node(), local, study, "", store);
    } catch (const PacsError& e) {
        message = e.what();
    }
    EXPECT_NE(message.find("1 instance(s) of another study, which were refused (not stored); it "
                           "sent nothing of study " +
                           study),
              std::string::npos)
        << message;
    ASSERT_EQ(pacs.scp().storeStatuses.size(), 1u);
    EXPECT_EQ(pacs.scp().storeStatuses[0], STATUS_STORE_Refused_NotAuthorized);
    EXPECT_TRUE(store.studies().empty());
}

// A C-FIND that the PACS never finishes (one pending match, then silence, or then an abort) is
// a failure, not an answer: the matches sent so far are not all there are.
TEST(PacsFakeGetScp, AFindWithoutItsFinalResponseFails) {
    for (const bool abort : {false, true}) {
        SCOPED_TRACE(abort ? "then aborted" : "then silent");
        FakePacs pacs;
        pacs.scp().abortAfterMatch = abort;
        pacs.start();
        LocalAe local;
        local.aeTitle = fvr::test::kOurAe;
        local.timeoutSeconds = 2;
        std::string message;
        std::size_t found = 0;
        try {
            found = findStudies(pacs.node(), local, {}).size();
        } catch (const PacsError& e) {
            message = e.what();
        }
        std::printf("[ message  ] %s\n", message.c_str());
        EXPECT_EQ(found, 0u) << "a partial answer was taken for the whole";
        EXPECT_NE(message.find(kFakeAe), std::string::npos) << message;
        if (!abort)
            EXPECT_NE(message.find("stopped answering (no reply within 2 s)"), std::string::npos)
                << message;
        pacs.scp().stop = true;
    }
}
