// The local study store: files in a folder per study and series, index.json beside them.
#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/pacs/local_store.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <fstream>
#include <map>
#include <sstream>
#include <sys/file.h>
#include <unistd.h>

namespace fs = std::filesystem;
using nlohmann::json;

namespace fvr::core::pacs {

/** The index as read from index.json: entries by study UID, with their time of change. */
struct LocalStore::Index {
    std::map<std::string, json> studies;
};

namespace {

constexpr const char* kIndexName = "index.json";

/** A UID as a file name: DICOM UIDs are digits and dots; some archives add letters. */
std::string uidName(const std::string& uid, const char* what) {
    const bool ok =
        !uid.empty() && uid.size() <= 64 && uid.front() != '.' &&
        std::all_of(uid.begin(), uid.end(), [](char c) {
            return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_';
        });
    if (!ok)
        throw PacsError(std::string("the ") + what + " UID \"" + uid +
                        "\" cannot name a file in the local store");
    return uid;
}

std::string nowIso() {
    const auto t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

/** An exclusive lock on <root>/.index.lock: the index is read, changed and written by one
 *  process at a time. */
class IndexLock {
public:
    explicit IndexLock(const fs::path& root) {
        std::error_code ec;
        fs::create_directories(root, ec);
        const fs::path path = root / ".index.lock";
        m_fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (m_fd < 0)
            throw PacsError("local store " + root.string() +
                            ": cannot open the index lock: " + std::strerror(errno));
        while (::flock(m_fd, LOCK_EX) != 0 && errno == EINTR) {}
    }
    ~IndexLock() {
        if (m_fd >= 0) ::close(m_fd); // releases the lock
    }
    IndexLock(const IndexLock&) = delete;
    IndexLock& operator=(const IndexLock&) = delete;

private:
    int m_fd = -1;
};

json studyJson(const StudyRecord& s) {
    json j{{"studyUid", s.studyUid}};
    for (const StudyTextField& f : studyTextFields()) j[f.name] = s.*f.member;
    j["complete"] = false;
    j["series"] = json::object();
    return j;
}

/** Fills the fields the entry lacks from `s` (the first instance or query gives them). */
void mergeStudy(json& entry, const StudyRecord& s) {
    for (const StudyTextField& f : studyTextFields())
        if (entry.value(f.name, std::string()).empty() && !(s.*f.member).empty())
            entry[f.name] = s.*f.member;
}

json& studyEntry(std::map<std::string, json>& studies, const StudyRecord& s) {
    auto it = studies.find(s.studyUid);
    if (it == studies.end())
        it = studies.emplace(s.studyUid, studyJson(s)).first;
    else
        mergeStudy(it->second, s);
    it->second["updated"] = nowIso();
    return it->second;
}

json& seriesEntry(json& study, const SeriesRecord& s) {
    json& series = study["series"];
    if (!series.contains(s.seriesUid))
        series[s.seriesUid] =
            json{{"modality", s.modality}, {"description", s.description}, {"complete", false}};
    return series[s.seriesUid];
}

/** DICOM files in a folder (written ones: not the .part of a write in progress). */
int countInstances(const fs::path& folder) {
    std::error_code ec;
    int n = 0;
    for (fs::recursive_directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec))
        if (it->is_regular_file(ec) && it->path().extension() == ".dcm") ++n;
    return n;
}

StudyRecord recordFromJson(const std::string& uid, const json& j) {
    StudyRecord s;
    s.studyUid = uid;
    for (const StudyTextField& f : studyTextFields()) s.*f.member = j.value(f.name, "");
    return s;
}

/** Throws PacsError (or json::type_error) when an index entry, edited by hand, does not have
 *  the shape the store reads and writes: objects of strings and booleans. */
void checkEntry(const std::string& uid, const json& entry) {
    const auto object = [&](const json& j, const std::string& what) {
        if (!j.is_object()) throw PacsError(what + " is not an object");
    };
    object(entry, "study " + uid);
    recordFromJson(uid, entry);
    (void)entry.value("complete", false);
    (void)entry.value("retrievePending", false);
    (void)entry.value("updated", "");
    const json series = entry.value("series", json::object());
    object(series, "the series of study " + uid);
    for (const auto& [suid, s] : series.items()) {
        object(s, "series " + suid);
        (void)s.value("modality", "");
        (void)s.value("description", "");
        (void)s.value("complete", false);
    }
}

} // namespace

const std::vector<StudyTextField>& studyTextFields() {
    static const std::vector<StudyTextField> fields{
        {"patientName", &StudyRecord::patientName},
        {"patientId", &StudyRecord::patientId},
        {"patientBirthDate", &StudyRecord::patientBirthDate},
        {"studyDate", &StudyRecord::studyDate},
        {"studyTime", &StudyRecord::studyTime},
        {"accessionNumber", &StudyRecord::accessionNumber},
        {"description", &StudyRecord::description},
        {"modalities", &StudyRecord::modalities}};
    return fields;
}

fs::path defaultLocalStoreRoot() {
    const char* xdg = std::getenv("XDG_DATA_HOME");
    fs::path base;
    if (xdg && *xdg && fs::path(xdg).is_absolute())
        base = xdg;
    else if (const char* home = std::getenv("HOME"); home && *home)
        base = fs::path(home) / ".local" / "share";
    else
        base = fs::temp_directory_path();
    return base / "fvr-workstation" / "studies";
}

LocalStore::LocalStore(fs::path root) : m_root(std::move(root)) {}

fs::path LocalStore::studyFolder(const std::string& studyUid) const {
    return m_root / uidName(studyUid, "study");
}

fs::path LocalStore::seriesFolder(const std::string& studyUid, const std::string& seriesUid) const {
    return studyFolder(studyUid) / uidName(seriesUid, "series");
}

LocalStore::Index LocalStore::load() const {
    Index index;
    const fs::path path = m_root / kIndexName;
    std::ifstream in(path);
    if (!in) return index; // no index yet: an empty store
    try {
        const json j = json::parse(in);
        const json& studies = j.at("studies");
        if (!studies.is_object()) throw PacsError("\"studies\" is not an object");
        for (const auto& [uid, entry] : studies.items()) {
            checkEntry(uid, entry);
            index.studies[uid] = entry;
        }
    } catch (const PacsError& e) {
        throw PacsError("local store index " + path.string() + " cannot be read: " + e.what());
    } catch (const json::exception& e) {
        throw PacsError("local store index " + path.string() + " cannot be read: " + e.what());
    }
    return index;
}

void LocalStore::save(const Index& index) const {
    json j{{"version", 1}, {"studies", json::object()}};
    for (const auto& [uid, entry] : index.studies) j["studies"][uid] = entry;
    writeFileAtomic(m_root / kIndexName, j.dump(2) + "\n");
}

std::vector<LocalStore::Entry> LocalStore::studies() const {
    std::lock_guard lock(m_mutex);
    const IndexLock fileLock(m_root);
    const Index index = load();
    std::vector<std::pair<std::string, Entry>> sorted;
    for (const auto& [uid, j] : index.studies) {
        Entry e;
        e.study = recordFromJson(uid, j);
        e.folder = studyFolder(uid);
        e.complete = j.value("complete", false);
        e.instances = countInstances(e.folder);
        const json series = j.value("series", json::object());
        for (const auto& [suid, sj] : series.items()) {
            SeriesEntry s{suid,
                          sj.value("modality", ""),
                          sj.value("description", ""),
                          seriesFolder(uid, suid),
                          sj.value("complete", false),
                          0};
            s.instances = countInstances(s.folder);
            e.series.push_back(std::move(s));
        }
        e.study.numberOfSeries = static_cast<int>(e.series.size());
        e.study.numberOfInstances = e.instances;
        sorted.emplace_back(j.value("updated", ""), std::move(e));
    }
    std::stable_sort(sorted.begin(), sorted.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<Entry> out;
    for (auto& [when, e] : sorted) out.push_back(std::move(e));
    return out;
}

std::optional<LocalStore::Entry> LocalStore::find(const std::string& studyUid) const {
    for (auto& e : studies())
        if (e.study.studyUid == studyUid) return std::move(e);
    return std::nullopt;
}

fs::path LocalStore::storeInstance(const StudyRecord& study, const SeriesRecord& series,
                                   const std::string& sopInstanceUid, const std::string& bytes) {
    return storeInstance(study, series, sopInstanceUid, [&](const fs::path& tmp) {
        std::ofstream out(tmp, std::ios::binary);
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        if (!out.flush()) throw WriteError(tmp.string() + ": write failed");
    });
}

fs::path LocalStore::storeInstance(const StudyRecord& study, const SeriesRecord& series,
                                   const std::string& sopInstanceUid,
                                   const std::function<void(const fs::path& tmp)>& write) {
    const fs::path folder = seriesFolder(study.studyUid, series.seriesUid);
    const fs::path path = folder / (uidName(sopInstanceUid, "SOP instance") + ".dcm");
    std::lock_guard lock(m_mutex);
    {
        // Listed (partial) before the first file lands, so no file is ever outside the index.
        const IndexLock fileLock(m_root);
        Index index = load();
        const bool known = index.studies.count(study.studyUid) &&
                           index.studies[study.studyUid]["series"].contains(series.seriesUid);
        if (!known) {
            seriesEntry(studyEntry(index.studies, study), series);
            save(index);
        }
    }
    std::error_code ec;
    fs::create_directories(folder, ec);
    if (ec) throw WriteError(folder.string() + ": cannot create the folder: " + ec.message());
    writeAtomically(path, write);
    ++m_stored;
    return path;
}

int LocalStore::instancesStored() const {
    std::lock_guard lock(m_mutex);
    return m_stored;
}

void LocalStore::beginRetrieve(const StudyRecord& study, const std::string& seriesUid) {
    uidName(study.studyUid, "study");
    std::lock_guard lock(m_mutex);
    m_retrieving.insert(study.studyUid);
    const IndexLock fileLock(m_root);
    Index index = load();
    json& entry = studyEntry(index.studies, study);
    entry["retrievePending"] = true; // until a retrieve completes it (markReceived)
    if (seriesUid.empty())
        entry["complete"] = false;
    else
        seriesEntry(entry, SeriesRecord{seriesUid, "", "", -1, -1})["complete"] = false;
    save(index);
}

void LocalStore::finishRetrieve(const std::string& studyUid, const std::string& seriesUid,
                                bool complete) {
    std::lock_guard lock(m_mutex);
    m_retrieving.erase(studyUid);
    if (!complete) return;
    const IndexLock fileLock(m_root);
    Index index = load();
    json& entry = studyEntry(index.studies, StudyRecord{studyUid});
    entry["retrievePending"] = false;
    if (seriesUid.empty()) entry["complete"] = true;
    for (auto& [suid, s] : entry["series"].items())
        if (seriesUid.empty() || suid == seriesUid) s["complete"] = true;
    save(index);
}

bool LocalStore::retrieving(const std::string& studyUid) const {
    std::lock_guard lock(m_mutex);
    return m_retrieving.count(studyUid) > 0;
}

void LocalStore::markReceived(const std::string& studyUid,
                              const std::set<std::string>& seriesUids) {
    std::lock_guard lock(m_mutex);
    if (m_retrieving.count(studyUid)) return;
    const IndexLock fileLock(m_root);
    Index index = load();
    auto it = index.studies.find(studyUid);
    // A retrieve that did not finish (cancelled, failed) keeps its study partial: a late
    // sub-association of its C-MOVE may still end normally.
    if (it == index.studies.end() || it->second.value("retrievePending", false)) return;
    for (const auto& suid : seriesUids)
        if (it->second["series"].contains(suid)) it->second["series"][suid]["complete"] = true;
    it->second["updated"] = nowIso();
    save(index);
}

void LocalStore::remove(const std::string& studyUid) {
    std::lock_guard lock(m_mutex);
    const IndexLock fileLock(m_root);
    Index index = load();
    index.studies.erase(studyUid);
    save(index); // unlisted first: a half-removed folder is never listed
    std::error_code ec;
    fs::remove_all(studyFolder(studyUid), ec);
}

} // namespace fvr::core::pacs
