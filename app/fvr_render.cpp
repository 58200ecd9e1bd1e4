// fvr-render: headless Fourier volume rendering from the command line.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <fvr/core/cpu_renderer.h>
#include <fvr/core/errors.h>
#include <fvr/core/image_io.h>
#include <fvr/core/phantom.h>
#include <fvr/core/preprocess.h>
#include <fvr/core/volume_io.h>

using namespace fvr::core;

namespace {

const char* kUsage = R"(usage: fvr-render INPUT [options] --out FILE
       fvr-render INPUT --info
       fvr-render INPUT --bench N [options]

INPUT is a volume file (.mhd, .mha, .nii, .nii.gz), a headerless raw file with --raw-dims,
or phantom:shepp-logan[:N] (built-in 3D Shepp-Logan in HU, N^3 voxels, default 128).

View and image:
  --dir x,y,z           viewing direction in the volume frame (default 0,0,1)
  --up x,y,z            up vector (default 0,-1,0: the plain sum of the slices, as stored)
  --size M              slice/image size, power of two 128..2048 (default 512)
  --pixel-size mm       output pixel size (default: volume diagonal / M, no overlapping copies)
Rendering:
  --kernel K            nearest | linear | bspline | catmull-rom | sinc4 (default linear)
  --transform T         fft | fht (default fft)
  --oversampling f      zero-padding factor 1..2 (default 1, as in the paper)
  --values V            raw (stored values) | mu (attenuation rel. water, max(0,1+HU/1000))
  --backend cpu         renderer (the GPU backend comes with the GPU renderer)
  --threads N           worker threads (default: all cores)
Raw input:
  --raw-dims NX,NY,NZ   --raw-type int16|uint16|uint8|float32|...   --raw-spacing sx,sy,sz
  --raw-big-endian      --raw-header BYTES
Output:
  --out FILE            .npy (float32 line integrals, shape (M, M), row 0 at the top),
                        .pfm (float, rows bottom-to-top), .png (display-mapped, auto window)
  --info                print the volume's facts as JSON
  --bench N             render N frames over varying views, print per-stage timings as JSON
Exit status: 0 success, 2 bad input or settings, 1 other failure.
)";

struct Args {
    std::string input;
    Vec3 dir{0, 0, 1};
    Vec3 up{0, -1, 0};
    int size = 512;
    std::optional<double> pixelSize;
    Kernel kernel = Kernel::Linear;
    TransformKind transform = TransformKind::Fft;
    double oversampling = 1.0;
    ValueMapping values = ValueMapping::Raw;
    int threads = 0;
    std::optional<RawSpec> raw;
    std::string out;
    bool info = false;
    int bench = 0;
};

double parseNumber(const std::string& opt, const std::string& s) {
    try {
        std::size_t pos = 0;
        const double v = std::stod(s, &pos);
        if (pos != s.size() || !std::isfinite(v)) throw std::invalid_argument(s);
        return v;
    } catch (const std::exception&) {
        throw SettingsError(opt + ": expected a number, found '" + s + "'");
    }
}

int parseInt(const std::string& opt, const std::string& s) {
    const double v = parseNumber(opt, s);
    if (v != std::floor(v) || std::abs(v) > 1e9) throw SettingsError(opt + ": expected an integer, found '" + s + "'");
    return int(v);
}

Vec3 parseVec(const std::string& opt, const std::string& s) {
    std::vector<double> v;
    std::stringstream ss(s);
    std::string tok;
    while (std::getline(ss, tok, ',')) v.push_back(parseNumber(opt, tok));
    if (v.size() != 3) throw SettingsError(opt + ": expected x,y,z, found '" + s + "'");
    return {v[0], v[1], v[2]};
}

Args parseArgs(int argc, char** argv) {
    Args a;
    RawSpec raw;
    bool rawGiven = false;
    for (int i = 1; i < argc; ++i) {
        const std::string opt = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw SettingsError(opt + ": missing value");
            return argv[++i];
        };
        if (opt == "-h" || opt == "--help") {
            std::cout << kUsage;
            std::exit(0);
        } else if (opt == "--dir") a.dir = parseVec(opt, value());
        else if (opt == "--up") a.up = parseVec(opt, value());
        else if (opt == "--size") a.size = parseInt(opt, value());
        else if (opt == "--pixel-size") a.pixelSize = parseNumber(opt, value());
        else if (opt == "--kernel") a.kernel = parseKernel(value());
        else if (opt == "--transform") a.transform = parseTransform(value());
        else if (opt == "--oversampling") a.oversampling = parseNumber(opt, value());
        else if (opt == "--values") a.values = parseValueMapping(value());
        else if (opt == "--backend") {
            const std::string b = value();
            if (b != "cpu") throw SettingsError("--backend: expected cpu (the GPU backend is not built yet), found '" + b + "'");
        } else if (opt == "--threads") a.threads = parseInt(opt, value());
        else if (opt == "--out") a.out = value();
        else if (opt == "--info") a.info = true;
        else if (opt == "--bench") a.bench = parseInt(opt, value());
        else if (opt == "--raw-dims") {
            const Vec3 d = parseVec(opt, value());
            raw.dims = {std::int64_t(d[0]), std::int64_t(d[1]), std::int64_t(d[2])};
            rawGiven = true;
        } else if (opt == "--raw-type") raw.type = parseElementType(value());
        else if (opt == "--raw-spacing") raw.spacing = parseVec(opt, value());
        else if (opt == "--raw-big-endian") raw.bigEndian = true;
        else if (opt == "--raw-header") raw.headerBytes = std::uint64_t(parseNumber(opt, value()));
        else if (!opt.empty() && opt[0] == '-') throw SettingsError("unknown option '" + opt + "' (see --help)");
        else if (a.input.empty()) a.input = opt;
        else throw SettingsError("unexpected argument '" + opt + "' (one INPUT only)");
    }
    if (rawGiven) a.raw = raw;
    if (a.input.empty()) throw SettingsError("no INPUT given (see --help)");
    if (!a.info && a.bench <= 0 && a.out.empty()) throw SettingsError("no --out FILE given (or --info, --bench N)");
    if (a.bench < 0) throw SettingsError("--bench: expected a positive frame count");
    if (a.threads < 0) throw SettingsError("--threads: expected a positive count");
    return a;
}

Volume loadInput(const Args& a) {
    const std::string prefix = "phantom:";
    if (a.input.rfind(prefix, 0) == 0) {
        const std::string rest = a.input.substr(prefix.size());
        const auto colon = rest.find(':');
        const std::string kind = rest.substr(0, colon);
        if (kind != "shepp-logan") throw SettingsError("INPUT: unknown phantom '" + kind + "' (expected shepp-logan)");
        const int n = colon == std::string::npos ? 128 : parseInt("phantom size", rest.substr(colon + 1));
        return makeSheppLoganVolume(n);
    }
    if (a.raw) return loadRaw(a.input, *a.raw);
    return loadVolume(a.input);
}

std::string jsonEscape(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '"' || c == '\\') { o += '\\'; o += c; }
        else if (static_cast<unsigned char>(c) < 0x20) { char b[8]; std::snprintf(b, sizeof b, "\\u%04x", c); o += b; }
        else o += c;
    }
    return o;
}

std::string vecJson(const Vec3& v) {
    std::ostringstream s;
    s << "[" << v[0] << ", " << v[1] << ", " << v[2] << "]";
    return s.str();
}

void printInfo(const Volume& v) {
    const auto [lo, hi] = v.valueRange();
    std::cout << "{\n  \"name\": \"" << jsonEscape(v.name) << "\",\n"
              << "  \"dims\": [" << v.dims[0] << ", " << v.dims[1] << ", " << v.dims[2] << "],\n"
              << "  \"spacing_mm\": " << vecJson(v.spacing) << ",\n"
              << "  \"origin_mm\": " << vecJson(v.origin) << ",\n"
              << "  \"direction\": [" << vecJson(v.direction[0]) << ", " << vecJson(v.direction[1]) << ", "
              << vecJson(v.direction[2]) << "],\n"
              << "  \"units\": \"" << unitsName(v.units) << "\",\n"
              << "  \"value_range\": [" << lo << ", " << hi << "],\n"
              << "  \"extent_mm\": " << vecJson(v.extent()) << "\n}\n";
}

struct Stat {
    double median, p95;
};
Stat stats(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    auto q = [&](double f) { return v[std::min(v.size() - 1, std::size_t(std::ceil(f * v.size())) - 1)]; };
    return {v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]), q(0.95)};
}

std::string settingsJson(const Args& a, const Spectrum& s, double d, int threads) {
    std::ostringstream o;
    o << "{\"input\": \"" << jsonEscape(a.input) << "\", \"backend\": \"cpu\", \"kernel\": \"" << kernelName(a.kernel)
      << "\", \"transform\": \"" << transformName(a.transform) << "\", \"size\": " << a.size
      << ", \"pixel_size_mm\": " << d << ", \"oversampling\": " << a.oversampling << ", \"values\": \""
      << valueMappingName(a.values) << "\", \"volume_dims\": [" << s.volumeDims[0] << ", " << s.volumeDims[1] << ", "
      << s.volumeDims[2] << "], \"padded_dims\": [" << s.padded[0] << ", " << s.padded[1] << ", " << s.padded[2]
      << "], \"spectrum_mb\": " << double(s.bytes()) / (1 << 20) << ", \"threads\": " << threads << "}";
    return o.str();
}

int run(int argc, char** argv) {
    const Args a = parseArgs(argc, argv);
    const Volume volume = loadInput(a);
    if (a.info) {
        printInfo(volume);
        if (a.out.empty() && a.bench <= 0) return 0;
    }
    PreprocessOptions po;
    po.mapping = a.values;
    po.transform = a.transform;
    po.oversampling = a.oversampling;
    po.threads = a.threads;
    const auto tp0 = std::chrono::steady_clock::now();
    int lastPct = -1;
    const bool tty = isatty(2);
    auto spectrum = preprocess(volume, po, [&](double f, std::string_view stage) {
        const int pct = int(f * 100);
        if (tty && pct != lastPct) {
            std::fprintf(stderr, "\rpreprocessing %3d%% %-28.*s", pct, int(stage.size()), stage.data());
            lastPct = pct;
        }
    });
    if (tty) std::fprintf(stderr, "\r%60s\r", "");
    const double preprocessMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - tp0).count();

    const double d = a.pixelSize ? *a.pixelSize : defaultPixelSize(volume.dims, volume.spacing, a.size);
    ImageGeometry geom{a.size, d};
    validateImageGeometry(geom);
    if (a.size < 128 || a.size > 2048)
        throw SettingsError("--size: expected a power of two in 128..2048, found " + std::to_string(a.size));
    CpuFourierRenderer renderer(spectrum, a.threads);
    const int threads = a.threads > 0 ? a.threads : hardwareThreads();

    if (a.bench > 0) {
        std::vector<double> sl, inv, tot;
        const ViewFrame base = ViewFrame::fromDirUp(a.dir, a.up);
        renderer.render({base, geom, a.kernel}); // warm-up: plans and buffers
        for (int i = 0; i < a.bench; ++i) {
            // Views over a cone of directions, so the spectrum is read along varied planes.
            const ViewFrame v = base.rotated({0.3, 1.0, 0.2}, 2.0 * std::numbers::pi * i / a.bench);
            StageTimes t;
            renderer.render({v, geom, a.kernel}, &t);
            sl.push_back(t.sliceMs);
            inv.push_back(t.inverseMs);
            tot.push_back(t.totalMs);
        }
        const Stat s1 = stats(sl), s2 = stats(inv), s3 = stats(tot);
        std::printf("{\n  \"settings\": %s,\n  \"frames\": %d,\n", settingsJson(a, *spectrum, d, threads).c_str(), a.bench);
        std::printf("  \"preprocess\": {\"median_ms\": %.3f, \"p95_ms\": %.3f},\n", preprocessMs, preprocessMs);
        std::printf("  \"slice\": {\"median_ms\": %.3f, \"p95_ms\": %.3f},\n", s1.median, s1.p95);
        std::printf("  \"inverse\": {\"median_ms\": %.3f, \"p95_ms\": %.3f},\n", s2.median, s2.p95);
        std::printf("  \"total\": {\"median_ms\": %.3f, \"p95_ms\": %.3f, \"fps\": %.1f}\n}\n", s3.median, s3.p95,
                    1000.0 / s3.median);
    }
    if (!a.out.empty()) {
        const ViewFrame view = ViewFrame::fromDirUp(a.dir, a.up);
        const ProjectionImage img = renderer.render({view, geom, a.kernel});
        writeProjection(a.out, img);
        std::fprintf(stderr, "wrote %s (%dx%d, pixel %.4g mm, %s, %s, %s)\n", a.out.c_str(), a.size, a.size, d,
                     kernelName(a.kernel), transformName(a.transform),
                     projectionUnits(a.values, volume.units).c_str());
    }
    return 0;
}

} // namespace

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const InputError& e) {
        std::cerr << "fvr-render: error: " << e.what() << "\n";
        return 2;
    } catch (const std::bad_alloc&) {
        std::cerr << "fvr-render: error: out of memory (try a smaller --oversampling or --size)\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "fvr-render: error: " << e.what() << "\n";
        return 1;
    }
}
