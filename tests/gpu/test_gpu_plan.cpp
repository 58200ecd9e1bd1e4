// GPU planning without GL: the FFT plan against FFTW in double, the shader include resolver.
#include <complex>
#include <map>
#include <optional>
#include <random>

#include <fftw3.h>
#include <gtest/gtest.h>

#include <fvr/gpu/errors.h>
#include <fvr/gpu/fft_plan.h>
#include <fvr/gpu/shader_source.h>

using namespace fvr::gpu;

TEST(FftPlan, CpuExecutionMatchesFftwDouble) {
    std::mt19937 rng(3);
    std::normal_distribution<float> g;
    for (int M : {2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096}) {
        for (int sign : {+1, -1}) {
            FftPlan plan(M, sign);
            std::vector<std::complex<float>> x(static_cast<std::size_t>(M));
            for (auto& v : x) v = {g(rng), g(rng)};
            std::vector<fftw_complex> in(static_cast<std::size_t>(M)),
                out(static_cast<std::size_t>(M));
            for (int i = 0; i < M; ++i) {
                in[i][0] = x[i].real();
                in[i][1] = x[i].imag();
            }
            fftw_plan p = fftw_plan_dft_1d(M, in.data(), out.data(),
                                           sign > 0 ? FFTW_BACKWARD : FFTW_FORWARD, FFTW_ESTIMATE);
            fftw_execute(p);
            fftw_destroy_plan(p);
            plan.execute(x);
            double maxErr = 0, maxRef = 0;
            for (int i = 0; i < M; ++i) {
                const std::complex<double> ref(out[i][0], out[i][1]);
                maxErr = std::max(maxErr, std::abs(std::complex<double>(x[i]) - ref));
                maxRef = std::max(maxRef, std::abs(ref));
            }
            EXPECT_LT(maxErr / maxRef, 2e-6) << "M " << M << " sign " << sign;
        }
    }
}

TEST(FftPlan, ValidatesAtCreation) {
    EXPECT_THROW(FftPlan(100, 1), std::invalid_argument);
    EXPECT_THROW(FftPlan(8192, 1), std::invalid_argument);
    EXPECT_THROW(FftPlan(64, 0), std::invalid_argument);
    FftPlan p(16, 1);
    EXPECT_EQ(p.log2Size(), 4);
    EXPECT_EQ(p.twiddles().size(), 32u); // M complex twiddles
    EXPECT_NEAR(p.twiddles()[2 * 4 + 1], 1.0f, 0.0f); // exp(i pi/2) = i exactly: the shader's sign
}

TEST(FftPlan, RadixFourStockhamStages) {
    // Radix 4 while it divides, one radix-2 stage for odd log2 M; the product is M.
    const std::map<int, std::vector<int>> expected{{2, {2}},
                                                   {4, {4}},
                                                   {8, {4, 2}},
                                                   {64, {4, 4, 4}},
                                                   {512, {4, 4, 4, 4, 2}},
                                                   {1024, {4, 4, 4, 4, 4}},
                                                   {4096, {4, 4, 4, 4, 4, 4}}};
    for (const auto& [M, radices] : expected) {
        const FftPlan plan(M, 1);
        EXPECT_EQ(plan.radices(), radices) << "M " << M;
        int product = 1;
        for (int r : plan.radices()) product *= r;
        EXPECT_EQ(product, M);
    }
}

TEST(ShaderSource, ResolvesIncludesOnceAndMapsLines) {
    std::map<std::string, std::string> files{
        {"a.comp",
         "#version 430\n#include \"common/b.glsl\"\n#include \"common/c.glsl\"\nvoid main() {}\n"},
        {"common/b.glsl", "#include \"common/c.glsl\"\nfloat b;\n"},
        {"common/c.glsl", "float c;\n"},
    };
    auto reader = [&](const std::string& p) -> std::optional<std::string> {
        auto it = files.find(p);
        if (it == files.end()) return std::nullopt;
        return it->second;
    };
    const auto s = ShaderSource::assemble("a.comp", {{"TAPS", "4"}}, reader);
    EXPECT_EQ(s.text(), "#version 430\n#define TAPS 4\nfloat c;\nfloat b;\nvoid main() {}\n");
    EXPECT_EQ(s.locate(1), "a.comp:1");
    EXPECT_EQ(s.locate(3), "common/c.glsl:1");
    EXPECT_EQ(s.locate(4), "common/b.glsl:2");
    EXPECT_EQ(s.locate(5), "a.comp:4");
    // Driver logs in the Mesa, NVIDIA and AMD formats point at the original file and line.
    EXPECT_NE(s.mapLog("0:4(7): error: bad").find("common/b.glsl:2: 0:4(7): error"),
              std::string::npos);
    EXPECT_NE(s.mapLog("0(5) : error C1008: x").find("a.comp:4:"), std::string::npos);
    EXPECT_NE(s.mapLog("ERROR: 0:3: 'x'").find("common/c.glsl:1:"), std::string::npos);
}

TEST(ShaderSource, ReportsMissingFilesAndCycles) {
    std::map<std::string, std::string> files{{"a.comp", "#version 430\n#include \"x.glsl\"\n"},
                                             {"x.glsl", "#include \"y.glsl\"\n"},
                                             {"y.glsl", "#include \"x.glsl\"\n"},
                                             {"noversion.comp", "void main() {}\n"}};
    auto reader = [&](const std::string& p) -> std::optional<std::string> {
        auto it = files.find(p);
        if (it == files.end()) return std::nullopt;
        return it->second;
    };
    EXPECT_THROW(ShaderSource::assemble("a.comp", {}, reader), ShaderError);
    EXPECT_THROW(ShaderSource::assemble("missing.comp", {}, reader), ShaderError);
    try {
        ShaderSource::assemble("noversion.comp", {}, reader);
        FAIL();
    } catch (const ShaderError& e) {
        EXPECT_NE(std::string(e.what()).find("noversion.comp:1"), std::string::npos);
    }
}

TEST(ShaderSource, EmbeddedShadersAreThere) {
    const auto reader = ShaderSource::defaultReader();
    for (const char* p :
         {"fft/rows.comp", "fft/cols.comp", "fft/hartley_correct.comp", "slice/slice.comp",
          "display/display.comp", "common/slice.glsl", "common/kernel.glsl", "common/fft.glsl"})
        EXPECT_TRUE(reader(p).has_value()) << p;
}
