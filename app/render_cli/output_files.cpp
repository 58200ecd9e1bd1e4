// fvr-render's outputs: staged beside FILE, committed together; leftovers of dead runs removed.
#include "output_files.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/text.h>

namespace fvr::cli {
namespace fs = std::filesystem;

namespace {

bool allDigits(const std::string& s) {
    return !s.empty() &&
           std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
}

/** Whether `name` is the name of a file fvr writes as an output (or the dataset's Zarr). */
bool isOutputName(const std::string& name) {
    const std::string ext = core::asciiLower(fs::path(name).extension().string());
    for (const char* e : {".npy", ".pfm", ".png", ".dcm", ".json", ".zarr"})
        if (ext == e) return true;
    return false;
}

/** A file or a symbolic link (what a run may remove); never a folder. */
bool isFileOrLink(const fs::path& p) {
    std::error_code ec;
    const fs::file_status st = fs::symlink_status(p, ec);
    return !ec && (fs::is_regular_file(st) || fs::is_symlink(st));
}

/** The entries of `dir` (the working folder for ""), listed without throwing; `ok` false where
 *  the folder cannot be read. Listed first, so that removing some does not disturb the listing.
 */
std::vector<fs::path> entriesOf(const fs::path& dir, bool& ok) {
    std::vector<fs::path> entries;
    std::error_code ec;
    fs::directory_iterator it(dir.empty() ? fs::path(".") : dir, ec);
    for (const fs::directory_iterator end; !ec && it != end; it.increment(ec))
        entries.push_back(it->path());
    ok = !ec;
    return entries;
}

/** The (device, inode) of every file some process holds open, from /proc/<pid>/fd; nothing
 *  where a process's descriptors cannot be read (then `complete` is false: anything may be
 *  open). */
std::set<std::pair<dev_t, ino_t>> openFiles(bool& complete) {
    std::set<std::pair<dev_t, ino_t>> open;
    complete = true;
    bool ok = false;
    const std::vector<fs::path> procs = entriesOf("/proc", ok);
    if (!ok) complete = false;
    for (const fs::path& proc : procs) {
        if (!allDigits(proc.filename())) continue;
        const std::vector<fs::path> fds = entriesOf(proc / "fd", ok);
        // A process that cannot be read (EACCES) may hold the file; one that ended holds none.
        if (!ok && fs::exists(proc)) complete = false;
        for (const fs::path& fd : fds) {
            struct stat st {};
            if (::stat(fd.c_str(), &st) == 0 && S_ISREG(st.st_mode))
                open.emplace(st.st_dev, st.st_ino);
        }
    }
    return open;
}

/** Removes the old-form temporaries `candidates` that no process holds open and that have not
 *  changed for a minute (a writer of the old form keeps its file open until it renames it). */
void removeUnopened(const std::vector<fs::path>& candidates, std::vector<std::string>& removed) {
    if (candidates.empty()) return;
    bool complete = false;
    const auto open = openFiles(complete);
    if (!complete) return; // some process's files are hidden from us: it may be the writer
    const auto minuteAgo = fs::file_time_type::clock::now() - std::chrono::minutes(1);
    for (const fs::path& p : candidates) {
        struct stat st {};
        std::error_code ec;
        if (::lstat(p.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) continue;
        if (open.count({st.st_dev, st.st_ino}) || fs::last_write_time(p, ec) > minuteAgo || ec)
            continue;
        if (fs::remove(p, ec)) removed.push_back(p.filename());
    }
}

} // namespace

std::string temporaryName(const std::string& name) {
    return core::temporaryPathFor(name).filename(); // the one form of fvr's temporaries
}

std::optional<std::pair<std::string, long>> parseTemporaryName(const std::string& filename) {
    const std::string suffix = ".part";
    if (filename.size() < 1 + suffix.size() || filename[0] != '.' ||
        filename.compare(filename.size() - suffix.size(), suffix.size(), suffix) != 0)
        return std::nullopt;
    const std::string body = filename.substr(1, filename.size() - 1 - suffix.size());
    const auto dot2 = body.rfind('.');
    if (dot2 == std::string::npos || dot2 == 0) return std::nullopt;
    const auto dot1 = body.rfind('.', dot2 - 1);
    if (dot1 == std::string::npos || dot1 == 0) return std::nullopt;
    const auto pid = core::temporaryWriterPid(filename);
    if (!pid) return std::nullopt;
    return std::make_pair(body.substr(0, dot1), *pid);
}

bool processIsGone(long pid) {
    if (pid <= 0 || pid > INT_MAX) return false;
    if (pid == long(::getpid())) return false;
    return ::kill(pid_t(pid), 0) != 0 && errno == ESRCH;
}

bool isNumberedFrame(const std::string& name, const std::string& out) {
    const fs::path p(out);
    const std::string stem = p.stem().string() + "_", ext = p.extension().string();
    if (name.size() < stem.size() + 4 + ext.size() || name.compare(0, stem.size(), stem) != 0 ||
        name.compare(name.size() - ext.size(), ext.size(), ext) != 0)
        return false;
    const std::string num = name.substr(stem.size(), name.size() - stem.size() - ext.size());
    // numberedPath's "_%04zu": four digits, or more without a leading zero.
    return allDigits(num) && (num.size() == 4 || num[0] != '0');
}

std::vector<std::string> removeStaleTemporaries(const fs::path& dir, const std::string& out) {
    std::vector<std::string> removed;
    std::vector<fs::path> oldForm;
    const std::string outName = fs::path(out).filename();
    bool ok = false;
    for (const fs::path& entry : entriesOf(dir, ok)) {
        const std::string name = entry.filename();
        if (const auto t = parseTemporaryName(name)) {
            // fvr's form: the writer's pid in the name, of this host's pid space (a temporary
            // of another host or container is never parsed: kept). Only where that process is
            // gone, and only temporaries of outputs: staging folders and the Zarr conversion's
            // folders are named after an output (`.b.png.PID-ID.N.part`), like the files; a
            // folder of any other name (`.mydir.1.2.part`) is the user's.
            std::error_code ec;
            if (isOutputName(t->first) && processIsGone(t->second)) {
                if (fs::remove_all(entry, ec) != static_cast<std::uintmax_t>(-1) && !ec)
                    removed.push_back(name);
            }
        } else if (name.size() > 5 && name.compare(name.size() - 5, 5, ".part") == 0) {
            const std::string of = name.substr(0, name.size() - 5); // the name it was for
            if (of == outName || of == outName + ".json" || isNumberedFrame(of, out))
                oldForm.push_back(entry);
        }
    }
    removeUnopened(oldForm, removed);
    return removed;
}

void removeStaleTemporariesOf(const fs::path& dir, const std::string& name) {
    bool ok = false;
    for (const fs::path& entry : entriesOf(dir, ok)) {
        const auto t = parseTemporaryName(entry.filename());
        std::error_code ec;
        if (t && t->first == name && processIsGone(t->second)) fs::remove_all(entry, ec);
    }
}

OutputFiles::OutputFiles(std::string out) : m_out(std::move(out)) {
    m_dir = fs::path(m_out).parent_path();
    const std::string name = fs::path(m_out).filename();
    for (const std::string& r : removeStaleTemporaries(m_dir, m_out))
        std::fprintf(stderr, "fvr-render: removed %s, left by a run that died\n",
                     (m_dir / r).c_str());
    const fs::path staging = m_dir / temporaryName(name);
    if (::mkdir(staging.c_str(), 0777) != 0)
        throw core::WriteError(m_out + ": cannot write into its folder " +
                               (m_dir.empty() ? fs::path(".") : m_dir).string() + ": " +
                               std::strerror(errno));
    m_staging = staging;
}

OutputFiles::~OutputFiles() { discard(); }

fs::path OutputFiles::staged(const std::string& finalPath) {
    const fs::path target(finalPath);
    const fs::path at = target.parent_path() == m_dir
                            ? m_staging / target.filename()
                            : target.parent_path() / temporaryName(target.filename());
    m_files.emplace_back(at, target);
    return at;
}

namespace {

/** `text` with every `from` replaced by `to` (left to right, never inside a replacement). */
std::string replaceAll(std::string text, const std::string& from, const std::string& to) {
    for (std::size_t k = 0; !from.empty() && (k = text.find(from, k)) != std::string::npos;
         k += to.size())
        text.replace(k, from.size(), to);
    return text;
}

} // namespace

std::string OutputFiles::finalNames(std::string message) const {
    for (const auto& [at, target] : m_files)
        message = replaceAll(message, at.string(), target.string());
    if (m_staging.empty()) return message; // committed or discarded: nothing staged
    return replaceAll(message, m_staging.string() + "/", m_dir.empty() ? "" : m_dir.string() + "/");
}

namespace {

/** The file names the sidecar `path` lists in "output"/"files" (none where it cannot be read). */
std::vector<std::string> listedFiles(const fs::path& path) {
    std::vector<std::string> names;
    std::error_code ec;
    if (!fs::is_regular_file(fs::symlink_status(path, ec)) || fs::file_size(path, ec) > (64 << 20))
        return names;
    std::ifstream in(path, std::ios::binary);
    const auto j = nlohmann::json::parse(in, nullptr, false);
    if (!j.is_object() || !j.contains("output") || !j["output"].is_object()) return names;
    const auto& files = j["output"].value("files", nlohmann::json::array());
    if (!files.is_array()) return names;
    for (const auto& f : files)
        if (f.is_string()) names.push_back(fs::path(f.get<std::string>()).filename());
    return names;
}

} // namespace

void OutputFiles::removeEarlierRun() const {
    std::set<std::string> ours;
    for (const auto& f : m_files) ours.insert(f.second.filename());
    // The files the earlier run's sidecar lists, only where they are FILE or its frames (the
    // names --out FILE writes) in this folder: a sidecar names nothing else for removal.
    const std::string outName = fs::path(m_out).filename(), sidecar = m_out + ".json";
    const std::vector<std::string> earlier = listedFiles(sidecar);
    // Its sidecar first: from here to the last rename no sidecar describes a mix of two runs.
    std::error_code ec;
    if (isFileOrLink(sidecar)) fs::remove(sidecar, ec);
    for (const std::string& name : earlier) {
        const fs::path p = m_dir / name;
        if ((name == outName || isNumberedFrame(name, m_out)) && !ours.count(name) &&
            isFileOrLink(p))
            fs::remove(p, ec);
    }
}

void OutputFiles::commit() {
    // What would stop a rename (a folder under a final name) fails before anything is moved.
    for (const auto& [at, target] : m_files) {
        std::error_code ec;
        if (fs::is_directory(fs::symlink_status(target, ec)))
            throw core::WriteError(target.string() +
                                   ": cannot move the written file into place: a folder");
    }
    removeEarlierRun();
    std::stable_partition(m_files.begin(), m_files.end(),
                          [&](const auto& f) { return f.second.string() != m_out + ".json"; });
    for (const auto& [at, target] : m_files)
        if (::rename(at.c_str(), target.c_str()) != 0)
            throw core::WriteError(target.string() + ": cannot move the written file into place: " +
                                   std::strerror(errno));
    m_files.clear();
    discard();
}

void OutputFiles::discard() noexcept {
    std::error_code ec;
    for (const auto& f : m_files)
        if (f.first.parent_path() != m_staging) fs::remove(f.first, ec);
    m_files.clear();
    if (!m_staging.empty()) fs::remove_all(m_staging, ec);
    m_staging.clear();
}

InterruptGuard::InterruptGuard() {
    s_signal = 0;
    for (std::size_t k = 0; k < std::size(kSignals); ++k) {
        struct sigaction old {};
        m_installed[k] = sigaction(kSignals[k], nullptr, &old) == 0 &&
                         !(old.sa_flags & SA_SIGINFO) && old.sa_handler == SIG_DFL;
        if (!m_installed[k]) continue;
        struct sigaction sa {};
        sa.sa_handler = &InterruptGuard::onSignal;
        sigemptyset(&sa.sa_mask);
        sa.sa_flags = SA_RESTART | SA_RESETHAND;
        sigaction(kSignals[k], &sa, nullptr);
    }
}

void InterruptGuard::dieIfInterrupted(const std::string& what) {
    const int sig = s_signal;
    if (sig == 0) return;
    std::fprintf(stderr, "fvr-render: %s\n", what.c_str());
    restore();
    std::raise(sig);
    std::_Exit(128 + sig); // not reached: the default action ends the process
}

void InterruptGuard::restore() {
    for (std::size_t k = 0; k < std::size(kSignals); ++k)
        if (m_installed[k]) std::signal(kSignals[k], SIG_DFL);
    std::fill(std::begin(m_installed), std::end(m_installed), false);
}

} // namespace fvr::cli
