#pragma once
/** The local study store: what was retrieved from a PACS or received by the storage listener,
 *  so that a study opens again without the network. A folder per study under the root (a
 *  sub-folder per series, a file per instance named after its SOP Instance UID), and an index,
 *  `index.json` (nlohmann-json), of the studies with their series: complete or partial. */
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <fvr/core/pacs/pacs.h>

namespace fvr::core::pacs {

/** $XDG_DATA_HOME/fvr-workstation/studies, or ~/.local/share/fvr-workstation/studies. */
std::filesystem::path defaultLocalStoreRoot();

/**
 * Thread-safe within a process (the listener's thread and a retrieve may write at once): use one
 * LocalStore object for both. The index is rewritten atomically after every change and read
 * again by studies(), so another process sees complete entries only.
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
    };

    const std::filesystem::path& root() const { return m_root; }
    /** Every study in the index, most recently changed first. Throws PacsError when the index
     *  exists but cannot be read (naming the file). */
    std::vector<Entry> studies() const;
    std::optional<Entry> find(const std::string& studyUid) const;
    /** Where a study's / series' files go (whether or not they exist). */
    std::filesystem::path studyFolder(const std::string& studyUid) const;
    std::filesystem::path seriesFolder(const std::string& studyUid,
                                       const std::string& seriesUid) const;

    /** Writes one instance (`bytes`: a DICOM file with meta header) atomically as
     *  <study>/<series>/<sopInstanceUid>.dcm, and lists its study and series as partial unless
     *  already complete. `study` fills the index's description fields the first time. Returns
     *  the path. Throws WriteError, or PacsError for a UID that cannot name a file. */
    std::filesystem::path storeInstance(const StudyRecord& study, const SeriesRecord& series,
                                        const std::string& sopInstanceUid,
                                        const std::string& bytes);
    /** The same, the file written by `write` into the temporary path it is given (renamed into
     *  place when it returns). */
    std::filesystem::path storeInstance(
        const StudyRecord& study, const SeriesRecord& series, const std::string& sopInstanceUid,
        const std::function<void(const std::filesystem::path& tmp)>& write);
    /** Instances written by storeInstance() in this process since the store was made. */
    int instancesStored() const;

    /** A retrieve starts: the study (and series, when not empty) is listed as partial until
     *  finish(). The listener marks what it receives complete at the end of an association only
     *  for studies no retrieve is running on. */
    void beginRetrieve(const StudyRecord& study, const std::string& seriesUid);
    /** Ends the retrieve begun with the same UIDs; `complete` lists the study (or the series)
     *  complete and recounts its files; otherwise it stays partial. */
    void finishRetrieve(const std::string& studyUid, const std::string& seriesUid, bool complete);
    bool retrieving(const std::string& studyUid) const;
    /** The listener's rule: series received over an association that ended normally are
     *  complete (the sender sent what it meant to), unless a retrieve runs on their study or
     *  the last one on it did not finish (the index keeps that until a retrieve completes). */
    void markReceived(const std::string& studyUid, const std::set<std::string>& seriesUids);

    /** Removes the study's folder and its entry. */
    void remove(const std::string& studyUid);

private:
    struct Index;
    Index load() const;
    void save(const Index& index) const;

    std::filesystem::path m_root;
    mutable std::mutex m_mutex;
    std::set<std::string> m_retrieving;
    int m_stored = 0;
};

} // namespace fvr::core::pacs
