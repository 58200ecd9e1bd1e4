// A retrieve of what the local store lacks: nothing for a complete study, the missing instances
// (C-FIND and C-GET/C-MOVE at IMAGE level) for a partial one.
#include "pacs_internal.h"

#include <fvr/core/errors.h>

#include <map>

namespace fs = std::filesystem;

namespace fvr::core::pacs {
namespace {

/** SOP Instance UIDs a single IMAGE-level request names at most (a UI element's values stay far
 *  below its 64 KiB length). */
constexpr std::size_t kUidsPerRequest = 500;

/** Whether the store lists the study (or the series) as complete. */
bool completeInStore(const LocalStore& store, const std::string& studyUid,
                     const std::string& seriesUid) {
    const auto entry = store.find(studyUid);
    if (!entry) return false;
    if (seriesUid.empty()) return entry->complete;
    for (const auto& s : entry->series)
        if (s.seriesUid == seriesUid) return s.complete || entry->complete;
    return false;
}

/** Retrieves `sops` of one series at IMAGE level, in batches; `done` counts what arrived before
 *  (progress goes on from it, out of `total`). */
void retrieveInstances(const Node& node, const LocalAe& local, const std::string& studyUid,
                       const std::string& seriesUid, const std::vector<std::string>& sops,
                       LocalStore& store, const RetrieveProgressFn& progress,
                       const CancelToken* cancel, int total, int& done) {
    for (std::size_t from = 0; from < sops.size(); from += kUidsPerRequest) {
        std::string list;
        for (std::size_t i = from; i < std::min(sops.size(), from + kUidsPerRequest); ++i)
            list += (list.empty() ? "" : "\\") + sops[i];
        DcmDataset keys;
        keys.putAndInsertString(DCM_QueryRetrieveLevel, "IMAGE");
        keys.putAndInsertString(DCM_StudyInstanceUID, studyUid.c_str());
        keys.putAndInsertString(DCM_SeriesInstanceUID, seriesUid.c_str());
        keys.putAndInsertString(DCM_SOPInstanceUID, list.c_str());
        const int before = done;
        const RetrieveProgressFn onward = [&](const RetrieveProgress& p) {
            if (progress) progress({before + p.received, total, p.failed});
        };
        done += detail::retrieveWith(node, local, studyUid, seriesUid, keys,
                                     "the missing instances of series " + seriesUid, store, onward,
                                     cancel, false);
    }
}

} // namespace

RetrieveSummary retrieveMissing(const Node& node, const LocalAe& local, const std::string& studyUid,
                                const std::string& seriesUid, LocalStore& store,
                                const RetrieveProgressFn& progress, const CancelToken* cancel,
                                bool refresh) {
    RetrieveSummary out;
    out.folder =
        seriesUid.empty() ? store.studyFolder(studyUid) : store.seriesFolder(studyUid, seriesUid);
    if (!refresh && completeInStore(store, studyUid, seriesUid)) {
        out.fromStore = true;
        return out;
    }
    if (refresh || !store.find(studyUid)) { // nothing to keep: the ordinary retrieve
        const int before = store.instancesStored();
        retrieve(node, local, studyUid, seriesUid, store, progress, cancel);
        out.fetched = store.instancesStored() - before;
        return out;
    }
    // What the PACS has that the store lacks, by series.
    std::map<std::string, std::vector<std::string>> missing;
    int total = 0;
    for (const InstanceRecord& r : findInstances(node, local, studyUid, seriesUid)) {
        const fs::path file =
            store.seriesFolder(studyUid, r.seriesUid) / (r.sopInstanceUid + ".dcm");
        std::error_code ec;
        if (fs::exists(file, ec))
            ++out.present;
        else {
            missing[r.seriesUid].push_back(r.sopInstanceUid);
            ++total;
        }
    }
    if (out.present == 0 && total == 0)
        throw PacsError(describe(node) + ": the PACS has no instances of " +
                        (seriesUid.empty() ? "study " + studyUid : "series " + seriesUid));
    store.beginRetrieve(StudyRecord{studyUid}, seriesUid);
    try {
        for (const auto& [series, sops] : missing)
            retrieveInstances(node, local, studyUid, series, sops, store, progress, cancel, total,
                              out.fetched);
    } catch (...) {
        store.finishRetrieve(studyUid, seriesUid, false);
        throw;
    }
    store.finishRetrieve(studyUid, seriesUid, true);
    return out;
}

} // namespace fvr::core::pacs
