// fvr-render batches (--sweep, --views): the writer thread and the .npy stack written as it is
// produced. Runs the real binary.
#include <sys/resource.h>
#include <sys/wait.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include <fvr/core/io/atomic_file.h>
#include <fvr/core/io/image_io.h>

#include "image_metrics.h"
#include "test_support.h"

namespace fs = std::filesystem;

namespace {

/** A fresh scratch folder for one test (the files it expects, and none other, end up there). */
fs::path scratch(const std::string& name) {
    const fs::path dir = fvr::test::tmpDir() / ("batch_" + name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

std::string readBytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

struct Result {
    int status = -1;
    std::string output; // stdout, then stderr
};

/** Runs `shellPrefix` fvr-render `args` through the shell (the prefix may set limits and
 *  `exec`). */
Result run(const std::string& args, const std::string& shellPrefix = {}) {
    static int calls = 0;
    const fs::path err = fvr::test::tmpDir() / ("batch_stderr_" + std::to_string(getpid()) + "_" +
                                                std::to_string(++calls) + ".txt");
    const fvr::test::CommandOutput c = fvr::test::runCommand(shellPrefix + " " + FVR_RENDER_EXE +
                                                             " " + args + " 2>" + err.string());
    Result r{c.status, c.out + readBytes(err)};
    fs::remove(err);
    return r;
}

/** The files in `dir`, by name. */
std::vector<std::string> filesIn(const fs::path& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    return names;
}

/** Starts fvr-render with `args` (no shell, its stderr in `log`, SIGINT, SIGTERM and SIGHUP at
 *  their default actions whatever the test runner's are); its pid, or -1. */
pid_t start(const std::vector<std::string>& args, const fs::path& log) {
    std::vector<std::string> copy = args;
    std::string exe = FVR_RENDER_EXE;
    std::vector<char*> argv{exe.data()};
    for (std::string& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t pid = fork();
    if (pid == 0) {
        if (std::freopen(log.c_str(), "w", stderr) == nullptr) _exit(126);
        std::signal(SIGINT, SIG_DFL);
        std::signal(SIGTERM, SIG_DFL);
        std::signal(SIGHUP, SIG_DFL);
        execv(argv[0], argv.data());
        _exit(127);
    }
    return pid;
}

/** Runs fvr-render with `args` (its stderr in `log`) and returns its peak resident memory in KB,
 *  or -1 where it did not exit with 0. */
long maxRssKb(const std::vector<std::string>& args, const fs::path& log) {
    const pid_t pid = start(args, log);
    int status = 0;
    rusage usage{};
    if (pid < 0 || wait4(pid, &status, 0, &usage) != pid) return -1;
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1;
    return usage.ru_maxrss;
}

/** The paths under `dir` (recursively) that hold ".part": temporaries, staged files. */
std::vector<std::string> partsIn(const fs::path& dir) {
    std::vector<std::string> parts;
    std::error_code ec;
    for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string rel = it->path().lexically_relative(dir);
        if (rel.find(".part") != std::string::npos) parts.push_back(rel);
    }
    return parts;
}

/** Polls until `ready()` (true) or until the process `pid` ends (false, its status in
 *  `status`). */
template <class Ready>
bool waitUntil(pid_t pid, int& status, Ready ready) {
    while (!ready()) {
        if (waitpid(pid, &status, WNOHANG) == pid) return false;
        usleep(500);
    }
    return true;
}

const std::string kPhantom = "phantom:shepp-logan:40 --backend cpu --kernel catmull-rom "
                             "--values mu --size 128 ";

} // namespace

TEST(FvrRenderBatch, StackedSweepEqualsTheViewsWrittenOneByOneBitForBit) {
    const fs::path dir = scratch("bitwise");
    for (const std::string extra : {"", "--beer-lambert "}) {
        const std::string common = kPhantom + extra + "--sweep 7 --axis 0.2,1,0.1 ";
        Result r = run(common + "--out " + (dir / "stack.npy").string());
        ASSERT_EQ(r.status, 0) << r.output;
        r = run(common + "--numbered --out " + (dir / "one.npy").string());
        ASSERT_EQ(r.status, 0) << r.output;
        std::vector<std::int64_t> shape;
        const std::vector<float> stack = fvr::core::readNpy(dir / "stack.npy", shape);
        ASSERT_EQ(shape, (std::vector<std::int64_t>{7, 128, 128})) << extra;
        for (int i = 0; i < 7; ++i) {
            const fs::path one = dir / ("one_000" + std::to_string(i) + ".npy");
            const std::vector<float> view = fvr::core::readNpy(one, shape);
            ASSERT_EQ(shape, (std::vector<std::int64_t>{128, 128})) << one;
            // Bit for bit, in order: view i of the stack is the file of view i.
            EXPECT_EQ(std::memcmp(view.data(), stack.data() + std::size_t(i) * 128 * 128,
                                  view.size() * sizeof(float)),
                      0)
                << extra << "view " << i;
        }
        // The views differ (a sweep that wrote one view 7 times would pass the loop above).
        EXPECT_NE(std::memcmp(stack.data(), stack.data() + 128 * 128, 128 * 128 * sizeof(float)),
                  0);
    }
    for (const std::string& name : filesIn(dir))
        EXPECT_EQ(name.find(".part"), std::string::npos) << name;
}

TEST(FvrRenderBatch, StackHeaderAndSizeAreTheNpyFormats) {
    const fs::path dir = scratch("header");
    const fs::path out = dir / "s.npy";
    const Result r = run(kPhantom + "--sweep 5 --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.output;
    const std::string bytes = readBytes(out);
    ASSERT_GE(bytes.size(), 10u);
    // NumPy format 1.0: magic, version, little-endian header length, header padded with spaces
    // and ended by '\n' so that the data starts on a 64-byte boundary.
    EXPECT_EQ(bytes.substr(0, 8), std::string("\x93NUMPY\x01\x00", 8));
    const std::size_t hlen = std::uint8_t(bytes[8]) | (std::size_t(std::uint8_t(bytes[9])) << 8);
    EXPECT_EQ((10 + hlen) % 64, 0u) << hlen;
    ASSERT_GE(bytes.size(), 10 + hlen);
    const std::string header = bytes.substr(10, hlen);
    EXPECT_EQ(header.back(), '\n');
    EXPECT_NE(header.find("'descr': '<f4'"), std::string::npos) << header;
    EXPECT_NE(header.find("'fortran_order': False"), std::string::npos) << header;
    EXPECT_NE(header.find("'shape': (5, 128, 128)"), std::string::npos) << header;
    EXPECT_EQ(bytes.size(), 10 + hlen + 5u * 128 * 128 * sizeof(float));
    EXPECT_EQ(filesIn(dir), (std::vector<std::string>{"s.npy", "s.npy.json"}));
}

TEST(FvrRenderBatch, StackIsWrittenAsItIsProducedNotHeldInMemory) {
    // 1500 views of 128 x 128 floats: a 98 MB stack. Held in memory (and copied to be written),
    // the peak would pass it; streamed, the process holds a few views.
    const fs::path dir = scratch("memory");
    const std::size_t stackKb = 1500u * 128 * 128 * sizeof(float) / 1024;
    const fs::path log = fvr::test::tmpDir() / "batch_memory.log";
    const long rss = maxRssKb({"phantom:shepp-logan:16", "--backend", "cpu", "--size", "128",
                               "--sweep", "1500", "--out", (dir / "big.npy").string()},
                              log);
    ASSERT_GT(rss, 0) << "fvr-render failed: " << readBytes(log);
    fs::remove(log);
    EXPECT_LT(std::size_t(rss), stackKb / 2) << "peak " << rss << " KB, stack " << stackKb << " KB";
    EXPECT_EQ(fs::file_size(dir / "big.npy"), 128u + stackKb * 1024);
    fs::remove_all(dir); // 98 MB
}

TEST(FvrRenderBatch, OutputUnderARegularFileFailsAtOnceNamingIt) {
    const fs::path dir = scratch("notdir");
    { std::ofstream(dir / "plain") << "a file, not a folder\n"; }
    for (const std::string name : {"s.npy", "v.png"}) {
        const std::string out = (dir / "plain" / name).string();
        const Result r = run(kPhantom + "--sweep 40 --out " + out);
        EXPECT_EQ(r.status, 1) << r.output;
        // The output's name (FILE, for the stack or the numbered views) and the reason.
        EXPECT_NE(r.output.find(out + ": "), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(std::strerror(ENOTDIR)), std::string::npos) << r.output;
        // Stopped before rendering the whole sweep.
        EXPECT_EQ(r.output.find("view 40/40"), std::string::npos) << r.output;
        EXPECT_EQ(r.output.find("terminate"), std::string::npos) << r.output;
    }
    EXPECT_EQ(filesIn(dir), (std::vector<std::string>{"plain"}));
}

TEST(FvrRenderBatch, WriteErrorMidStackStopsTheRunAndLeavesNoFile) {
    // A file size limit makes write() fail part way through the stack (EFBIG, as a full disk
    // gives ENOSPC), with SIGXFSZ ignored (the disposition outlives exec). 1024 blocks of 512 or
    // 1024 bytes: 8 or 16 of the 64 views of 64 KB.
    const fs::path dir = scratch("efbig");
    const std::string out = (dir / "big.npy").string();
    const Result r =
        run(kPhantom + "--sweep 64 --out " + out, "trap '' XFSZ; ulimit -f 1024; exec");
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find(out + ": write failed: " + std::strerror(EFBIG)), std::string::npos)
        << r.output;
    EXPECT_EQ(r.output.find("view 64/64"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("terminate"), std::string::npos) << r.output;
    EXPECT_EQ(filesIn(dir), std::vector<std::string>{}); // neither big.npy nor big.npy.part
}

TEST(FvrRenderBatch, InterruptedRunRemovesItsStackAndDiesOfTheSignal) {
    for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
        const fs::path dir = scratch("interrupt" + std::to_string(sig));
        const fs::path out = dir / "s.npy";
        const fs::path log = fvr::test::tmpDir() / "batch_interrupt.log";
        const pid_t pid = start({"phantom:shepp-logan:16", "--backend", "cpu", "--size", "128",
                                 "--sweep", "3000", "--out", out.string()},
                                log);
        ASSERT_GT(pid, 0);
        // The stack's temporary file appears when the rendering starts: the signal comes then.
        int status = 0;
        ASSERT_TRUE(waitUntil(pid, status, [&] { return !partsIn(dir).empty(); }))
            << "fvr-render ended before its stack file appeared:\n"
            << readBytes(log);
        kill(pid, sig);
        ASSERT_EQ(waitpid(pid, &status, 0), pid);
        const std::string err = readBytes(log);
        // Dies of the signal (a shell or make stops), after removing what it had written.
        EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << status << "\n" << err;
        EXPECT_NE(err.find("interrupted after view "), std::string::npos) << err;
        EXPECT_NE(err.find(out.string() + " not written"), std::string::npos) << err;
        EXPECT_EQ(filesIn(dir), std::vector<std::string>{}); // neither s.npy nor s.npy.part
        fs::remove(log);
    }
}

TEST(FvrRenderBatch, DefaultSweepIsAGantryRotationFromAP) {
    // The default view looks along the slices, the head-feet axis a sweep turns about: the views
    // would all be one projection spun in the image plane. The sweep starts from AP instead.
    const fs::path dir = scratch("gantry");
    const std::string common = "phantom:shepp-logan:32 --size 128 --values mu ";
    Result r = run(common + "--sweep 4 --out " + (dir / "s.npy").string());
    ASSERT_EQ(r.status, 0) << r.output;
    r = run(common + "--view AP --out " + (dir / "ap.npy").string());
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::int64_t> shape;
    const auto stack = fvr::core::readNpy(dir / "s.npy", shape);
    ASSERT_EQ(shape, (std::vector<std::int64_t>{4, 128, 128}));
    const auto ap = fvr::core::readNpy(dir / "ap.npy", shape);
    const std::size_t n = 128 * 128;
    const std::vector<float> view0(stack.begin(), stack.begin() + n);
    const std::vector<float> view1(stack.begin() + n, stack.begin() + 2 * n);
    EXPECT_GT(fvr::test::compare(view0, ap).psnr, 100.0); // view 0 is AP
    // View 1 is the lateral view (90 degrees on): a different projection, not AP turned.
    EXPECT_LT(fvr::test::compare(view1, ap).psnr, 30.0);

    // A view of the user's own along the axis is refused, naming the problem.
    r = run(common + "--sweep 4 --view HEAD --out " + (dir / "h.npy").string());
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_NE(r.output.find("--sweep: the view looks along the rotation axis"), std::string::npos)
        << r.output;
    EXPECT_FALSE(fs::exists(dir / "h.npy"));
}

namespace {

/** Every file under `dir` (hidden ones and subfolders' too), by path, with its bytes. */
std::map<std::string, std::string> snapshot(const fs::path& dir) {
    std::map<std::string, std::string> files;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        files[e.path().lexically_relative(dir)] = e.is_regular_file() ? readBytes(e.path()) : "/";
    return files;
}

/** A pid that no process has: a child that has exited and been reaped. */
pid_t deadPid() {
    const pid_t pid = fork();
    if (pid == 0) _exit(0);
    int status = 0;
    waitpid(pid, &status, 0);
    return pid;
}

/** The paths whose bytes differ between two snapshots (or that one of them lacks), for a
 *  message shorter than the files. */
std::string differences(const std::map<std::string, std::string>& a,
                        const std::map<std::string, std::string>& b) {
    std::string text;
    for (const auto& [path, bytes] : a)
        if (!b.count(path) || b.at(path) != bytes) text += " " + path;
    for (const auto& [path, bytes] : b)
        if (!a.count(path)) text += " +" + path;
    return text;
}

} // namespace

TEST(FvrRenderBatch, InterruptedSweepLeavesTheEarlierRunWhole) {
    // A numbered sweep (and a stack) over an earlier run's files, interrupted once its first new
    // views are written: all or nothing, so the folder holds the earlier run as it was, every
    // frame and the sidecar that describes them, and no temporary.
    for (const std::string name : {"v.png", "s.npy"}) {
        for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
            const fs::path dir = scratch("mix" + std::to_string(sig) + name);
            const fs::path out = dir / name;
            const std::string numbered = name == "s.npy" ? "--numbered " : "";
            Result r = run(kPhantom + numbered + "--sweep 8 --out " + out.string());
            ASSERT_EQ(r.status, 0) << r.output;
            const auto before = snapshot(dir);
            ASSERT_EQ(before.size(), 9u); // 8 frames and the sidecar
            const fs::path log = fvr::test::tmpDir() / "batch_mix.log";
            // Other settings (another kernel): every new frame differs from the earlier one.
            const fs::path third = dir / (name == "s.npy" ? "s_0002.npy" : "v_0002.png");
            std::vector<std::string> args{"phantom:shepp-logan:40",
                                          "--backend",
                                          "cpu",
                                          "--size",
                                          "128",
                                          "--kernel",
                                          "bspline",
                                          "--values",
                                          "mu",
                                          "--sweep",
                                          "3000",
                                          "--out",
                                          out.string()};
            if (!numbered.empty()) args.push_back("--numbered");
            const pid_t pid = start(args, log);
            ASSERT_GT(pid, 0);
            // The signal comes once the third new view is written (staged, or, before this
            // rule, under its final name).
            int status = 0;
            ASSERT_TRUE(waitUntil(pid, status, [&] {
                for (const auto& p : partsIn(dir))
                    if (p.find(third.filename().string()) != std::string::npos) return true;
                return fs::exists(third) && readBytes(third) != before.at(third.filename());
            })) << readBytes(log);
            kill(pid, sig);
            ASSERT_EQ(waitpid(pid, &status, 0), pid);
            const std::string err = readBytes(log);
            EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << status << "\n" << err;
            EXPECT_EQ(differences(before, snapshot(dir)), "") << name << " signal " << sig << "\n"
                                                              << err.substr(0, 2000);
            EXPECT_NE(err.find(out.string() + " not written"), std::string::npos) << err;
            fs::remove(log);
        }
    }
}

TEST(FvrRenderBatch, ShorterSweepRemovesTheEarlierRunsFrames) {
    // The sidecar describes the folder: a 3-view sweep after a 6-view one leaves no view 3..5.
    const fs::path dir = scratch("shorter");
    const fs::path out = dir / "v.png";
    Result r = run(kPhantom + "--sweep 6 --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.output;
    { std::ofstream(dir / "v_0009.png") << "not listed in the sidecar: not fvr-render's\n"; }
    r = run(kPhantom + "--sweep 3 --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(filesIn(dir), (std::vector<std::string>{"v.png.json", "v_0000.png", "v_0001.png",
                                                      "v_0002.png", "v_0009.png"}));
}

TEST(FvrRenderBatch, SidecarThatDoesNotFitLeavesNoImage) {
    // A file size limit between a frame (4 KB) and the sidecar of 200 views (38 KB): every frame
    // is written, the sidecar fails (EFBIG, as a full disk gives ENOSPC). The frames must not
    // land without it: the folder keeps the earlier run, frames and sidecar, as it was.
    const fs::path dir = scratch("sidecarfull");
    const fs::path out = dir / "v.png";
    const std::string phantom = "phantom:shepp-logan:16 --backend cpu --size 128 ";
    Result r = run(phantom + "--sweep 2 --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto before = snapshot(dir);
    ASSERT_LT(fs::file_size(dir / "v_0000.png"), 8u * 1024);
    // 24 blocks of 512 or 1024 bytes (the shell's ulimit unit): 12 or 24 KB.
    r = run(phantom + "--kernel bspline --sweep 200 --out " + out.string(),
            "trap '' XFSZ; ulimit -f 24; exec");
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find(out.string() + ".json: write failed: " + std::strerror(EFBIG)),
              std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("view 200/200"), std::string::npos) << r.output; // frames written
    EXPECT_EQ(differences(before, snapshot(dir)), "");
}

TEST(FvrRenderBatch, KilledRunsLeftoversAreRemovedByTheNextRun) {
    // kill -9 mid-stack leaves its temporary (nothing can remove it then); the next run into the
    // same folder removes it, and the leftovers of other dead writers, but never a live writer's
    // file.
    const fs::path dir = scratch("killed");
    const fs::path out = dir / "s.npy";
    const fs::path log = fvr::test::tmpDir() / "batch_killed.log";
    const pid_t pid = start({"phantom:shepp-logan:16", "--backend", "cpu", "--size", "128",
                             "--sweep", "3000", "--out", out.string()},
                            log);
    ASSERT_GT(pid, 0);
    int status = 0;
    ASSERT_TRUE(waitUntil(pid, status, [&] { return !partsIn(dir).empty(); })) << readBytes(log);
    kill(pid, SIGKILL);
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_FALSE(partsIn(dir).empty()); // the killed run's temporary
    // Other leftovers: a dead writer's temporary folder, the older form FILE.json.part untouched
    // for two minutes and open nowhere; a live writer's (this process's) temporary, and an
    // older-form FILE.part held open here, which must stay.
    const std::string dead = ".t.npy." + std::to_string(deadPid()) + ".3.part";
    const std::string live = ".t.npy." + std::to_string(getpid()) + ".3.part";
    fs::create_directory(dir / dead);
    { std::ofstream(dir / dead / "t.npy") << "a dead run's staged file\n"; }
    { std::ofstream(dir / live) << "a live writer's file\n"; }
    { std::ofstream(dir / "s.npy.json.part") << "an older form, its writer gone\n"; }
    std::ofstream held(dir / "s.npy.part");
    held << "an older form, open in a live process\n" << std::flush;
    const auto twoMinutesAgo = fs::file_time_type::clock::now() - std::chrono::minutes(2);
    fs::last_write_time(dir / "s.npy.json.part", twoMinutesAgo);
    fs::last_write_time(dir / "s.npy.part", twoMinutesAgo);
    const Result r = run(kPhantom + "--sweep 2 --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("left by a run that died"), std::string::npos) << r.output;
    EXPECT_EQ(filesIn(dir), (std::vector<std::string>{live, "s.npy", "s.npy.json", "s.npy.part"}))
        << r.output;
    fs::remove(log);
}

TEST(FvrRenderBatch, TheNextRunRemovesOnlyItsHostsOutputTemporaries) {
    // A folder shared by hosts or containers (a dataset run's workers on several machines, NFS):
    // a temporary of another pid space names a pid that means nothing here, so it stays even
    // when that pid is gone here; one of this host with a dead pid goes. And a hidden folder of
    // the user's whose name looks like a temporary but is no output's (`.mydir.N.N.part`) stays
    // with its contents: the next run removes staging folders of outputs only.
    const fs::path dir = scratch("hosts");
    const std::string pid = std::to_string(deadPid()), ours = fvr::core::writerIdentity();
    const std::string other = ours == "00000000" ? "00000001" : "00000000";
    const std::string foreignFile = ".t.npy." + pid + "-" + other + ".3.part";
    const std::string foreignFolder = ".b.png." + pid + "-" + other + ".4.part";
    const std::string oursFolder = ".b.png." + pid + "-" + ours + ".5.part";
    const std::string userFolder = ".mydir." + pid + ".1.part";
    const std::string userFolderOurs = ".mydir." + pid + "-" + ours + ".2.part";
    { std::ofstream(dir / foreignFile) << "another host's write in progress\n"; }
    for (const std::string& d : {foreignFolder, oursFolder, userFolder, userFolderOurs}) {
        fs::create_directory(dir / d);
        std::ofstream(dir / d / "precious") << d << "\n";
    }
    const Result r = run(kPhantom + "--out " + (dir / "b.png").string());
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::string> kept{foreignFile,    foreignFolder, userFolder,
                                  userFolderOurs, "b.png",       "b.png.json"};
    std::sort(kept.begin(), kept.end());
    EXPECT_EQ(filesIn(dir), kept) << r.output;
    for (const std::string& d : {foreignFolder, userFolder, userFolderOurs})
        EXPECT_EQ(readBytes(dir / d / "precious"), d + "\n");
    EXPECT_NE(r.output.find("removed " + (dir / oursFolder).string()), std::string::npos)
        << r.output;
}

TEST(FvrRenderBatch, ARunBesideALiveOneLeavesItsFilesAlone) {
    // The next run into a folder removes the temporaries of dead runs only: a sweep still being
    // written there (its staging folder present) completes whole.
    const fs::path dir = scratch("beside");
    const fs::path log = fvr::test::tmpDir() / "batch_beside.log";
    const pid_t pid = start({"phantom:shepp-logan:16", "--backend", "cpu", "--size", "128",
                             "--sweep", "300", "--out", (dir / "a.png").string()},
                            log);
    ASSERT_GT(pid, 0);
    int status = 0;
    ASSERT_TRUE(waitUntil(pid, status, [&] { return !partsIn(dir).empty(); })) << readBytes(log);
    kill(pid, SIGSTOP); // held mid-sweep while the other run cleans the folder
    const Result r = run(kPhantom + "--out " + (dir / "b.npy").string());
    kill(pid, SIGCONT);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(r.output.find("left by a run that died"), std::string::npos) << r.output;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << readBytes(log);
    EXPECT_EQ(filesIn(dir).size(), 300u + 3u); // its frames and sidecar, b.npy and its sidecar
    EXPECT_EQ(partsIn(dir), std::vector<std::string>{});
    fs::remove(log);
}

TEST(FvrRenderBatch, InterruptedPolychromaticSweepLeavesNothing) {
    // --kvp runs its own loop: the same rule (SIGTERM here), all or nothing.
    const fs::path dir = scratch("polyint");
    const fs::path out = dir / "p.npy";
    const fs::path log = fvr::test::tmpDir() / "batch_polyint.log";
    const pid_t pid = start({"phantom:shepp-logan:16", "--backend", "cpu", "--size", "128", "--kvp",
                             "80", "--sweep", "3000", "--out", out.string()},
                            log);
    ASSERT_GT(pid, 0);
    int status = 0;
    ASSERT_TRUE(waitUntil(pid, status, [&] { return !partsIn(dir).empty(); })) << readBytes(log);
    kill(pid, SIGTERM);
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    const std::string err = readBytes(log);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << status << "\n" << err;
    EXPECT_NE(err.find(out.string() + " not written"), std::string::npos) << err;
    EXPECT_EQ(filesIn(dir), std::vector<std::string>{});
    fs::remove(log);
}

TEST(FvrRenderBatch, ImageWithoutRoomForItsSidecarIsNotLeft) {
    // One view of an empty volume: a PNG of 95 bytes, a sidecar of over 1 KB. With a file size
    // limit between the two, the sidecar cannot be written: the image must not stay alone under
    // its final name (it did, with exit status 1).
    const fs::path dir = scratch("single");
    { std::ofstream(dir / "zero.raw", std::ios::binary) << std::string(16 * 16 * 16 * 2, '\0'); }
    fs::create_directory(dir / "out");
    const fs::path out = dir / "out" / "v.png";
    const std::string args = (dir / "zero.raw").string() +
                             " --raw-dims 16,16,16 --size 128 --backend cpu --out " + out.string();
    // 1 block of 512 or 1024 bytes (the shell's ulimit unit).
    Result r = run(args, "trap '' XFSZ; ulimit -f 1; exec");
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find(out.string() + ".json: write failed: " + std::strerror(EFBIG)),
              std::string::npos)
        << r.output;
    EXPECT_EQ(filesIn(dir / "out"), std::vector<std::string>{});
    // Without the limit the same run writes both (the image is indeed the smaller file).
    r = run(args);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_LT(fs::file_size(out), 512u);
    EXPECT_GT(fs::file_size(out.string() + ".json"), 1024u);
}

TEST(FvrRenderBatch, SendFoldersOfDeadRunsAreRemoved) {
    // --send of PNG views writes Secondary Captures into a temporary folder of its own; a run
    // killed while sending leaves it. The next send removes those of dead runs, not a live
    // one's, and its own when it ends (here the PACS does not answer: the send fails).
    const fs::path dir = scratch("sendtmp");
    const fs::path tmp = dir / "tmp";
    const std::string dead = ".fvr-render-send." + std::to_string(deadPid()) + ".0.part";
    const std::string live = ".fvr-render-send." + std::to_string(getpid()) + ".0.part";
    fs::create_directories(tmp / dead);
    { std::ofstream(tmp / dead / "view_0.dcm") << "a dead run's view\n"; }
    fs::create_directories(tmp / live);
    const Result r = run(kPhantom + "--sweep 2 --out " + (dir / "v.png").string() +
                             " --send dicom://NOBODY@127.0.0.1:9",
                         "TMPDIR=" + tmp.string() + " exec");
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_EQ(filesIn(tmp), std::vector<std::string>{live}) << r.output;
    EXPECT_EQ(filesIn(dir),
              (std::vector<std::string>{"tmp", "v.png.json", "v_0000.png", "v_0001.png"}));
}
