// The local study store shared by many writers: threads and processes storing into one store,
// the temporaries of a dead writer, the same dataset under another meta header, and the
// quarantine's cap.
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include <fvr/core/io/atomic_file.h>

#include <gtest/gtest.h>

#include "pacs_local_test_support.h"

using namespace fvr::test::pacs_local;
using fvr::core::temporaryPathFor;

namespace {

/** What one writer did: its outcomes by SOP instance, or the first error. */
struct WriterReport {
    std::map<std::string, StoreResult> outcomes;
    std::string error;
};

/** Stores `shared` (from `offset` on, wrapping) interleaved with `own`, through its own
 *  LocalStore object on `root`, as a separate process would. */
WriterReport runWriter(const fs::path& root, const std::vector<Source>& shared,
                       const std::vector<Source>& own, std::size_t offset) {
    WriterReport report;
    try {
        LocalStore store(root);
        const std::size_t n = std::max(shared.size(), own.size());
        for (std::size_t i = 0; i < n; ++i) {
            if (i < shared.size()) {
                const Source& s = shared[(i + offset) % shared.size()];
                report.outcomes[s.sop] =
                    store.storeInstance(s.study, s.series, s.sop, s.bytes).result;
            }
            if (i < own.size()) {
                const Source& s = own[i];
                report.outcomes[s.sop] =
                    store.storeInstance(s.study, s.series, s.sop, s.bytes).result;
            }
        }
    } catch (const std::exception& e) {
        report.error = e.what();
    }
    return report;
}

/** A child process's report through a pipe: "<result digit> <sop>" lines, or "E <message>". */
std::string encode(const WriterReport& r) {
    if (!r.error.empty()) return "E " + r.error + "\n";
    std::string out;
    for (const auto& [sop, result] : r.outcomes)
        out += std::to_string(static_cast<int>(result)) + " " + sop + "\n";
    return out;
}

WriterReport decode(const std::string& text) {
    WriterReport r;
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("E ", 0) == 0)
            r.error = line.substr(2);
        else if (line.size() > 2)
            r.outcomes[line.substr(2)] = StoreResult(line[0] - '0');
    }
    return r;
}

} // namespace

// Concurrent retrieves into one store: each writer needs a temporary name of its own (with one
// shared <SOP>.dcm.part, 2 of 9 failed: "cannot move the written file into place"). 8 threads,
// each with its own LocalStore object, and 3 child processes store the same study at once (in
// different orders) and a study of their own each.
TEST(PacsLocalStore, EightWritersAndThreeProcessesShareOneStore) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-concurrent";
    fs::remove_all(root);
    std::vector<Source> shared = headCt();
    if (shared.empty()) {
        std::cout << "[ note ] shared data not found: the common study is 93 synthetic instances\n";
        shared = syntheticStudy("1.2.826.0.1.3680043.2.1125.1", 93);
    }
    constexpr int kThreads = 8, kProcesses = 3;
    std::vector<std::vector<Source>> own;
    for (int w = 0; w < kThreads + kProcesses; ++w)
        own.push_back(syntheticStudy("1.2.826.0.1.3680043.2.1125.9." + std::to_string(w + 1), 24));

    const auto start = std::chrono::steady_clock::now();
    std::vector<std::pair<pid_t, int>> children; // pid, read end of its pipe
    for (int p = 0; p < kProcesses; ++p) {
        int fds[2];
        ASSERT_EQ(::pipe(fds), 0);
        const pid_t pid = ::fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) { // the child: store, report, leave without the parent's atexit work
            ::close(fds[0]);
            const std::string text =
                encode(runWriter(root, shared, own[kThreads + p], 31 * (kThreads + p)));
            std::size_t done = 0;
            while (done < text.size()) {
                const ssize_t n = ::write(fds[1], text.data() + done, text.size() - done);
                if (n <= 0) ::_exit(2);
                done += std::size_t(n);
            }
            ::_exit(0);
        }
        ::close(fds[1]);
        children.emplace_back(pid, fds[0]);
    }
    std::vector<WriterReport> reports(kThreads);
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&, t] { reports[t] = runWriter(root, shared, own[t], 11 * t); });
    for (auto& t : threads) t.join();
    for (const auto& [pid, fd] : children) {
        std::string text;
        char buf[4096];
        for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) text.append(buf, std::size_t(n));
        ::close(fd);
        int status = 0;
        ASSERT_EQ(::waitpid(pid, &status, 0), pid);
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
        reports.push_back(decode(text));
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << "[ time ] " << kThreads + kProcesses << " writers, "
              << (kThreads + kProcesses) * (shared.size() + own[0].size()) << " stores: " << seconds
              << " s\n";

    // No error; each shared instance placed once and found identical by every other writer;
    // each writer's own instances placed by it; nothing quarantined.
    std::map<std::string, int> placed;
    for (std::size_t w = 0; w < reports.size(); ++w) {
        EXPECT_EQ(reports[w].error, "") << "writer " << w;
        EXPECT_EQ(reports[w].outcomes.size(), shared.size() + own[w].size()) << "writer " << w;
        for (const auto& [sop, result] : reports[w].outcomes) {
            EXPECT_NE(result, StoreResult::Quarantined) << sop;
            if (result == StoreResult::Stored) ++placed[sop];
        }
        for (const Source& s : own[w]) EXPECT_EQ(reports[w].outcomes[s.sop], StoreResult::Stored);
    }
    for (const Source& s : shared) EXPECT_EQ(placed[s.sop], 1) << s.sop;

    // Every file bit-equal to its source; no temporary left; the index valid and complete.
    LocalStore store(root);
    std::set<std::string> expectedFiles{".index.lock", "index.json"};
    std::vector<const std::vector<Source>*> all{&shared};
    for (const auto& o : own) all.push_back(&o);
    for (const auto* set : all)
        for (const Source& s : *set) {
            const fs::path file =
                store.seriesFolder(s.study.studyUid, s.series.seriesUid) / (s.sop + ".dcm");
            EXPECT_EQ(readBytes(file), s.bytes) << file;
            expectedFiles.insert(fs::relative(file, root).string());
        }
    const auto files = filesUnder(root);
    EXPECT_EQ(std::set<std::string>(files.begin(), files.end()), expectedFiles);
    const nlohmann::json index = nlohmann::json::parse(readBytes(root / "index.json"));
    for (const auto* set : all)
        for (const Source& s : *set)
            EXPECT_TRUE(
                index.at("studies").at(s.study.studyUid).at("series").contains(s.series.seriesUid))
                << s.study.studyUid << " / " << s.series.seriesUid;
    const auto entries = store.studies();
    EXPECT_EQ(entries.size(), all.size());
    for (const auto& e : entries)
        EXPECT_EQ(e.instances,
                  e.study.studyUid == shared[0].study.studyUid ? int(shared.size()) : 24)
            << e.study.studyUid;
}

// A process killed mid-write (kill -9) leaves its temporary file; the next retrieve into the
// study removes it, and keeps one whose writer still runs.
TEST(PacsLocalStore, ARetrieveRemovesTheTemporariesOfADeadWriter) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-stale";
    fs::remove_all(root);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) ::_exit(0);
    ASSERT_EQ(::waitpid(child, nullptr, 0), child); // its pid now names no process
    const std::string dead = std::to_string(child), alive = std::to_string(::getpid());
    const fs::path series = root / "1.2.3/1.2.3.1";
    fs::create_directories(series);
    const fs::path staleFile = series / (".1.2.3.1.1.dcm." + dead + ".0.part");
    const fs::path staleIndex = root / (".index.json." + dead + ".4.part");
    const fs::path live = series / (".1.2.3.1.2.dcm." + alive + ".0.part");
    const fs::path notOurs = series / "notes.part";
    // The form with the writer's pid space: ours with a dead pid goes; another host's or
    // container's (a store on NFS, shared with a container) stays, its pid means nothing here.
    const std::string ours = fvr::core::writerIdentity();
    const std::string other = ours == "00000000" ? "00000001" : "00000000";
    const fs::path staleOurs = series / (".1.2.3.1.3.dcm." + dead + "-" + ours + ".0.part");
    const fs::path indexOurs = root / (".index.json." + dead + "-" + ours + ".5.part");
    const fs::path foreign = series / (".1.2.3.1.4.dcm." + dead + "-" + other + ".0.part");
    const fs::path foreignIndex = root / (".index.json." + dead + "-" + other + ".5.part");
    for (const fs::path& p :
         {staleFile, staleIndex, live, notOurs, staleOurs, indexOurs, foreign, foreignIndex})
        std::ofstream(p) << "x";
    LocalStore store(root);
    store.beginRetrieve(study("1.2.3"), "");
    EXPECT_FALSE(fs::exists(staleFile));
    EXPECT_FALSE(fs::exists(staleIndex));
    EXPECT_FALSE(fs::exists(staleOurs));
    EXPECT_FALSE(fs::exists(indexOurs));
    EXPECT_TRUE(fs::exists(live));
    EXPECT_TRUE(fs::exists(notOurs));
    EXPECT_TRUE(fs::exists(foreign));
    EXPECT_TRUE(fs::exists(foreignIndex));
}

// The listener's Incoming area is never touched by a retrieve: a writer killed there left its
// temporary for good. The first store into a study folder removes the dead writers' ones (of
// this pid space), and keeps a live writer's and another host's.
TEST(PacsLocalStore, AStoreIntoIncomingRemovesTheTemporariesOfADeadWriter) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-stale-incoming";
    fs::remove_all(root);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) ::_exit(0);
    ASSERT_EQ(::waitpid(child, nullptr, 0), child);
    const std::string dead = std::to_string(child), alive = std::to_string(::getpid());
    const std::string ours = fvr::core::writerIdentity();
    const std::string other = ours == "00000000" ? "00000001" : "00000000";
    const fs::path series = root / "incoming/1.2.7/1.2.7.9";
    fs::create_directories(series);
    const fs::path stale = series / (".1.2.7.9.1.dcm." + dead + "-" + ours + ".0.part");
    const fs::path staleOld = series / (".1.2.7.9.2.dcm." + dead + ".0.part");
    const fs::path live = series / (".1.2.7.9.3.dcm." + alive + "-" + ours + ".0.part");
    const fs::path foreign = series / (".1.2.7.9.4.dcm." + dead + "-" + other + ".0.part");
    for (const fs::path& p : {stale, staleOld, live, foreign}) std::ofstream(p) << "x";
    LocalStore store(root);
    const auto ds = makeDataset("1.2.7", "1.2.7.1", "1.2.7.1.1");
    EXPECT_EQ(detail::storeDataset(store, *ds, Area::Incoming).outcome.result, StoreResult::Stored);
    EXPECT_FALSE(fs::exists(stale));
    EXPECT_FALSE(fs::exists(staleOld));
    EXPECT_TRUE(fs::exists(live));
    EXPECT_TRUE(fs::exists(foreign));
    EXPECT_EQ(store.find("1.2.7", Area::Incoming)->instances, 1);
}

// "The same instance" is the same dataset in the same transfer syntax, not the same file bytes:
// the meta header (group 0002) names the DCMTK that wrote the file, so after a DCMTK upgrade
// every resumed instance was quarantined and a study could never complete again.
TEST(PacsLocalStore, TheSameDatasetUnderAnotherMetaHeaderIsIdentical) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-meta";
    fs::remove_all(root);
    LocalStore store(root);
    const auto ds = makeDataset("1.2.8", "1.2.8.1", "1.2.8.1.1");
    const auto stored = detail::storeDataset(store, *ds);
    ASSERT_EQ(stored.outcome.result, StoreResult::Stored);
    // As an older DCMTK would have written it: another implementation class UID and version
    // name, of the same lengths (the meta header's group length stays right).
    std::string bytes = readBytes(stored.outcome.path);
    const auto replace = [&](const std::string& from, const std::string& to) {
        const std::size_t at = bytes.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        ASSERT_LT(at, 132u + 200u) << from; // in the meta header, not the dataset
        bytes.replace(at, from.size(), to);
    };
    replace(OFFIS_DTK_IMPLEMENTATION_VERSION_NAME,
            std::string(std::strlen(OFFIS_DTK_IMPLEMENTATION_VERSION_NAME), 'Z'));
    replace(OFFIS_IMPLEMENTATION_CLASS_UID,
            std::string(OFFIS_IMPLEMENTATION_CLASS_UID).substr(0, 18) +
                std::string(std::strlen(OFFIS_IMPLEMENTATION_CLASS_UID) - 18, '9'));
    { std::ofstream(stored.outcome.path, std::ios::binary) << bytes; }
    const auto again = detail::storeDataset(store, *ds);
    EXPECT_EQ(again.outcome.result, StoreResult::Identical) << again.outcome.message;
    EXPECT_EQ(readBytes(stored.outcome.path), bytes); // the stored file untouched
    EXPECT_TRUE(store.quarantined().empty());
    // One pixel changed: another dataset, quarantined as before.
    const std::vector<Uint16> pixels = [] {
        std::vector<Uint16> p(16, 100);
        p[5] = 101;
        return p;
    }();
    ds->putAndInsertUint16Array(DCM_PixelData, pixels.data(), pixels.size());
    const auto changed = detail::storeDataset(store, *ds);
    EXPECT_EQ(changed.outcome.result, StoreResult::Quarantined);
    EXPECT_EQ(readBytes(stored.outcome.path), bytes);
    EXPECT_EQ(store.quarantined().size(), 1u);
}

// A permitted sender could send endless variants of one SOP instance: the quarantine takes at
// most 3 files of one instance and a byte budget in all (1 GiB unless FVR_QUARANTINE_MAX_BYTES
// says otherwise); beyond, the instance is refused with WriteError (the listener answers
// 0xA700, Refused: Out of resources) naming the limit, and nothing is written.
TEST(PacsLocalStore, TheQuarantineIsCapped) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-quarantine-cap";
    fs::remove_all(root);
    ::unsetenv("FVR_QUARANTINE_MAX_BYTES");
    ::unsetenv("FVR_QUARANTINE_MAX_PER_INSTANCE");
    LocalStore store(root);
    const std::vector<Source> one = syntheticStudy("1.2.9", 2);
    for (const Source& s : one)
        ASSERT_EQ(store.storeInstance(s.study, s.series, s.sop, s.bytes).result,
                  StoreResult::Stored);
    const Source& a = one[0];
    const auto variant = [](const Source& s, int n) {
        return s.bytes.substr(0, s.bytes.size() - 8) + "variant" + std::to_string(n);
    };
    const auto refusal = [&](const Source& s, int n) {
        try {
            store.storeInstance(s.study, s.series, s.sop, variant(s, n));
        } catch (const fvr::core::WriteError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    for (int n = 1; n <= 3; ++n)
        EXPECT_EQ(store.storeInstance(a.study, a.series, a.sop, variant(a, n)).result,
                  StoreResult::Quarantined);
    const auto before = filesUnder(root);
    std::string msg = refusal(a, 4);
    for (const std::string& part :
         {"SOP instance " + a.sop, store.quarantineFolder().string() + " is full",
          std::string("it holds 3 files of this instance, at most 3"),
          std::string("FVR_QUARANTINE_MAX_PER_INSTANCE"), std::string("refused")})
        EXPECT_NE(msg.find(part), std::string::npos) << msg;
    EXPECT_EQ(filesUnder(root), before); // nothing written, no temporary left
    // A quarantined variant sent again still answers as before (it takes no more room).
    EXPECT_EQ(store.storeInstance(a.study, a.series, a.sop, variant(a, 2)).result,
              StoreResult::Quarantined);

    // The byte budget: room for one more file of the other instance, not two.
    const std::uintmax_t size = a.bytes.size();
    ::setenv("FVR_QUARANTINE_MAX_BYTES", std::to_string(4 * size + size / 2).c_str(), 1);
    const Source& b = one[1];
    EXPECT_EQ(store.storeInstance(b.study, b.series, b.sop, variant(b, 1)).result,
              StoreResult::Quarantined);
    msg = refusal(b, 2);
    for (const std::string& part : {"it holds " + std::to_string(4 * size) + " bytes",
                                    "budget of " + std::to_string(4 * size + size / 2) + " bytes",
                                    std::string("FVR_QUARANTINE_MAX_BYTES")})
        EXPECT_NE(msg.find(part), std::string::npos) << msg;
    ::setenv("FVR_QUARANTINE_MAX_BYTES", "lots", 1);
    msg = refusal(b, 3);
    EXPECT_NE(msg.find("FVR_QUARANTINE_MAX_BYTES=\"lots\" is not a count"), std::string::npos)
        << msg;
    ::unsetenv("FVR_QUARANTINE_MAX_BYTES");
    ::setenv("FVR_QUARANTINE_MAX_PER_INSTANCE", "4", 1);
    EXPECT_EQ(store.storeInstance(a.study, a.series, a.sop, variant(a, 4)).result,
              StoreResult::Quarantined);
    ::unsetenv("FVR_QUARANTINE_MAX_PER_INSTANCE");
    EXPECT_EQ(store.quarantined().size(), 5u);
    for (const Source& s : one)
        EXPECT_EQ(readBytes(store.find("1.2.9")->folder / s.series.seriesUid / (s.sop + ".dcm")),
                  s.bytes);
}
