#pragma once
// What the fvr-render tests share: running the real binary with its stdout and stderr.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include <nlohmann/json.hpp>

#include "test_support.h"

namespace fvr::test {

struct RenderResult {
    int status = -1;
    std::string output; ///< stdout, then stderr
};

/** Runs FVR_RENDER_EXE with `args` (shell words); stderr goes through a file of this process's
 *  own (ctest runs test processes in parallel). */
inline RenderResult runFvrRender(const std::string& args) {
    static int calls = 0;
    const std::string err = (tmpDir() / ("fvr_render_stderr_" + std::to_string(getpid()) + "_" +
                                         std::to_string(++calls) + ".txt"))
                                .string();
    const auto c = runCommand(std::string(FVR_RENDER_EXE) + " " + args + " 2>" + err);
    std::ifstream in(err);
    RenderResult r{c.status, c.out + std::string(std::istreambuf_iterator<char>(in), {})};
    std::remove(err.c_str());
    return r;
}

/** The JSON sidecar fvr-render wrote beside `out` (out + ".json"). */
inline nlohmann::json readSidecar(const std::string& out) {
    std::ifstream in(out + ".json");
    return nlohmann::json::parse(in);
}

} // namespace fvr::test
