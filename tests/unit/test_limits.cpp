// Resource limits checked before the work: the image against the volume (pixel size, size, field
// of view) and the voxel model's table; declared sizes against the memory this process may take;
// non-regular files refused without being opened; values whose spectrum overflows float; NUL
// characters in paths. None of these tests allocates more than a few tens of MB, whatever the
// code does (the large cases run fvr-render under an address-space limit: tests/cli).
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/io/open_study.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/memory_budget.h>
#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/slice_params.h>
#include <fvr/core/render/view.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/phantom.h>

#include "stored_deflate.h"
#include "test_support.h"

namespace {
namespace fs = std::filesystem;
using namespace fvr::core;
using fvr::test::tmpDir;

#define EXPECT_HAS(text, part) EXPECT_NE((text).find(part), std::string::npos) << (text)

fs::path caseDir(const std::string& name) {
    const fs::path d = tmpDir() / "limits" / name;
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

/** Sets an environment variable for one scope (the memory limit). */
class ScopedEnv {
public:
    ScopedEnv(const char* name, const std::string& value) : m_name(name) {
        if (const char* old = std::getenv(name)) m_old = old;
        setenv(name, value.c_str(), 1);
    }
    ~ScopedEnv() {
        if (m_old.empty())
            unsetenv(m_name);
        else
            setenv(m_name, m_old.c_str(), 1);
    }

private:
    const char* m_name;
    std::string m_old;
};

template <class E, class F>
std::string messageOf(F f) {
    try {
        f();
    } catch (const E& e) {
        return e.what();
    }
    ADD_FAILURE() << "no exception";
    return {};
}

// ------------------------------------------------------------------------------------------------
// Pixel size, image size and field of view against the volume

TEST(Limits, PixelSizeIsCheckedAgainstTheVolumeWithTheNumbers) {
    const Dims3 dims{32, 32, 32};
    const Vec3 spacing{1, 1, 1};
    const double diagonal = std::sqrt(3.0) * 32.0; // 55.4 mm
    // The default pixel size (the diagonal over M) and factors within 64 of it pass.
    for (const int M : {16, 128, 4096}) {
        EXPECT_NO_THROW(validateImageGeometry({M, diagonal / M}, dims, spacing)) << M;
        EXPECT_NO_THROW(validateImageGeometry({M, diagonal / M * 60.0}, dims, spacing)) << M;
    }
    EXPECT_NO_THROW(validateImageGeometry({128, diagonal / 128 / 60.0}, dims, spacing));
    // The pixel sizes: the message gives the pixel size, the span and the volume's.
    std::string m = messageOf<SettingsError>([&] {
        validateImageGeometry({128, 1e-6}, dims, spacing);
    });
    EXPECT_HAS(m, "pixel size 1e-06 mm");
    EXPECT_HAS(m, "128-pixel image would span 0.000128 mm");
    EXPECT_HAS(m, "diagonal is 55.4256 mm");
    EXPECT_HAS(m, "from 0.00676582 to 27.7128 mm");
    for (const double d : {1e-300, 1e300, 27.8, 0.0067})
        EXPECT_THROW(validateImageGeometry({128, d}, dims, spacing), SettingsError) << d;
    for (const double d : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()})
        EXPECT_THROW(validateImageGeometry({128, d}, dims, spacing), SettingsError) << d;
    // A small volume in a large image: the voxel model's frequency bound is the finer one.
    const PixelSizeRange r = pixelSizeRange({2, 2, 2}, {1, 1, 1}, 4096);
    EXPECT_NEAR(r.min, (2048.0 + 1.0) / 4096.0 * std::sqrt(2.0) / 2048.0, 1e-12);
    m = messageOf<SettingsError>([&] {
        validateImageGeometry({4096, r.min / 2}, {2, 2, 2}, {1, 1, 1});
    });
    EXPECT_HAS(m, "largest voxel spacing, 1 mm");
}

TEST(Limits, EveryImageWithinTheRangeKeepsTheTransferTableSmall) {
    // The table reaches the slice's highest frequency; at the finest pixel size allowed, for
    // any view, that is within the cap.
    const Dims3 dims{3, 5, 40};
    const Vec3 spacing{0.7, 2.5, 0.3};
    Volume v;
    v.dims = dims;
    v.spacing = spacing;
    v.voxels.assign(600, 1.0f);
    auto s = preprocess(v, PreprocessOptions{});
    for (const int M : {16, 512, 4096}) {
        RenderParams p;
        p.image = {M, pixelSizeRange(dims, spacing, M).min};
        for (const Vec3 dir : {Vec3{1, 0, 0}, Vec3{0, 1, 1}, Vec3{1, 1, 1}, Vec3{0.2, 0.9, 0.1}}) {
            p.view = ViewFrame::fromDirUp(dir, {0.3, -0.5, 0.8});
            const SliceParams sp = sliceParams(*s, p);
            EXPECT_LE(sp.maxCyclesPerVoxel, TransferTable::kMaxCyclesPerVoxel) << M;
        }
    }
}

TEST(Limits, TransferTableRefusesToGrowBeyondItsCap) {
    TransferTable t(VoxelModel::Trilinear);
    EXPECT_NO_THROW(t.cover(TransferTable::kMaxCyclesPerVoxel));
    // Beyond the cap (3000 cycles per voxel would be 24 MB of tables, 1e6 as asked by a pixel
    // of 1e-6 mm 8 GB): refused before allocating, naming the frequency.
    const std::string m = messageOf<SettingsError>([&] { t.cover(3000.0); });
    EXPECT_HAS(m, "3000 cycles per voxel");
    EXPECT_HAS(m, "2048");
    EXPECT_THROW(t.cover(std::numeric_limits<double>::infinity()), SettingsError);
    EXPECT_THROW(t.cover(std::nan("")), SettingsError);
    // The table still answers after the refusals.
    EXPECT_NEAR(t.value(0.5), voxelModelTransfer(VoxelModel::Trilinear, 0.5), 1e-6);
}

TEST(Limits, RendererRefusesAPixelSizeTheVolumeCannotFill) {
    const Volume v = makeSheppLoganVolume(32);
    CpuFourierRenderer r(preprocess(v, PreprocessOptions{}), 1);
    RenderParams p;
    p.voxelModel = VoxelModel::Trilinear;
    // 1e-3 mm would have asked for 1,400 cycles per voxel x 8 bytes x 1024: 11 MB; still far
    // outside what the image can show of the volume.
    p.image = {128, 1e-3};
    const std::string m = messageOf<SettingsError>([&] { r.render(p); });
    EXPECT_HAS(m, "pixel size 0.001 mm");
    p.image = {128, defaultPixelSize(v.dims, v.spacing, 128)};
    EXPECT_NO_THROW(r.render(p));
}

// ------------------------------------------------------------------------------------------------
// Declared sizes against the memory

TEST(Limits, MemoryBudgetComesFromTheMachineOrTheVariable) {
    unsetenv(kMemoryLimitVariable);
    const MemoryBudget b = memoryBudget();
    EXPECT_GT(b.bytes, 0u);
    EXPECT_FALSE(b.limitedBy.empty());
    {
        const ScopedEnv env(kMemoryLimitVariable, "12.5");
        EXPECT_EQ(memoryBudget().bytes, std::uint64_t(12.5 * 1024 * 1024));
        EXPECT_EQ(memoryBudget().limitedBy, "FVR_MEMORY_LIMIT_MB");
        const std::string m = messageOf<LoadError>(
            [] { checkMemoryFor(std::uint64_t(20) << 20, "file.nii", "voxels"); });
        EXPECT_HAS(m, "file.nii: voxels needs 20971520 bytes (20.0 MiB)");
        EXPECT_HAS(m, "13107200 bytes (12.5 MiB)");
        EXPECT_HAS(m, "FVR_MEMORY_LIMIT_MB");
        EXPECT_NO_THROW(checkMemoryFor(std::uint64_t(12) << 20, "file.nii", "voxels"));
    }
    for (const char* bad : {"0", "-5", "lots", "nan", "12MB"}) {
        const ScopedEnv env(kMemoryLimitVariable, bad);
        EXPECT_THROW(memoryBudget(), SettingsError) << bad;
    }
}

/** A NIfTI-1 header (348 bytes + 4 of extension flags) declaring nx x ny x nz int16 voxels. */
std::string niftiHeader(int nx, int ny, int nz) {
    std::string h(352, '\0');
    const auto put = [&h](std::size_t at, auto v) { std::memcpy(h.data() + at, &v, sizeof v); };
    put(0, std::int32_t(348));
    put(40, std::int16_t(3));
    put(42, std::int16_t(nx));
    put(44, std::int16_t(ny));
    put(46, std::int16_t(nz));
    for (int i = 4; i < 8; ++i) put(40 + 2 * i, std::int16_t(1));
    put(70, std::int16_t(4)); // int16
    put(72, std::int16_t(16));
    for (int i = 0; i < 4; ++i) put(76 + 4 * i, 1.0f);
    put(108, 352.0f);
    std::memcpy(h.data() + 344, "n+1\0", 4);
    return h;
}

using fvr::test::gzipStored;

TEST(Limits, DeclaredVoxelsAreCheckedAgainstTheMemoryBeforeAllocating) {
    // 256^3 int16 voxels (32 MiB of data, 64 MiB as float) declared by a 40 KiB gzip file: the
    // deflate bound lets that much in (40 KiB x 1032 > 32 MiB), the memory limit (16 MiB) not.
    const fs::path dir = caseDir("memory");
    const fs::path file = dir / "big.nii.gz";
    std::string body = niftiHeader(256, 256, 256);
    std::mt19937 rng(7);
    while (body.size() < 40 * 1024) body += char(rng());
    std::ofstream(file, std::ios::binary) << gzipStored(body);
    const ScopedEnv env(kMemoryLimitVariable, "16");
    const std::string m = messageOf<LoadError>([&] { loadVolume(file); });
    EXPECT_HAS(m, file.string() + ": voxels: the header declares 256 x 256 x 256 voxels");
    EXPECT_HAS(m, "needs 67108864 bytes (64.0 MiB)");
    EXPECT_HAS(m, "16777216 bytes (16.0 MiB)");
    // Raw input declares its size on the command line: the same check.
    const fs::path raw = dir / "big.raw";
    std::ofstream(raw, std::ios::binary) << std::string(std::size_t(256) * 256 * 128 * 2, '\0');
    RawSpec spec;
    spec.dims = {256, 256, 128};
    const std::string r = messageOf<LoadError>([&] { loadRaw(raw, spec); });
    EXPECT_HAS(r, "needs 33554432 bytes");
}

TEST(Limits, DicomSeriesAndPhantomsAreCheckedAgainstTheMemory) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const ScopedEnv env(kMemoryLimitVariable, "1");
    // 64 x 64 x 93 float voxels: 1.5 MB.
    const std::string m = messageOf<DicomError>([] {
        openStudy(
            classifyInput((fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93").string()));
    });
    EXPECT_HAS(m, "380928 voxels as float needs 1523712 bytes");
    EXPECT_HAS(m, "FVR_MEMORY_LIMIT_MB");
    EXPECT_THROW(makeSheppLoganVolume(128), LoadError);
}

TEST(Limits, TheSpectrumIsCheckedAgainstTheMemoryBeforeAllocating) {
    Volume v;
    v.dims = {32, 32, 32};
    v.name = "cube";
    v.voxels.assign(32 * 32 * 32, 1.0f);
    const PreprocessOptions options;
    const std::size_t bytes = spectrumBytes(paddedDimsFor(v.dims, options));
    {
        const ScopedEnv env(kMemoryLimitVariable, std::to_string(bytes / 2.0 / (1 << 20)));
        const std::string m = messageOf<LoadError>([&] { preprocess(v, options); });
        EXPECT_HAS(m, "cube: the spectrum of 32 x 32 x 32 voxels padded to ");
        EXPECT_HAS(m, "needs " + std::to_string(bytes) + " bytes");
    }
    const ScopedEnv env(kMemoryLimitVariable, std::to_string(bytes * 2.0 / (1 << 20)));
    EXPECT_NO_THROW(preprocess(v, options));
}

// ------------------------------------------------------------------------------------------------
// Non-regular files

/** While alive, opens `fifo` for writing as soon as a reader waits on it (then closes it, which
 *  gives the reader end-of-file): code that opens the FIFO cannot hang the test, it fails it. */
class FifoGuard {
public:
    explicit FifoGuard(const fs::path& fifo)
        : m_thread([this, fifo] {
              const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(60);
              while (!m_stop && std::chrono::steady_clock::now() < end) {
                  const int fd = open(fifo.c_str(), O_WRONLY | O_NONBLOCK); // ENXIO: no reader
                  if (fd >= 0) {
                      m_readerSeen = true;
                      close(fd);
                  }
                  std::this_thread::sleep_for(std::chrono::milliseconds(50));
              }
          }) {}
    ~FifoGuard() {
        m_stop = true;
        m_thread.join();
    }
    bool readerSeen() const { return m_readerSeen; }

private:
    std::atomic<bool> m_stop{false}, m_readerSeen{false};
    std::thread m_thread;
};

TEST(Limits, FifosAreRefusedWithoutBeingOpened) {
    const fs::path dir = caseDir("fifo");
    for (const char* name : {"pipe.nii", "pipe", "pipe.dcm"}) {
        const fs::path fifo = dir / name;
        ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
        const FifoGuard guard(fifo);
        const std::string m = messageOf<LoadError>([&] { classifyInput(fifo.string()); });
        EXPECT_HAS(m, fifo.string() + ": a FIFO (named pipe), not a regular file");
        EXPECT_FALSE(guard.readerSeen()) << name << " was opened";
    }
    // Through a symbolic link too, and a character device.
    fs::create_symlink(dir / "pipe.nii", dir / "link.nii");
    EXPECT_THROW(classifyInput((dir / "link.nii").string()), LoadError);
    const std::string m = messageOf<LoadError>([] { classifyInput("/dev/null"); });
    EXPECT_HAS(m, "/dev/null: a character device, not a regular file");
}

TEST(Limits, AFifoInADicomFolderIsSkippedWithAWarning) {
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93");
    const fs::path dir = caseDir("fifo_folder");
    for (const auto& e :
         fs::directory_iterator(fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93"))
        fs::copy_file(e.path(), dir / e.path().filename());
    ASSERT_EQ(mkfifo((dir / "zz_pipe").c_str(), 0600), 0);
    const FifoGuard guard(dir / "zz_pipe");
    const DicomScanResult scan = scanDicomFolder(dir);
    ASSERT_EQ(scan.series.size(), 1u);
    EXPECT_EQ(scan.series[0].imageCount, 93);
    bool warned = false;
    for (const std::string& w : scan.warnings)
        warned = warned || (w.find("not a regular file") != std::string::npos &&
                            w.find("zz_pipe") != std::string::npos);
    EXPECT_TRUE(warned) << ::testing::PrintToString(scan.warnings);
    EXPECT_FALSE(guard.readerSeen());
}

// ------------------------------------------------------------------------------------------------
// Values whose projections overflow float

TEST(Limits, ValuesWhoseSpectrumOverflowsFloatAreRefusedNamingThem) {
    Volume v;
    v.dims = {16, 16, 16};
    v.name = "huge";
    v.voxels.assign(16 * 16 * 16, 3e38f);
    const std::string m = messageOf<SettingsError>([&] { preprocess(v, PreprocessOptions{}); });
    EXPECT_HAS(m, "huge: values too large for float: |value| up to 3e+38");
    EXPECT_HAS(m, "4096 voxels");
    EXPECT_HAS(m, "rescale the values");
    // Large values that fit are rendered, finite.
    v.voxels.assign(v.voxels.size(), 1e25f);
    CpuFourierRenderer r(preprocess(v, PreprocessOptions{}), 1);
    RenderParams p;
    p.image = {32, defaultPixelSize(v.dims, v.spacing, 32)};
    const ProjectionImage img = r.render(p);
    for (const float x : img.pixels) ASSERT_TRUE(std::isfinite(x));
}

TEST(Limits, AnImageHoldingNaNIsAnErrorNotAnOutput) {
    ProjectionImage img;
    img.width = img.height = 4;
    img.pixels.assign(16, 1.0f);
    EXPECT_NO_THROW(checkFiniteImage(img));
    img.pixels[3] = std::nanf("");
    img.pixels[7] = std::numeric_limits<float>::infinity();
    const std::string m = messageOf<RenderError>([&] { checkFiniteImage(img); });
    EXPECT_HAS(m, "2 of 16 pixels are not finite");
}

// ------------------------------------------------------------------------------------------------
// NUL characters

TEST(Limits, PathsHoldingNulAreRefusedShowingTheWholePath) {
    const std::string path("/tmp/a\0b.nii", 12);
    const std::string m = messageOf<SettingsError>([&] { classifyInput(path); });
    EXPECT_HAS(m, "path holds a NUL character");
    EXPECT_HAS(m, "'/tmp/a\\0b.nii'");
    EXPECT_EQ(quotedWithEscapes(std::string("x\ny\x7f", 4)), "'x\\x0ay\\x7f'");
}

} // namespace
