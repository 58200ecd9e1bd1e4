// fvr-render against inputs that would exhaust the machine or hang it: a tiny pixel size, a
// .nii.gz declaring gigabytes, a FIFO, voxel values that overflow float. Each run is bounded so
// that a regression fails the test instead of taking the machine: an address-space limit
// (prlimit --as) and a wall-clock guard (timeout), neither near what the fixed code needs.
#include <sys/stat.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "stored_deflate.h"
#include "test_support.h"

namespace {
namespace fs = std::filesystem;

#define EXPECT_HAS(text, part) EXPECT_NE((text).find(part), std::string::npos) << (text)

/** At most 4 GiB of address space and 120 s: what a run that needs more was killed for. */
const std::string kBounded = "timeout -s KILL 120 prlimit --as=4294967296 --";

struct Result {
    int status = -1;
    std::string output; // stdout, then stderr
};

fs::path caseDir(const std::string& name) {
    const fs::path d = fvr::test::tmpDir() / "limits_cli" / name;
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

Result run(const std::string& args, const std::string& prefix = kBounded) {
    const fs::path err = fvr::test::tmpDir() / ("limits_stderr_" + std::to_string(getpid()));
    std::string cmd = prefix;
    cmd += " '";
    cmd += FVR_RENDER_EXE;
    cmd += "' ";
    cmd += args;
    cmd += " 2>'";
    cmd += err.string();
    cmd += "'";
    const fvr::test::CommandOutput c = fvr::test::runCommand(cmd);
    std::ifstream in(err);
    Result r{c.status, c.out + std::string(std::istreambuf_iterator<char>(in), {})};
    fs::remove(err);
    return r;
}

template <class T>
void put(std::string& s, std::size_t at, T v) {
    std::memcpy(s.data() + at, &v, sizeof v);
}

/** A NIfTI-1 header (+ 4 bytes of extension flags): nx x ny x nz voxels of `datatype`. */
std::string niftiHeader(int nx, int ny, int nz, std::int16_t datatype, std::int16_t bitpix) {
    std::string h(352, '\0');
    put(h, 0, std::int32_t(348));
    put(h, 40, std::int16_t(3));
    put(h, 42, std::int16_t(nx));
    put(h, 44, std::int16_t(ny));
    put(h, 46, std::int16_t(nz));
    for (int i = 4; i < 8; ++i) put(h, 40 + 2 * i, std::int16_t(1));
    put(h, 70, datatype);
    put(h, 72, bitpix);
    for (int i = 0; i < 4; ++i) put(h, 76 + 4 * i, 1.0f);
    put(h, 108, 352.0f);
    std::memcpy(h.data() + 344, "n+1\0", 4);
    return h;
}

using fvr::test::gzipStored;

// A pixel size of 1e-6 mm once grew fvr-render to 9.2 GB in the voxel model's table.
TEST(FvrRenderLimits, TinyOrHugePixelSizesAreRefusedWithTheNumbers) {
    const fs::path dir = caseDir("pixel");
    const std::string out = (dir / "x.npy").string();
    for (const char* d : {"1e-6", "1e-300", "1e300"}) {
        SCOPED_TRACE(d);
        const Result r = run(std::string("phantom:shepp-logan:32 --pixel-size ") + d +
                             " --size 128 --voxel-model trilinear --out '" + out + "'");
        EXPECT_EQ(r.status, 2) << r.output;
        EXPECT_HAS(r.output, "fvr-render: error: pixel size ");
        EXPECT_HAS(r.output, "128-pixel image would span");
        EXPECT_HAS(r.output, "expected a pixel size from");
        EXPECT_FALSE(fs::exists(out));
    }
    const Result r = run("phantom:shepp-logan:32 --pixel-size 1e-6 --size 128 --out '" + out + "'");
    EXPECT_HAS(r.output, "pixel size 1e-06 mm: the 128-pixel image would span 0.000128 mm");
    EXPECT_EQ(run("phantom:shepp-logan:32 --pixel-size 0 --size 128 --out '" + out + "'").status,
              2);
}

// A 4 MB .nii.gz declaring 2048 x 2048 x 512 once allocated 8.2 GB before "out of memory".
TEST(FvrRenderLimits, AGzipDeclaringGigabytesIsRefusedBeforeAllocating) {
    const fs::path dir = caseDir("nifti");
    // int16: 4 GiB of data, which 4.2 MB of deflate could just hold (1032:1), 8 GiB as float.
    std::string body = niftiHeader(2048, 2048, 512, 4, 16);
    std::mt19937 rng(3);
    while (body.size() < 4200 * 1000) body += char(rng());
    const fs::path big = dir / "declares_8gb.nii.gz";
    std::ofstream(big, std::ios::binary) << gzipStored(body);
    Result r = run("--info '" + big.string() + "'");
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_HAS(r.output, big.string() + ": voxels: the header declares 2048 x 2048 x 512 voxels");
    EXPECT_HAS(r.output, "needs 8589934592 bytes (8192.0 MiB), more than the ");
    EXPECT_HAS(r.output, "of memory this process may still take");
    // The limit can be set: the message names the variable.
    r = run("--info '" + big.string() + "'", "FVR_MEMORY_LIMIT_MB=100 " + kBounded);
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_HAS(r.output, "104857600 bytes (100.0 MiB) of memory this process may still take "
                         "(FVR_MEMORY_LIMIT_MB;");
    // A small body cannot hold the declared data at all: refused as such, both sizes given.
    const fs::path small = dir / "small_body.nii.gz";
    std::ofstream(small, std::ios::binary)
        << gzipStored(niftiHeader(2048, 2048, 512, 4, 16) + std::string(1000, 'x'));
    r = run("--info '" + small.string() + "'");
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_HAS(r.output, small.string() + ": data: expected 4294967648 bytes after decompression");
    EXPECT_HAS(r.output, "cannot hold that much");
}

// A FIFO as input once hung fvr-render --info (it opened the FIFO to read the DICOM preamble).
TEST(FvrRenderLimits, AFifoIsRefusedWithoutHanging) {
    const fs::path dir = caseDir("fifo");
    for (const char* name : {"pipe.nii.gz", "pipe"}) {
        const fs::path fifo = dir / name;
        ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
        // timeout: a regression ends with status 137 instead of hanging the suite.
        const Result r = run("--info '" + fifo.string() + "'", "timeout -s KILL 60");
        EXPECT_EQ(r.status, 2) << r.output;
        EXPECT_HAS(r.output, fifo.string() + ": a FIFO (named pipe), not a regular file");
    }
}

// Float voxels of 3e38 once gave 6,561 NaN pixels of 16,384, with exit status 0.
TEST(FvrRenderLimits, ValuesThatOverflowFloatAreRefusedNotRenderedAsNaN) {
    const fs::path dir = caseDir("overflow");
    std::string file = niftiHeader(16, 16, 16, 16, 32); // float32
    for (int i = 0; i < 16 * 16 * 16; ++i) {
        const float v = 3e38f;
        file.append(reinterpret_cast<const char*>(&v), 4);
    }
    const fs::path nii = dir / "huge_values.nii";
    std::ofstream(nii, std::ios::binary) << file;
    const std::string out = (dir / "x.npy").string();
    std::string args = "'";
    args += nii.string();
    args += "' --size 128 --out '";
    args += out;
    args += "'";
    const Result r = run(args);
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_HAS(r.output, "huge_values: values too large for float: |value| up to 3e+38");
    EXPECT_HAS(r.output, "rescale the values");
    EXPECT_FALSE(fs::exists(out));
}

} // namespace
