// GPU planning without GL: the FFT plan against FFTW in double, the shader include resolver, the
// binding points the shaders and the host share.
#include <complex>
#include <map>
#include <optional>
#include <random>
#include <regex>
#include <set>
#include <sstream>

#include <fftw3.h>
#include <gtest/gtest.h>

#include <fvr/gpu/bindings.h>
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

namespace {
/** The `#define NAME VALUE` lines of a GLSL text. */
std::map<std::string, std::string> glslDefines(const std::string& text) {
    static const std::regex def(R"(^#define\s+(\w+)\s+(\S+)\s*$)");
    std::map<std::string, std::string> defs;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);)
        if (std::smatch m; std::regex_match(line, m, def)) defs[m[1].str()] = m[2].str();
    return defs;
}
} // namespace

TEST(Bindings, GlslDefinesEveryHostBindingPointOnce) {
    const auto reader = ShaderSource::defaultReader();
    const auto text = reader(kBindingsInclude);
    ASSERT_TRUE(text.has_value()) << kBindingsInclude << " is not served";
    EXPECT_EQ(*text, bindingsGlsl());
    const auto defs = glslDefines(*text);
    EXPECT_EQ(defs.size(), std::size(kGlslBindings)) << *text; // no name twice
    for (const auto& b : kGlslBindings) {
        const std::string name = std::string("FVR_") + b.glsl;
        ASSERT_TRUE(defs.count(name)) << name << " missing from\n" << *text;
        EXPECT_EQ(defs.at(name), std::to_string(b.point)) << name;
        // OpenGL 4.3 guarantees 8 storage blocks, image units and texture units per compute shader.
        EXPECT_LT(b.point, 8u) << name;
    }
    // Spot checks against the enum itself, written out.
    EXPECT_EQ(defs.at("FVR_BINDING_PASS_OUTPUT"), std::to_string(point(Binding::PassOutput)));
    EXPECT_EQ(defs.at("FVR_BINDING_FILTER_AXIS"), std::to_string(point(Binding::FilterAxis)));
    EXPECT_EQ(defs.at("FVR_BINDING_MATERIAL_4"), std::to_string(point(materialBinding(4))));
    EXPECT_EQ(defs.at("FVR_IMAGE_DISPLAY"), std::to_string(point(ImageUnit::Display)));
}

TEST(Bindings, EveryEmbeddedShaderNamesItsBindingsBeforeAnyConditional) {
    const auto reader = ShaderSource::defaultReader();
    const auto paths = ShaderSource::embeddedPaths();
    static const std::regex bareNumber(R"(binding\s*=\s*[0-9])");
    static const std::regex named(R"(binding\s*=\s*(\w+))");
    int comps = 0, namedUses = 0;
    for (const auto& path : paths) {
        const auto text = reader(path);
        ASSERT_TRUE(text.has_value()) << path;
        EXPECT_FALSE(std::regex_search(*text, bareNumber))
            << path << ": a binding point as a bare number; name it (fvr/gpu/bindings.h)";
        if (path.size() < 5 || path.substr(path.size() - 5) != ".comp") continue;
        ++comps;
        // Assembled as the renderer does: every name used is defined, and defined before the
        // first #if (an include inside a skipped #ifdef would leave the names undefined).
        const auto src = ShaderSource::assemble(path, {}, reader);
        const auto defs = glslDefines(src.text());
        for (auto it = std::sregex_iterator(src.text().begin(), src.text().end(), named);
             it != std::sregex_iterator(); ++it, ++namedUses)
            EXPECT_TRUE(defs.count((*it)[1].str())) << path << ": " << (*it)[1].str();
        const auto firstIf = src.text().find("\n#if");
        const auto lastDefine = src.text().rfind("\n#define FVR_");
        ASSERT_NE(lastDefine, std::string::npos)
            << path << " does not include " << kBindingsInclude;
        if (firstIf != std::string::npos) {
            EXPECT_LT(lastDefine, firstIf)
                << path << ": include " << kBindingsInclude << " before the first #if";
        }
    }
    EXPECT_EQ(comps, 7) << "the compute shaders of gpu/CMakeLists.txt";
    EXPECT_GE(namedUses, 20);
}
