#pragma once
// Helpers shared by the test executables.
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace fvr::test {

/** ../shared/data as configured at build time (FVR_SHARED_DATA_DIR, overridable at run time). */
inline std::filesystem::path sharedData() {
    if (const char* env = std::getenv("FVR_SHARED_DATA_DIR")) return env;
    return FVR_SHARED_DATA_DIR;
}

/** What a shell command printed on stdout and its exit status (-1: did not exit normally). */
struct CommandOutput {
    int status = -1;
    std::string out;
};

/** Runs `cmd` through the shell (popen) and collects its stdout. */
inline CommandOutput runCommand(const std::string& cmd) {
    CommandOutput r;
    FILE* p = popen(cmd.c_str(), "r");
    if (!p) return r;
    char buf[4096];
    std::size_t n;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
    const int st = pclose(p);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return r;
}

/** A scratch folder for files written by tests. */
inline std::filesystem::path tmpDir() {
    std::filesystem::path p = FVR_TEST_TMP_DIR;
    std::filesystem::create_directories(p);
    return p;
}

} // namespace fvr::test

/** Skips the current test with a reason when a shared-data path is missing. */
#define FVR_REQUIRE_DATA(relpath)                                                                  \
    do {                                                                                           \
        if (!std::filesystem::exists(::fvr::test::sharedData() / (relpath)))                       \
            GTEST_SKIP() << "shared data not found: " << (::fvr::test::sharedData() / (relpath))   \
                         << " (tests that need ../shared/data are skipped without it)";            \
    } while (0)
