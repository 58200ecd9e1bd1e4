#pragma once
/** The local study store: what was retrieved from a PACS or received by the storage listener,
 *  so that a study opens again without the network. Two areas under the root:
 *  - Studies: `<root>/<study>/<series>/<sop>.dcm`, what a retrieve asked for (and what the
 *    listener takes as asked for);
 *  - Incoming: `<root>/incoming/<study>/<series>/<sop>.dcm`, what a peer sent unasked; it never
 *    mixes into a study of the Studies area, even under the same UIDs.
 *  Every folder and file name taken from a peer is a UID checked by isValidUid() (digits and
 *  dots), so it can never be one of the store's own names, which all contain a letter or begin
 *  with a dot: `index.json` (nlohmann-json: the studies of both areas with their series,
 *  complete or partial), `.index.lock`, the temporary files of writes in progress
 *  (`.<name>.<pid>-<id>.<n>.part`, io/atomic_file.h), and the folders `incoming` and `quarantine`.
 *  A stored instance is never overwritten: the same bytes again change nothing, other bytes under
 *  the same SOP Instance UID go to `<root>/quarantine/` and the store says so (StoreOutcome). */
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <fvr/core/pacs/pacs.h>

namespace fvr::core::pacs {

/** $XDG_DATA_HOME/fvr-workstation/studies, or ~/.local/share/fvr-workstation/studies. */
std::filesystem::path defaultLocalStoreRoot();

/** A DICOM UID (PS3.5 9.1): 1 to 64 characters, digits and '.', no empty component (no leading
 *  or trailing dot, no ".."). Leading zeros in a component are accepted (archives send them). */
bool isValidUid(std::string_view uid);
/** Why `uid` is not a DICOM UID in words ("it has 65 characters, at most 64"), or "" when it is
 *  one. */
std::string uidProblem(std::string_view uid);

/** Where an instance goes: asked for (a retrieve, or the listener's known peers) or unasked. */
enum class Area { Studies, Incoming };

/** What storeInstance() did with an instance. */
enum class StoreResult {
    Stored, ///< written under its name
    Identical, ///< the same instance was there already (the same transfer syntax and dataset;
               ///< the meta header may differ): nothing written
    Quarantined ///< another dataset was there: the stored file is untouched, this went aside
};
struct StoreOutcome {
    StoreResult result = StoreResult::Stored;
    /** The file that holds the bytes given: the stored file, or the quarantine file. */
    std::filesystem::path path;
    /** Quarantined: in words, naming the SOP instance, its study and the quarantine file. */
    std::string message;
};

/**
 * Thread-safe within a process (the listener's thread and a retrieve may write at once), and
 * between processes and objects on the same root: the index is changed under an exclusive lock
 * on `<root>/.index.lock`, rewritten atomically after every change and read again by studies(),
 * so another process sees complete entries only; instance files are written under unique
 * temporary names and placed without replacing.
 */
class LocalStore {
public:
    explicit LocalStore(std::filesystem::path root = defaultLocalStoreRoot());
    LocalStore(const LocalStore&) = delete;
    LocalStore& operator=(const LocalStore&) = delete;

    struct SeriesEntry {
        std::string seriesUid, modality, description;
        std::filesystem::path folder;
        bool complete = false; ///< a retrieve of this series (or of its study) finished
        int instances = 0; ///< files in the folder
    };
    struct Entry {
        StudyRecord study;
        std::filesystem::path folder;
        bool complete = false; ///< a retrieve of the whole study finished
        int instances = 0; ///< files in the study's folders
        std::vector<SeriesEntry> series;
        Area area = Area::Studies;
        /** The name of the PACS node it was retrieved from (setSource()), "" when unknown (the
         *  listener's, or stored before the index recorded it). */
        std::string source;
    };

    const std::filesystem::path& root() const { return m_root; }
    /** Every study in the index, of both areas (Entry::area), most recently changed first.
     *  Throws PacsError when the index exists but cannot be read (naming the file). */
    std::vector<Entry> studies() const;
    std::optional<Entry> find(const std::string& studyUid, Area area = Area::Studies) const;
    /** Where a study's / series' files go (whether or not they exist). Throw PacsError for a
     *  UID that isValidUid() refuses, naming it and the rule. */
    std::filesystem::path studyFolder(const std::string& studyUid, Area area = Area::Studies) const;
    std::filesystem::path seriesFolder(const std::string& studyUid, const std::string& seriesUid,
                                       Area area = Area::Studies) const;
    /** `<root>/quarantine`: received instances whose bytes differed from the stored ones. */
    std::filesystem::path quarantineFolder() const;
    /** The files in quarantineFolder(), sorted by name (the oldest first). */
    std::vector<std::filesystem::path> quarantined() const;

    /** Writes one instance (`bytes`: a DICOM file with meta header) as
     *  <area>/<study>/<series>/<sopInstanceUid>.dcm, and lists its study and series as partial
     *  unless already complete. `study` fills the index's description fields the first time.
     *  A file already under that name is never replaced: Identical when it holds the same
     *  bytes, or the same dataset in the same transfer syntax under another meta header (group
     *  0002, e.g. written by another DCMTK version); else the bytes go to quarantine
     *  (Quarantined, with a message; nothing thrown). The same instance in another transfer
     *  syntax is quarantined too. The quarantine takes at most 3 files per SOP instance and
     *  1 GiB in all (FVR_QUARANTINE_MAX_PER_INSTANCE, FVR_QUARANTINE_MAX_BYTES change them);
     *  beyond, the instance is refused: WriteError saying the quarantine is full, naming the
     *  limit. The first write into a study folder (per object) removes the temporaries that
     *  dead writers left in it (see beginRetrieve). Throws WriteError, or PacsError for a UID
     *  that isValidUid() refuses (naming it). */
    StoreOutcome storeInstance(const StudyRecord& study, const SeriesRecord& series,
                               const std::string& sopInstanceUid, const std::string& bytes,
                               Area area = Area::Studies);
    /** The same, the file written by `write` into the temporary path it is given. */
    StoreOutcome storeInstance(const StudyRecord& study, const SeriesRecord& series,
                               const std::string& sopInstanceUid,
                               const std::function<void(const std::filesystem::path& tmp)>& write,
                               Area area = Area::Studies);
    /** Instances taken by storeInstance() in this object (stored, identical or quarantined). */
    int instancesStored() const;
    /** A received instance's text that could not be converted to UTF-8 (listed with U+FFFD for
     *  the bad bytes), in words naming the instance and the elements: kept (at most 50) until
     *  takeTextProblems() hands them to the user. */
    void noteTextProblem(const std::string& text);
    std::vector<std::string> takeTextProblems();

    /** A retrieve starts (Studies area): the study (and series, when not empty) is listed as
     *  partial until finish(). The listener marks what it receives complete at the end of an
     *  association only for studies no retrieve is running on. Temporary files that a process
     *  killed mid-write left in the root or the study's folder are removed first (those whose
     *  writer's pid no longer runs). */
    void beginRetrieve(const StudyRecord& study, const std::string& seriesUid);
    /** Ends the retrieve begun with the same UIDs; `complete` lists the study (or the series)
     *  complete and recounts its files; otherwise it stays partial. */
    void finishRetrieve(const std::string& studyUid, const std::string& seriesUid, bool complete);
    bool retrieving(const std::string& studyUid) const;
    /** The listener's rule: series received over an association that ended normally are
     *  complete (the sender sent what it meant to), unless a retrieve runs on their study or
     *  the last one on it did not finish (the index keeps that until a retrieve completes). */
    void markReceived(const std::string& studyUid, const std::set<std::string>& seriesUids,
                      Area area = Area::Studies);

    /** Removes the study's folder and its entry. */
    void remove(const std::string& studyUid, Area area = Area::Studies);
    /** What the user's Delete does: unlists the study (the index rewritten atomically), then
     *  removes its files. Throws PacsError while a retrieve runs on it (saying so) or when it is
     *  not listed, WriteError naming the folder when files could not be removed (the study is
     *  unlisted then). */
    void deleteStudy(const std::string& studyUid, Area area = Area::Studies);
    /** Records the PACS node a study (Studies area) was retrieved from, for Resume; nothing
     *  when the study is not listed. */
    void setSource(const std::string& studyUid, const std::string& nodeName);

private:
    struct Index;
    Index load() const;
    void save(const Index& index) const;
    std::filesystem::path areaRoot(Area area) const;
    void listInstance(const StudyRecord& study, const SeriesRecord& series, Area area);
    StoreOutcome place(const std::filesystem::path& tmp, const std::filesystem::path& path,
                       const std::string& studyUid, const std::string& sopUid, Area area);

    std::filesystem::path m_root;
    mutable std::mutex m_mutex;
    std::set<std::string> m_retrieving;
    std::set<std::filesystem::path> m_cleaned; ///< study folders rid of dead writers' temporaries
    int m_stored = 0;
    std::vector<std::string> m_textProblems;
};

} // namespace fvr::core::pacs
