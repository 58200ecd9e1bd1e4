// fvr-render batches (--sweep, --views): the writer thread and the .npy stack written as it is
// produced. Runs the real binary.
#include <sys/resource.h>
#include <sys/wait.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

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

/** Starts fvr-render with `args` (no shell, its stderr in `log`, SIGINT and SIGTERM at their
 *  default actions whatever the test runner's are); its pid, or -1. */
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
        // The file (the stack, or the first numbered view) and the reason.
        const std::string named = name == "s.npy" ? out : (dir / "plain" / "v_0000.png").string();
        EXPECT_NE(r.output.find(named), std::string::npos) << r.output;
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
    for (const int sig : {SIGINT, SIGTERM}) {
        const fs::path dir = scratch("interrupt" + std::to_string(sig));
        const fs::path out = dir / "s.npy";
        const fs::path log = fvr::test::tmpDir() / "batch_interrupt.log";
        const pid_t pid = start({"phantom:shepp-logan:16", "--backend", "cpu", "--size", "128",
                                 "--sweep", "3000", "--out", out.string()},
                                log);
        ASSERT_GT(pid, 0);
        // The stack's temporary file appears when the rendering starts: the signal comes then.
        int status = 0;
        bool ended = false;
        const auto writing = [&] { // s.npy's temporary file (.s.npy.<pid>.<n>.part)
            for (const auto& f : fs::directory_iterator(dir))
                if (f.path().extension() == ".part") return true;
            return false;
        };
        while (!ended && !writing()) {
            ended = waitpid(pid, &status, WNOHANG) == pid;
            usleep(500);
        }
        ASSERT_FALSE(ended) << "fvr-render ended before its stack file appeared:\n"
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
