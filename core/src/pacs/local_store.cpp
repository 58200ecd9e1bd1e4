// The local study store: files in a folder per study and series (in two areas), index.json
// beside them, received bytes that differ from a stored instance in quarantine/.
#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/text.h>

#include <nlohmann/json.hpp>

#include <dcmtk/config/osconfig.h> // first DCMTK include
#include <dcmtk/dcmdata/dcostrmb.h>
#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <fstream>
#include <map>
#include <sstream>
#include <sys/file.h>
#include <unistd.h>
#include <utility>

namespace fs = std::filesystem;
using nlohmann::json;

namespace fvr::core::pacs {

/** The index as read from index.json: entries by study UID, with their time of change, one
 *  map per area (an index of version 1 has no "incoming"). */
struct LocalStore::Index {
    std::map<std::string, json> studies, incoming;
    std::map<std::string, json>& of(Area area) {
        return area == Area::Incoming ? incoming : studies;
    }
};

namespace {

constexpr const char* kIndexName = "index.json";

constexpr const char* kIncomingName = "incoming";
constexpr const char* kQuarantineName = "quarantine";
constexpr std::size_t kMaxUidLength = 64;
/** The quarantine's limits (checkQuarantineRoom): files per SOP instance, bytes in all. */
constexpr std::uintmax_t kQuarantinePerInstance = 3;
constexpr std::uintmax_t kQuarantineBytes = std::uintmax_t(1) << 30; // 1 GiB

/** `text` quoted for a message: printable ASCII as it is, other bytes as \xNN, at most 80
 *  characters shown (a peer's value can be anything). */
std::string shownValue(std::string_view text) {
    std::string out = "\"";
    for (std::size_t i = 0; i < text.size() && i < 80; ++i) {
        const unsigned char c = static_cast<unsigned char>(text[i]);
        if (c == '"' || c == '\\') {
            out += '\\';
            out += static_cast<char>(c);
        } else if (c >= 0x20 && c < 0x7f) {
            out += static_cast<char>(c);
        } else {
            char hex[8];
            std::snprintf(hex, sizeof hex, "\\x%02x", c);
            out += hex;
        }
    }
    out += '"';
    if (text.size() > 80) out += "... (" + std::to_string(text.size()) + " characters)";
    return out;
}

/** A peer's UID as a folder or file name of the store: throws PacsError naming the UID and
 *  the rule when isValidUid() refuses it. */
const std::string& checkedUid(const std::string& uid, const char* what) {
    const std::string problem = uidProblem(uid);
    if (!problem.empty())
        throw PacsError(std::string("the ") + what + " UID " + shownValue(uid) +
                        " cannot name a file in the local store: " + problem +
                        " (a DICOM UID has 1 to 64 characters, digits and dots, with no empty "
                        "component)");
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

/** Whether the index entry `entry` lacks a study field that `s` has, or the series entry of
 *  `series` lacks its modality or description that `series` has. */
bool lacksFields(const json& entry, const StudyRecord& s, const SeriesRecord& series) {
    for (const StudyTextField& f : studyTextFields())
        if (entry.value(f.name, std::string()).empty() && !(s.*f.member).empty()) return true;
    const json all = entry.value("series", json::object());
    if (!all.contains(series.seriesUid)) return true;
    const json& one = all[series.seriesUid];
    return (one.value("modality", std::string()).empty() && !series.modality.empty()) ||
           (one.value("description", std::string()).empty() && !series.description.empty());
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

/** Moves `from` to `to` unless `to` exists (then false, `from` untouched): renameat2's
 *  RENAME_NOREPLACE, or link() and unlink() where the file system lacks it. Atomic either way:
 *  of two writers of the same name, exactly one places its file. Throws WriteError. */
bool placeNoReplace(const fs::path& from, const fs::path& to) {
    if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE) == 0)
        return true;
    int err = errno;
    if (err == EINVAL || err == ENOSYS || err == ENOTSUP) {
        if (::link(from.c_str(), to.c_str()) == 0) {
            ::unlink(from.c_str());
            return true;
        }
        err = errno;
    }
    if (err == EEXIST) return false;
    throw WriteError(to.string() +
                     ": cannot move the written file into place: " + std::strerror(err));
}

/** Whether two files hold the same bytes. Throws WriteError when one cannot be read. */
bool sameBytes(const fs::path& a, const fs::path& b) {
    std::error_code ec;
    const auto sizeA = fs::file_size(a, ec);
    if (ec) throw WriteError(a.string() + ": cannot be read: " + ec.message());
    const auto sizeB = fs::file_size(b, ec);
    if (ec) throw WriteError(b.string() + ": cannot be read: " + ec.message());
    if (sizeA != sizeB) return false;
    std::ifstream inA(a, std::ios::binary), inB(b, std::ios::binary);
    if (!inA) throw WriteError(a.string() + ": cannot be read: " + std::strerror(errno));
    if (!inB) throw WriteError(b.string() + ": cannot be read: " + std::strerror(errno));
    std::vector<char> bufA(1 << 16), bufB(1 << 16);
    while (inA && inB) {
        inA.read(bufA.data(), static_cast<std::streamsize>(bufA.size()));
        inB.read(bufB.data(), static_cast<std::streamsize>(bufB.size()));
        if (inA.gcount() != inB.gcount() ||
            !std::equal(bufA.begin(), bufA.begin() + inA.gcount(), bufB.begin()))
            return false;
    }
    return inA.eof() && inB.eof();
}

/** `dataset` encoded in `xfer` (explicit lengths), as the current DCMTK writes it; nullopt
 *  where it cannot be. */
std::optional<std::string> encoded(DcmDataset& dataset, E_TransferSyntax xfer) {
    std::string bytes;
    std::vector<char> chunk(1 << 16);
    DcmOutputBufferStream out(chunk.data(), static_cast<offile_off_t>(chunk.size()));
    dataset.transferInit();
    OFCondition cond = EC_StreamNotifyClient;
    while (cond == EC_StreamNotifyClient) {
        cond = dataset.write(out, xfer, EET_ExplicitLength, nullptr);
        void* data = nullptr;
        offile_off_t length = 0;
        out.flushBuffer(data, length);
        bytes.append(static_cast<const char*>(data), static_cast<std::size_t>(length));
    }
    dataset.transferEnd();
    if (cond.bad()) return std::nullopt;
    return bytes;
}

/** The dataset of DICOM file `path` encoded by encoded() in its own transfer syntax, with that
 *  syntax's UID; nullopt where DCMTK cannot read it. */
std::optional<std::pair<std::string, std::string>> datasetOf(const fs::path& path) {
    DcmFileFormat file;
    if (file.loadFile(path.c_str()).bad()) return std::nullopt;
    OFString syntax;
    file.getMetaInfo()->findAndGetOFString(DCM_TransferSyntaxUID, syntax);
    DcmDataset& dataset = *file.getDataset();
    E_TransferSyntax xfer = dataset.getOriginalXfer();
    if (xfer == EXS_Unknown) xfer = EXS_LittleEndianExplicit;
    auto bytes = encoded(dataset, xfer);
    if (!bytes) return std::nullopt;
    return std::make_pair(std::string(syntax.c_str()), std::move(*bytes));
}

/** Whether DICOM files `a` and `b` hold the same instance: the same transfer syntax and the same
 *  dataset, encoded by this DCMTK. The meta header (group 0002: the writer's implementation
 *  UID and version, the source AE) is not compared, so that a file written by an older DCMTK
 *  is the same instance as the one received again. A file DCMTK cannot read: false. */
bool sameDataset(const fs::path& a, const fs::path& b) {
    const auto da = datasetOf(a);
    if (!da) return false;
    const auto db = datasetOf(b);
    return db && *da == *db;
}

/** A limit from the environment variable `name` (a decimal count), `fallback` where unset;
 *  WriteError naming the variable and its value when that is not a count. */
std::uintmax_t limitFromEnv(const char* name, std::uintmax_t fallback) {
    const char* text = std::getenv(name);
    if (!text || !*text) return fallback;
    const std::string value = text;
    if (value.size() > 19 || value.find_first_not_of("0123456789") != std::string::npos)
        throw WriteError(std::string("the environment variable ") + name + "=" + shownValue(value) +
                         " is not a count (digits only)");
    return *parseNumber<std::uintmax_t>(value); // at most 19 digits: within uintmax_t
}

/** Throws WriteError (the callers answer C-STORE 0xA700, Refused: Out of resources) when the
 *  quarantine `folder` may take no more of `sop`: it holds kQuarantinePerInstance files of it
 *  already, or `size` more bytes would pass its budget. Both limits can be changed from the
 *  environment (FVR_QUARANTINE_MAX_PER_INSTANCE, FVR_QUARANTINE_MAX_BYTES). */
void checkQuarantineRoom(const fs::path& folder, const std::string& sop, std::uintmax_t size,
                         const std::string& what) {
    const std::uintmax_t perInstance =
        limitFromEnv("FVR_QUARANTINE_MAX_PER_INSTANCE", kQuarantinePerInstance);
    const std::uintmax_t budget = limitFromEnv("FVR_QUARANTINE_MAX_BYTES", kQuarantineBytes);
    std::uintmax_t total = 0, ofThis = 0;
    std::error_code ec;
    const std::string mark = "-" + sop + "-";
    for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
        std::error_code sizeEc;
        const std::uintmax_t bytes = it->is_regular_file(sizeEc) ? it->file_size(sizeEc) : 0;
        if (!sizeEc) total += bytes;
        if (it->path().filename().string().find(mark) != std::string::npos) ++ofThis;
    }
    const std::string refused = what + ", but the quarantine " + folder.string() + " is full: ";
    if (ofThis >= perInstance)
        throw WriteError(refused + "it holds " + std::to_string(ofThis) +
                         " files of this instance, at most " + std::to_string(perInstance) +
                         " (FVR_QUARANTINE_MAX_PER_INSTANCE). The instance is refused; the "
                         "stored file is kept unchanged");
    if (total + size > budget)
        throw WriteError(refused + "it holds " + std::to_string(total) + " bytes, and these " +
                         std::to_string(size) + " would pass its budget of " +
                         std::to_string(budget) +
                         " bytes (FVR_QUARANTINE_MAX_BYTES). The instance is refused; the stored "
                         "file is kept unchanged");
}

/** UTC now as yyyymmddThhmmss (quarantine file names sort by time). */
std::string nowStamp() {
    const auto t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y%m%dT%H%M%S", &tm);
    return buf;
}

/** A file in quarantine `folder` for `sop` with the bytes of `tmp`, or empty: a peer that sends
 *  the same changed instance again fills no more of the disk. */
fs::path alreadyQuarantined(const fs::path& tmp, const fs::path& folder, const std::string& sop) {
    std::error_code ec;
    const std::string mark = "-" + sop + "-";
    for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.find(mark) != std::string::npos && it->is_regular_file(ec) &&
            sameBytes(tmp, it->path()))
            return it->path();
    }
    return {};
}

/** Moves `tmp` to `<folder>/<stamp>-<sop>-<n>.dcm` with the first n free; the path. */
fs::path moveToQuarantine(const fs::path& tmp, const fs::path& folder, const std::string& sop) {
    std::error_code ec;
    fs::create_directories(folder, ec);
    if (ec) throw WriteError(folder.string() + ": cannot create the folder: " + ec.message());
    const std::string stem = nowStamp() + "-" + sop + "-";
    for (int n = 1; n < 100000; ++n) {
        const fs::path path = folder / (stem + std::to_string(n) + ".dcm");
        if (placeNoReplace(tmp, path)) return path;
    }
    throw WriteError(folder.string() + ": no free quarantine name for " + stem + "<n>.dcm");
}

/** Removes the temporary files (io/atomic_file.h names) in `folder` (and below it when
 *  `recursive`) whose writer no longer runs: what a killed process left. A file whose pid is
 *  alive (or reused) is kept: it may be a write in progress; so is one of another host or
 *  container (a store on NFS, shared with a container): temporaryWriterPid() gives no pid for
 *  it, its writer cannot be checked here. */
void removeStaleTemporaries(const fs::path& folder, bool recursive) {
    const auto stale = [](const fs::directory_entry& e) {
        std::error_code ec;
        const std::optional<long> pid = temporaryWriterPid(e.path());
        return pid && e.is_regular_file(ec) && ::kill(static_cast<pid_t>(*pid), 0) != 0 &&
               errno == ESRCH;
    };
    std::error_code ec;
    std::vector<fs::path> gone;
    if (recursive) {
        for (fs::recursive_directory_iterator it(folder, ec), end; !ec && it != end;
             it.increment(ec))
            if (stale(*it)) gone.push_back(it->path());
    } else {
        for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec))
            if (stale(*it)) gone.push_back(it->path());
    }
    for (const fs::path& p : gone) fs::remove(p, ec);
}

const char* areaName(Area area) { return area == Area::Incoming ? "incoming " : ""; }
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

std::string uidProblem(std::string_view uid) {
    if (uid.empty()) return "it is empty";
    if (uid.size() > kMaxUidLength)
        return "it has " + std::to_string(uid.size()) + " characters, at most 64";
    for (const char c : uid)
        if (!(c >= '0' && c <= '9') && c != '.')
            return "it contains " + shownValue(std::string_view(&c, 1)) + ", not a digit or a dot";
    if (uid.front() == '.') return "it begins with a dot";
    if (uid.back() == '.') return "it ends with a dot";
    if (uid.find("..") != std::string_view::npos) return "it has an empty component (\"..\")";
    return "";
}

bool isValidUid(std::string_view uid) { return uidProblem(uid).empty(); }

LocalStore::LocalStore(fs::path root) : m_root(std::move(root)) {}

fs::path LocalStore::areaRoot(Area area) const {
    return area == Area::Incoming ? m_root / kIncomingName : m_root;
}

fs::path LocalStore::studyFolder(const std::string& studyUid, Area area) const {
    return areaRoot(area) / checkedUid(studyUid, "study");
}

fs::path LocalStore::seriesFolder(const std::string& studyUid, const std::string& seriesUid,
                                  Area area) const {
    return studyFolder(studyUid, area) / checkedUid(seriesUid, "series");
}

fs::path LocalStore::quarantineFolder() const { return m_root / kQuarantineName; }

std::vector<fs::path> LocalStore::quarantined() const {
    std::vector<fs::path> files;
    std::error_code ec;
    for (fs::directory_iterator it(quarantineFolder(), ec), end; !ec && it != end; it.increment(ec))
        if (it->is_regular_file(ec) && it->path().extension() == ".dcm")
            files.push_back(it->path());
    std::sort(files.begin(), files.end());
    return files;
}

/** Reads one area's section of the index into `out` (absent: empty). */
static void loadSection(const json& j, const char* name, std::map<std::string, json>& out) {
    if (!j.contains(name)) return;
    const json& section = j.at(name);
    if (!section.is_object()) throw PacsError(std::string("\"") + name + "\" is not an object");
    for (const auto& [uid, entry] : section.items()) {
        checkEntry(uid, entry);
        out[uid] = entry;
    }
}

LocalStore::Index LocalStore::load() const {
    Index index;
    const fs::path path = m_root / kIndexName;
    std::ifstream in(path);
    if (!in) return index; // no index yet: an empty store
    try {
        const json j = json::parse(in);
        if (!j.is_object() || !j.contains("studies"))
            throw PacsError("it has no \"studies\" object");
        loadSection(j, "studies", index.studies);
        loadSection(j, "incoming", index.incoming); // version 2 on
    } catch (const PacsError& e) {
        throw PacsError("local store index " + path.string() + " cannot be read: " + e.what());
    } catch (const json::exception& e) {
        throw PacsError("local store index " + path.string() + " cannot be read: " + e.what());
    }
    return index;
}

void LocalStore::save(const Index& index) const {
    json j{{"version", 2}, {"studies", json::object()}, {"incoming", json::object()}};
    for (const auto& [uid, entry] : index.studies) j["studies"][uid] = entry;
    for (const auto& [uid, entry] : index.incoming) j["incoming"][uid] = entry;
    // The index is UTF-8 JSON: received text is converted from its SpecificCharacterSet before
    // it gets here (detail::storeDataset, with U+FFFD and noteTextProblem() for what cannot
    // be); a record given directly that is not UTF-8 still gets U+FFFD for each bad byte rather
    // than making the dump throw and the store stop. The DICOM files keep their own bytes.
    writeFileAtomic(m_root / kIndexName,
                    j.dump(2, ' ', false, json::error_handler_t::replace) + "\n");
}

/** The listing of one index entry (`uid` a valid UID). */
static LocalStore::Entry entryFrom(const LocalStore& store, const std::string& uid, const json& j,
                                   Area area) {
    LocalStore::Entry e;
    e.area = area;
    e.study = recordFromJson(uid, j);
    e.folder = store.studyFolder(uid, area);
    e.complete = j.value("complete", false);
    e.source = j.value("source", std::string());
    e.instances = countInstances(e.folder);
    const json series = j.value("series", json::object());
    for (const auto& [suid, sj] : series.items()) {
        if (!isValidUid(suid)) continue; // see studies()
        LocalStore::SeriesEntry s{suid,
                                  sj.value("modality", ""),
                                  sj.value("description", ""),
                                  store.seriesFolder(uid, suid, area),
                                  sj.value("complete", false),
                                  0};
        s.instances = countInstances(s.folder);
        e.series.push_back(std::move(s));
    }
    // Never complete with a series that is not: a refresh of one series of a complete study
    // that was cancelled leaves that series partial, and Open and Resume must see it.
    e.complete =
        e.complete && std::all_of(e.series.begin(), e.series.end(),
                                  [](const LocalStore::SeriesEntry& s) { return s.complete; });
    e.study.numberOfSeries = static_cast<int>(e.series.size());
    e.study.numberOfInstances = e.instances;
    return e;
}

std::vector<LocalStore::Entry> LocalStore::studies() const {
    std::lock_guard lock(m_mutex);
    const IndexLock fileLock(m_root);
    Index index = load();
    std::vector<std::pair<std::string, Entry>> sorted;
    for (const Area area : {Area::Studies, Area::Incoming})
        for (const auto& [uid, j] : index.of(area)) {
            // An entry written by an older version under a UID with letters is kept in the
            // file but not listed: the strict rule gives it no folder.
            if (!isValidUid(uid)) continue;
            sorted.emplace_back(j.value("updated", ""), entryFrom(*this, uid, j, area));
        }
    std::stable_sort(sorted.begin(), sorted.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<Entry> out;
    for (auto& [when, e] : sorted) out.push_back(std::move(e));
    return out;
}

std::optional<LocalStore::Entry> LocalStore::find(const std::string& studyUid, Area area) const {
    for (auto& e : studies())
        if (e.area == area && e.study.studyUid == studyUid) return std::move(e);
    return std::nullopt;
}

StoreOutcome LocalStore::storeInstance(const StudyRecord& study, const SeriesRecord& series,
                                       const std::string& sopInstanceUid, const std::string& bytes,
                                       Area area) {
    return storeInstance(
        study, series, sopInstanceUid,
        [&](const fs::path& tmp) {
            std::ofstream out(tmp, std::ios::binary);
            out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
            if (!out.flush()) throw WriteError(tmp.string() + ": write failed");
        },
        area);
}

void LocalStore::listInstance(const StudyRecord& study, const SeriesRecord& series, Area area) {
    std::lock_guard lock(m_mutex);
    const IndexLock fileLock(m_root);
    Index index = load();
    auto& section = index.of(area);
    const auto it = section.find(study.studyUid);
    const bool known = it != section.end() && it->second["series"].contains(series.seriesUid);
    // An entry that a retrieve began with UIDs alone (a series retrieve: no patient, date or
    // description) takes them from the first instance that has them.
    if (!known || lacksFields(it->second, study, series)) {
        json& seriesJson = seriesEntry(studyEntry(section, study), series);
        if (seriesJson.value("modality", std::string()).empty())
            seriesJson["modality"] = series.modality;
        if (seriesJson.value("description", std::string()).empty())
            seriesJson["description"] = series.description;
        save(index);
    }
}

StoreOutcome LocalStore::place(const fs::path& tmp, const fs::path& path,
                               const std::string& studyUid, const std::string& sopUid, Area area) {
    try {
        if (placeNoReplace(tmp, path)) return {StoreResult::Stored, path, ""};
        // A file is there already (stored before, or by a concurrent writer just now): it is
        // never replaced.
        // The same instance: the same bytes, or the same dataset under another meta header
        // (written by another DCMTK version, another source AE).
        if (sameBytes(tmp, path) || sameDataset(tmp, path)) {
            std::error_code ec;
            fs::remove(tmp, ec);
            return {StoreResult::Identical, path, ""};
        }
        const std::string what = "SOP instance " + sopUid + " of " + areaName(area) + "study " +
                                 studyUid + " was received again with different bytes";
        const IndexLock quarantineLock(m_root); // one writer at a time counts and adds
        fs::path kept = alreadyQuarantined(tmp, quarantineFolder(), sopUid);
        const bool again = !kept.empty();
        std::error_code ec;
        if (again) {
            fs::remove(tmp, ec);
        } else {
            checkQuarantineRoom(quarantineFolder(), sopUid, fs::file_size(tmp), what);
            kept = moveToQuarantine(tmp, quarantineFolder(), sopUid);
        }
        return {StoreResult::Quarantined, kept,
                what + ": the stored file " + path.string() +
                    " is kept unchanged, the received one is in quarantine as " + kept.string() +
                    (again ? " (the same bytes were quarantined before)" : "")};
    } catch (...) {
        std::error_code ec;
        fs::remove(tmp, ec);
        throw;
    }
}

StoreOutcome LocalStore::storeInstance(const StudyRecord& study, const SeriesRecord& series,
                                       const std::string& sopInstanceUid,
                                       const std::function<void(const fs::path& tmp)>& write,
                                       Area area) {
    const fs::path folder = seriesFolder(study.studyUid, series.seriesUid, area);
    const fs::path path = folder / (checkedUid(sopInstanceUid, "SOP instance") + ".dcm");
    // Listed (partial) before the first file lands, so no file is ever outside the index.
    listInstance(study, series, area);
    std::error_code ec;
    fs::create_directories(folder, ec);
    if (ec) throw WriteError(folder.string() + ": cannot create the folder: " + ec.message());
    // What a writer killed mid-write left in this study (the listener's Incoming area is
    // never cleaned by a retrieve): removed once per study and object, before this one writes.
    const fs::path studyDir = studyFolder(study.studyUid, area);
    bool clean = false;
    {
        std::lock_guard lock(m_mutex);
        clean = m_cleaned.insert(studyDir).second;
    }
    if (clean) removeStaleTemporaries(studyDir, true);
    // Written under a name of this writer alone, then placed without replacing.
    const fs::path tmp = temporaryPathFor(path);
    try {
        write(tmp);
    } catch (...) {
        fs::remove(tmp, ec);
        throw;
    }
    StoreOutcome outcome = place(tmp, path, study.studyUid, sopInstanceUid, area);
    std::lock_guard lock(m_mutex);
    ++m_stored;
    return outcome;
}

int LocalStore::instancesStored() const {
    std::lock_guard lock(m_mutex);
    return m_stored;
}

void LocalStore::noteTextProblem(const std::string& text) {
    std::lock_guard lock(m_mutex);
    if (m_textProblems.size() < 50) m_textProblems.push_back(text);
}

std::vector<std::string> LocalStore::takeTextProblems() {
    std::lock_guard lock(m_mutex);
    return std::exchange(m_textProblems, {});
}

void LocalStore::beginRetrieve(const StudyRecord& study, const std::string& seriesUid) {
    checkedUid(study.studyUid, "study");
    if (!seriesUid.empty()) checkedUid(seriesUid, "series");
    std::lock_guard lock(m_mutex);
    m_retrieving.insert(study.studyUid);
    const IndexLock fileLock(m_root);
    Index index = load();
    // What a retrieve or an index write killed before left: gone before this one writes.
    removeStaleTemporaries(m_root, false);
    removeStaleTemporaries(studyFolder(study.studyUid), true);
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

void LocalStore::markReceived(const std::string& studyUid, const std::set<std::string>& seriesUids,
                              Area area) {
    std::lock_guard lock(m_mutex);
    if (area == Area::Studies && m_retrieving.count(studyUid)) return;
    const IndexLock fileLock(m_root);
    Index index = load();
    auto& section = index.of(area);
    auto it = section.find(studyUid);
    // A retrieve that did not finish (cancelled, failed) keeps its study partial: a late
    // sub-association of its C-MOVE may still end normally.
    if (it == section.end() || it->second.value("retrievePending", false)) return;
    json& series = it->second["series"];
    for (const auto& suid : seriesUids)
        if (series.contains(suid)) series[suid]["complete"] = true;
    // A study is complete when all its series are (what the sender sent is all it meant to).
    bool all = !series.empty();
    for (const auto& [suid, s] : series.items()) all = all && s.value("complete", false);
    if (all) it->second["complete"] = true;
    it->second["updated"] = nowIso();
    save(index);
}

void LocalStore::remove(const std::string& studyUid, Area area) {
    const fs::path folder = studyFolder(studyUid, area); // refuses a UID that is not one
    std::lock_guard lock(m_mutex);
    const IndexLock fileLock(m_root);
    Index index = load();
    index.of(area).erase(studyUid);
    save(index); // unlisted first: a half-removed folder is never listed
    std::error_code ec;
    fs::remove_all(folder, ec);
}

void LocalStore::deleteStudy(const std::string& studyUid, Area area) {
    const fs::path folder = studyFolder(studyUid, area); // refuses a UID that is not one
    std::lock_guard lock(m_mutex);
    if (area == Area::Studies && m_retrieving.count(studyUid))
        throw PacsError("study " + studyUid +
                        " is being retrieved: cancel the retrieve (or let it end) before "
                        "deleting it");
    const IndexLock fileLock(m_root);
    Index index = load();
    if (index.of(area).erase(studyUid) == 0)
        throw PacsError("study " + studyUid + " is not in the local store " + m_root.string());
    save(index); // the index first, atomically: a half-removed folder is never listed
    std::error_code ec;
    fs::remove_all(folder, ec);
    if (ec)
        throw WriteError(folder.string() +
                         ": unlisted, but its files could not all be removed: " + ec.message());
}

void LocalStore::setSource(const std::string& studyUid, const std::string& nodeName) {
    std::lock_guard lock(m_mutex);
    const IndexLock fileLock(m_root);
    Index index = load();
    const auto it = index.studies.find(studyUid);
    if (it == index.studies.end() || it->second.value("source", std::string()) == nodeName) return;
    it->second["source"] = nodeName;
    save(index);
}

} // namespace fvr::core::pacs
