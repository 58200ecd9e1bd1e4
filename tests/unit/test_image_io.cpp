#include <algorithm>
#include <atomic>
#include <cstring>
#include <fstream>
#include <iterator>
#include <thread>

#include <gtest/gtest.h>
#include <zlib.h>

#include <unistd.h>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/io/image_io.h>

#include "test_support.h"

using namespace fvr::core;

namespace {
std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
std::vector<float> ramp(int rows, int cols) {
    std::vector<float> v(std::size_t(rows) * cols);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) v[std::size_t(r) * cols + c] = float(r * 100 + c);
    return v;
}
/** The temporary file this process writes for `dir/name` (`.<name>.<pid>-<id>.<n>.part`), or
 *  empty. */
std::filesystem::path temporaryOf(const std::filesystem::path& dir, const std::string& name) {
    for (const auto& f : std::filesystem::directory_iterator(dir)) {
        const std::string file = f.path().filename().string();
        if (file.rfind("." + name + ".", 0) == 0 && temporaryWriterPid(f.path()) == ::getpid())
            return f.path();
    }
    return {};
}
} // namespace

TEST(ImageIo, NpyRoundTripAndHeader) {
    const auto v = ramp(5, 7);
    const auto p = fvr::test::tmpDir() / "ramp.npy";
    writeNpy(p, v.data(), 5, 7);
    const std::string bytes = slurp(p);
    ASSERT_EQ(bytes.substr(0, 6), "\x93NUMPY");
    const std::size_t hlen = std::uint8_t(bytes[8]) | (std::uint8_t(bytes[9]) << 8);
    EXPECT_EQ((10 + hlen) % 64, 0u);
    EXPECT_NE(bytes.find("'shape': (5, 7)"), std::string::npos);
    EXPECT_NE(bytes.find("'fortran_order': False"), std::string::npos);
    std::vector<std::int64_t> shape;
    EXPECT_EQ(readNpy(p, shape), v);
    EXPECT_EQ(shape, (std::vector<std::int64_t>{5, 7}));
    // Stacked (N, M, M)
    std::vector<float> stack(3 * 4 * 4, 1.5f);
    writeNpy(p, stack.data(), 4, 4, 3);
    EXPECT_EQ(readNpy(p, shape).size(), 48u);
    EXPECT_EQ(shape, (std::vector<std::int64_t>{3, 4, 4}));
}

// A shape tuple that is not sizes >= 0 is a LoadError naming the file and the shape, never a
// std::invalid_argument from the number parser or a wrapped negative size.
TEST(ImageIo, NpyBadShapeNamesFileAndField) {
    const auto v = ramp(5, 7);
    const auto good = fvr::test::tmpDir() / "shape_good.npy";
    writeNpy(good, v.data(), 5, 7);
    const std::string bytes = slurp(good);
    const std::size_t at = bytes.find("(5, 7)");
    ASSERT_NE(at, std::string::npos);
    // Same length as "(5, 7)": the header length and data offset stay right.
    for (const std::string shape : {"(x5,7)", "(5, x)", "(5,-7)", "(5, 7 "}) {
        std::string bad = bytes;
        bad.replace(at, shape.size(), shape);
        const auto p = fvr::test::tmpDir() / "shape_bad.npy";
        std::ofstream(p, std::ios::binary).write(bad.data(), std::streamsize(bad.size()));
        std::vector<std::int64_t> out;
        try {
            readNpy(p, out);
            FAIL() << "expected LoadError for shape " << shape;
        } catch (const LoadError& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find(p.string() + ": shape: "), std::string::npos) << what;
        }
    }
}

TEST(ImageIo, NpyStackWriterStreamsTheSameBytesAsWriteNpy) {
    const auto dir = fvr::test::tmpDir() / "npy_stack";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const auto v = ramp(3 * 5, 7); // three 5 x 7 images
    writeNpy(dir / "whole.npy", v.data(), 5, 7, 3);
    {
        NpyStackWriter w(dir / "streamed.npy", 5, 7, 3);
        for (int i = 0; i < 3; ++i) {
            // Written as it comes: the header and the images so far, under the temporary name.
            w.add(v.data() + std::size_t(i) * 5 * 7);
            EXPECT_FALSE(std::filesystem::exists(dir / "streamed.npy"));
            const std::filesystem::path part = temporaryOf(dir, "streamed.npy");
            ASSERT_FALSE(part.empty()) << "no temporary file of streamed.npy in " << dir;
            EXPECT_EQ(std::filesystem::file_size(part),
                      128u + std::size_t(i + 1) * 5 * 7 * sizeof(float));
        }
        w.finish();
    }
    EXPECT_EQ(slurp(dir / "streamed.npy"), slurp(dir / "whole.npy"));
    // Fewer images than the header says: finish() fails naming the file, and nothing stays.
    {
        NpyStackWriter w(dir / "short.npy", 5, 7, 3);
        w.add(v.data());
        try {
            w.finish();
            ADD_FAILURE() << "a stack of 1 of 3 images was finished";
        } catch (const WriteError& e) {
            EXPECT_NE(std::string(e.what()).find("short.npy: the stack has 1 images of the 3"),
                      std::string::npos)
                << e.what();
        }
        EXPECT_THROW(w.add(v.data()), WriteError); // closed: nothing more goes in
    }
    { NpyStackWriter abandoned(dir / "abandoned.npy", 5, 7, 3); }
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(dir))
        names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"streamed.npy", "whole.npy"}));
}

TEST(ImageIo, PfmStoresRowsBottomToTop) {
    const auto v = ramp(3, 4);
    const auto p = fvr::test::tmpDir() / "ramp.pfm";
    writePfm(p, v.data(), 3, 4);
    const std::string bytes = slurp(p);
    const std::string header = "Pf\n4 3\n-1.0\n";
    ASSERT_EQ(bytes.substr(0, header.size()), header);
    ASSERT_EQ(bytes.size(), header.size() + 12 * 4);
    float first;
    std::memcpy(&first, bytes.data() + header.size(), 4);
    EXPECT_EQ(first, 200.0f); // bottom row (row 2), column 0
}

TEST(ImageIo, PngDecodesToWindowedValues) {
    const auto v = ramp(2, 3); // 0 1 2 / 100 101 102
    const auto p = fvr::test::tmpDir() / "ramp.png";
    for (int depth : {8, 16}) {
        writePng(p, v.data(), 2, 3, {0.0, 102.0, false}, depth);
        const std::string b = slurp(p);
        ASSERT_EQ(b.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
        ASSERT_EQ(b.substr(12, 4), "IHDR");
        EXPECT_EQ(std::uint8_t(b[24]), depth);
        const auto idat = b.find("IDAT");
        ASSERT_NE(idat, std::string::npos);
        const std::uint32_t len = (std::uint8_t(b[idat - 4]) << 24) |
                                  (std::uint8_t(b[idat - 3]) << 16) |
                                  (std::uint8_t(b[idat - 2]) << 8) | std::uint8_t(b[idat - 1]);
        const int bpp = depth / 8;
        std::vector<unsigned char> raw(2 * (1 + 3 * bpp));
        uLongf rawLen = uLongf(raw.size());
        ASSERT_EQ(uncompress(raw.data(), &rawLen,
                             reinterpret_cast<const Bytef*>(b.data() + idat + 4), len),
                  Z_OK);
        ASSERT_EQ(rawLen, raw.size());
        auto px = [&](int r, int c) {
            const unsigned char* q = &raw[r * (1 + 3 * bpp) + 1 + c * bpp];
            return bpp == 2 ? (q[0] << 8 | q[1]) : q[0];
        };
        const int maxv = depth == 8 ? 255 : 65535;
        EXPECT_EQ(px(0, 0), 0);
        EXPECT_EQ(px(1, 2), maxv);
        EXPECT_EQ(px(1, 0), std::lround(100.0 / 102.0 * maxv));
    }
}

TEST(ImageIo, AutoWindowIgnoresOutliers) {
    std::vector<float> v(10000);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(i % 100);
    v[5] = 1e9f;
    const auto w = autoWindow(v);
    EXPECT_LT(w.high, 100.0);
    EXPECT_GE(w.low, 0.0);
}

TEST(ImageIo, UnknownExtensionAndUnwritablePath) {
    ProjectionImage img;
    img.width = img.height = 2;
    img.pixels.assign(4, 1.0f);
    EXPECT_THROW(writeProjection(fvr::test::tmpDir() / "x.bmp", img), WriteError);
    try {
        writeProjection("/nonexistent-dir/x.npy", img);
        FAIL() << "expected WriteError";
    } catch (const WriteError& e) {
        EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.npy"), std::string::npos);
    }
}

// Temporary names are unique per process and writer (concurrent writers of one name shared
// `<name>.part` and failed: "cannot move the written file into place"), hidden, end in .part and
// name their writer's pid for a cleaner; a long final name is shortened in the temporary name.
TEST(AtomicFile, TemporaryNamesAreUniqueAndNameTheirWriter) {
    const std::filesystem::path dir = "/out";
    const auto a = temporaryPathFor(dir / "s.npy"), b = temporaryPathFor(dir / "s.npy");
    EXPECT_NE(a, b);
    EXPECT_EQ(a.parent_path(), dir);
    EXPECT_EQ(a.extension(), ".part");
    EXPECT_EQ(temporaryWriterPid(a), ::getpid());
    for (const char* other : {"s.npy.part", ".s.npy.part", ".s.npy.12x.3.part", "s.npy",
                              ".s.npy.12.3.part.npy", "..1.part"})
        EXPECT_FALSE(temporaryWriterPid(dir / other)) << other;
    EXPECT_EQ(temporaryWriterPid(dir / ".x.99.0.part"), 99); // the older form, no identity
    // The writer's pid space in the name: a pid of this one is read back, one of another host
    // or container (another identity) is not (a cleaner must keep its file).
    const std::string ours = writerIdentity(), other = ours == "00000000" ? "00000001" : "00000000";
    EXPECT_EQ(
        a.filename().string().rfind(".s.npy." + std::to_string(::getpid()) + "-" + ours + ".", 0),
        0u)
        << a;
    EXPECT_EQ(temporaryWriterPid(dir / (".x.99-" + ours + ".0.part")), 99);
    for (const std::string& foreign : {".x.99-" + other + ".0.part", ".x.99-" + ours + "0.0.part",
                                       ".x.99-" + ours.substr(1) + ".0.part",
                                       std::string(".x.99-.0.part"), ".x.-" + ours + ".0.part"})
        EXPECT_FALSE(temporaryWriterPid(dir / foreign)) << foreign;
    const auto longName = temporaryPathFor(dir / std::string(255, 'n'));
    EXPECT_LE(longName.filename().string().size(), 255u);
    EXPECT_EQ(temporaryWriterPid(longName), ::getpid());
}

TEST(AtomicFile, ConcurrentWritersOfOneNameNeverCollide) {
    const auto dir = fvr::test::tmpDir() / "atomic_concurrent";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const auto path = dir / "same.bin";
    std::vector<std::string> contents;
    for (int t = 0; t < 8; ++t) contents.push_back(std::string(100000 + t, char('a' + t)));
    std::atomic<int> failures{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < 8; ++t)
        threads.emplace_back([&, t] {
            for (int i = 0; i < 50; ++i) try {
                    if (i % 2)
                        writeFileAtomic(path, contents[t]);
                    else
                        writeAtomically(path, [&](const std::filesystem::path& tmp) {
                            std::ofstream(tmp, std::ios::binary) << contents[t];
                        });
                } catch (const WriteError&) {
                    ++failures;
                }
        });
    for (auto& t : threads) t.join();
    EXPECT_EQ(failures.load(), 0);
    // One writer's whole content (the last rename), nothing else in the folder.
    const std::string last = slurp(path);
    EXPECT_NE(std::find(contents.begin(), contents.end(), last), contents.end());
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir),
                            std::filesystem::directory_iterator()),
              1);
}
