// fvr-render: headless Fourier volume rendering from the command line.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <sys/stat.h>
#include <unistd.h>

#include <fvr/core/render/cpu_renderer.h>
#include <fvr/core/dicom/dicom.h>
#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/xray/patient_views.h>
#include <fvr/core/errors.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/render/image_metrics.h>
#include <fvr/core/xray/phantom.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/core/io/volume_io.h>
#ifdef FVR_HAVE_GPU
#include <QGuiApplication>

#include <fvr/gpu/errors.h>
#include <fvr/gpu/gpu_renderer.h>
#include <fvr/gpu/offscreen_context.h>
#endif

using namespace fvr::core;

namespace {

const char* kUsage = R"(usage: fvr-render INPUT [options] --out FILE
       fvr-render INPUT --info
       fvr-render INPUT --bench N [options]

INPUT is a DICOM folder (or one DICOM file), a volume file (.mhd, .mha, .nii, .nii.gz), a
headerless raw file with --raw-dims, or phantom:shepp-logan[:N] (built-in 3D Shepp-Logan in HU,
N^3 voxels, default 128).

View and image:
  --dir x,y,z           viewing direction in the volume frame (default 0,0,1)
  --up x,y,z            up vector (default 0,-1,0: the plain sum of the slices, as stored)
  --view V              patient view from the direction cosines (instead of --dir/--up):
                        AP | PA | LEFT | RIGHT | HEAD | FEET (AP: from anterior, head up,
                        patient's left on the image's right)
DICOM:
  --series UID          the series to load from a folder (default: the only one, else the one
                        with most slices); --info lists the folder's series as JSON
  --size M              slice/image size, power of two 128..2048 (default 512)
  --pixel-size mm       output pixel size (default: volume diagonal / M, no overlapping copies)
Rendering:
  --kernel K            nearest | linear | bspline | catmull-rom | sinc4 | kaiser-bessel
                        (default linear)
  --kernel-width W      kaiser-bessel width: 4 (default) or 6
  --deapodize on|off    divide the volume by the kernel's Fourier transform before the 3D FFT
                        (gridding correction; default on for kaiser-bessel, off otherwise)
  --transform T         fft | fht (default fft)
  --oversampling f      zero-padding factor 1..2 (default 1, as in the paper)
  --values V            raw (stored values) | mu (attenuation rel. water, max(0,1+HU/1000)) |
                        mu-bone (as mu up to +100 HU, twice as steep above: bone stands out)
  --voxel-model V       what lies between the voxels: trilinear (default: the projection a
                        trilinear DRR ray caster computes, no ringing) | bspline (the cubic
                        B-spline through the voxels) | bandlimited (the plain FVR image, sharpest,
                        rings at scan ends and between coarse slices)
  --pixel-aperture      detector pixels integrate over their area (sinc per image axis) instead
                        of sampling the projection at their centres
  --no-clip             keep what FVR puts outside the volume's shadow (ghost copies, ringing);
                        by default pixels whose ray misses the voxel model's support are 0, as
                        they truly are
  --keep-negative       keep negative line integrals of a volume without negative values
                        (mu values, or raw data >= 0); by default they are 0, as they truly are
  --depth-cue S         depth cueing strength 0..1 (default 0): weight 1 at the front of the
                        volume's bounding sphere falling linearly to 1-S at its back (not with
                        --kernel nearest)
  --sharpen A           unsharp mask on the slice: image + A x (image - Gaussian blur), A >= 0
                        (default 0, off)
  --sharpen-radius mm   sigma of the unsharp mask's Gaussian (default 1.0)
  --band-limit lp/mm    order-8 Butterworth low-pass, -3 dB at this frequency (default 0, off)
  --backend cpu|gpu     renderer (default cpu); gpu renders offscreen with OpenGL 4.3 compute
                        shaders and falls back to the CPU, saying why, when no GPU is usable
  --fp16                GPU: store the spectrum as float16 (2 bytes per voxel)
  --threads N           worker threads (default: all cores)
Raw input:
  --raw-dims NX,NY,NZ   --raw-type int16|uint16|uint8|float32|...   --raw-spacing sx,sy,sz
  --raw-big-endian      --raw-header BYTES
Many views (DRRs):
  --sweep N             N views rotating about --axis (default: the patient's head-feet axis)
  --axis x,y,z          rotation axis of --sweep in the volume frame
  --views FILE          one view per line: dx dy dz ux uy uz (commas or spaces; # comments)
  --numbered            with several views and a .npy output: numbered files, not one stack
Output:
  --out FILE            .npy (float32 line integrals, shape (M, M), row 0 at the top; several
                        views: one stacked (N, M, M) file), .pfm (float, rows bottom-to-top),
                        .png (display-mapped, auto window); several views and .pfm/.png:
                        FILE_0000.ext, FILE_0001.ext, ... A JSON sidecar FILE.json records
                        every parameter and view.
  --bit-depth 8|16      PNG bit depth (default 8)
  --beer-lambert        with --values mu or mu-bone: transmitted intensity
                        exposure x exp(-mu_water x integral) instead of line integrals (a
                        radiograph's physics)
  --mu-water 1/mm       linear attenuation of water for --beer-lambert (default 0.0193,
                        about 70 keV)
  --energy keV          photon energy 20..150 for --beer-lambert: mu_water from the NIST XCOM
                        table (instead of --mu-water; 0.02059 per mm at 60 keV)
  --exposure X          beam intensity for --beer-lambert, > 0 (default 1: full scale)
  --info                print the volume's facts as JSON
  --bench N             render N frames over varying views, print per-stage timings as JSON,
                        and the same views by ray casting (spatial projector) with the speed-up
Exit status: 0 success, 2 bad input or settings, 1 other failure.
)";

struct Args {
    std::string input;
    Vec3 dir{0, 0, 1};
    Vec3 up{0, -1, 0};
    int size = 512;
    std::optional<double> pixelSize;
    Kernel kernel = Kernel::Linear;
    int kernelWidth = 0;
    std::optional<bool> deapodize;
    TransformKind transform = TransformKind::Fft;
    double oversampling = 1.0;
    ValueMapping values = ValueMapping::Raw;
    int threads = 0;
    bool gpu = false;
    bool fp16 = false;
    std::optional<RawSpec> raw;
    std::optional<PatientView> view;
    std::string series;
    int sweep = 0;
    std::optional<Vec3> axis;
    std::string viewsFile;
    bool numbered = false;
    int bitDepth = 8;
    bool beerLambert = false;
    std::optional<double> muWater; ///< --mu-water
    std::optional<double> energy;  ///< --energy, keV
    std::optional<double> exposure;
    Transmission transmission;     ///< resolved from the three above; active with --beer-lambert
    double depthCue = 0.0;
    bool clip = true;
    VoxelModel voxelModel = VoxelModel::Trilinear;
    bool pixelAperture = false;
    bool keepNegative = false;
    SliceFilter filter;
    std::string out;
    bool info = false;
    int bench = 0;
};

constexpr double kDefaultMuWater = 0.0193; // per mm, about 70 keV

std::string numberText(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
}

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
        else if (opt == "--view") a.view = parsePatientView(value());
        else if (opt == "--series") a.series = value();
        else if (opt == "--sweep") a.sweep = parseInt(opt, value());
        else if (opt == "--axis") a.axis = parseVec(opt, value());
        else if (opt == "--views") a.viewsFile = value();
        else if (opt == "--numbered") a.numbered = true;
        else if (opt == "--bit-depth") a.bitDepth = parseInt(opt, value());
        else if (opt == "--beer-lambert") a.beerLambert = true;
        else if (opt == "--mu-water") a.muWater = parseNumber(opt, value());
        else if (opt == "--energy") a.energy = parseNumber(opt, value());
        else if (opt == "--exposure") a.exposure = parseNumber(opt, value());
        else if (opt == "--depth-cue") a.depthCue = parseNumber(opt, value());
        else if (opt == "--no-clip") a.clip = false;
        else if (opt == "--voxel-model") {
            try {
                a.voxelModel = parseVoxelModel(value());
            } catch (const SettingsError& e) {
                throw SettingsError(std::string("--voxel-model: ") + e.what());
            }
        } else if (opt == "--pixel-aperture") a.pixelAperture = true;
        else if (opt == "--keep-negative") a.keepNegative = true;
        else if (opt == "--sharpen") a.filter.sharpenAmount = parseNumber(opt, value());
        else if (opt == "--sharpen-radius") a.filter.sharpenSigmaMm = parseNumber(opt, value());
        else if (opt == "--band-limit") a.filter.bandLimitLpMm = parseNumber(opt, value());
        else if (opt == "--size") a.size = parseInt(opt, value());
        else if (opt == "--pixel-size") a.pixelSize = parseNumber(opt, value());
        else if (opt == "--kernel") a.kernel = parseKernel(value());
        else if (opt == "--kernel-width") a.kernelWidth = parseInt(opt, value());
        else if (opt == "--deapodize") {
            const std::string v = value();
            if (v != "on" && v != "off") throw SettingsError("--deapodize: expected on|off, found '" + v + "'");
            a.deapodize = v == "on";
        }
        else if (opt == "--transform") a.transform = parseTransform(value());
        else if (opt == "--oversampling") a.oversampling = parseNumber(opt, value());
        else if (opt == "--values") a.values = parseValueMapping(value());
        else if (opt == "--backend") {
            const std::string b = value();
            if (b != "cpu" && b != "gpu") throw SettingsError("--backend: expected cpu|gpu, found '" + b + "'");
            a.gpu = b == "gpu";
        } else if (opt == "--fp16") a.fp16 = true;
        else if (opt == "--threads") a.threads = parseInt(opt, value());
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
    const bool kb = a.kernel == Kernel::KaiserBessel4 || a.kernel == Kernel::KaiserBessel6;
    if (a.kernelWidth != 0) {
        if (!kb) throw SettingsError("--kernel-width: only for --kernel kaiser-bessel");
        a.kernel = kaiserBesselKernel(a.kernelWidth);
    }
    if (a.sweep < 0 || a.sweep > 100000) throw SettingsError("--sweep: expected 1..100000 views");
    if (a.sweep > 0 && !a.viewsFile.empty()) throw SettingsError("--sweep and --views: give one of them");
    if (a.bitDepth != 8 && a.bitDepth != 16) throw SettingsError("--bit-depth: expected 8 or 16");
    if (a.beerLambert && !isAttenuation(a.values))
        throw SettingsError("--beer-lambert: needs --values mu or mu-bone (transmission follows from attenuation)");
    if (a.muWater && !(*a.muWater > 0 && *a.muWater < 10)) throw SettingsError("--mu-water: expected 0..10 per mm");
    if (a.energy) {
        try {
            a.transmission.muWaterPerMm = waterAttenuationPerMm(*a.energy);
        } catch (const SettingsError& e) {
            throw SettingsError(std::string("--energy: ") + e.what());
        }
    }
    if (a.exposure && !(*a.exposure > 0))
        throw SettingsError("--exposure: expected a positive beam intensity, found " + numberText(*a.exposure));
    if (a.energy && a.muWater)
        throw SettingsError("--energy and --mu-water: give one of them (--energy sets mu_water from the photon energy)");
    if (!a.beerLambert && (a.energy || a.exposure))
        throw SettingsError(std::string(a.energy ? "--energy" : "--exposure") + ": only with --beer-lambert");
    if (!a.energy) a.transmission.muWaterPerMm = a.muWater.value_or(kDefaultMuWater);
    a.transmission.exposure = a.exposure.value_or(1.0);
    if (!(a.depthCue >= 0 && a.depthCue <= 1))
        throw SettingsError("--depth-cue: expected a strength in 0..1, found " + numberText(a.depthCue));
    if (a.depthCue > 0 && a.kernel == Kernel::Nearest)
        throw SettingsError("--depth-cue: needs the derivative of the interpolation kernel; --kernel nearest has "
                            "none (choose linear or better)");
    // Each filter option on its own, so that the message names the option.
    for (const auto& [name, field] : {std::pair{"--sharpen", &SliceFilter::sharpenAmount},
                                      std::pair{"--sharpen-radius", &SliceFilter::sharpenSigmaMm},
                                      std::pair{"--band-limit", &SliceFilter::bandLimitLpMm}}) {
        SliceFilter f;
        f.*field = a.filter.*field;
        try {
            validateSliceFilter(f);
        } catch (const SettingsError& e) {
            throw SettingsError(std::string(name) + ": " + e.what());
        }
    }
    if (a.threads < 0) throw SettingsError("--threads: expected a positive count");
    return a;
}

std::string jsonEscape(const std::string& s);

void printWarnings(const std::vector<std::string>& warnings) {
    for (const auto& w : warnings) std::fprintf(stderr, "fvr-render: warning: %s\n", w.c_str());
}

void printSeriesJson(const DicomScanResult& scan) {
    std::printf("{\n  \"series\": [");
    for (std::size_t i = 0; i < scan.series.size(); ++i) {
        const auto& s = scan.series[i];
        std::printf("%s\n    {\"key\": \"%s\", \"series_uid\": \"%s\", \"patient_name\": \"%s\", "
                    "\"patient_id\": \"%s\", \"study_date\": \"%s\", \"modality\": \"%s\", "
                    "\"description\": \"%s\", \"transfer_syntax\": \"%s\", \"images\": %d, \"frames\": %d, "
                    "\"dims\": [%lld, %lld, %lld], \"spacing_mm\": [%g, %g, %g], \"warnings\": [",
                    i ? "," : "", jsonEscape(s.key).c_str(), jsonEscape(s.seriesUid).c_str(),
                    jsonEscape(s.patientName).c_str(), jsonEscape(s.patientId).c_str(), jsonEscape(s.studyDate).c_str(),
                    jsonEscape(s.modality).c_str(), jsonEscape(s.description).c_str(),
                    jsonEscape(s.transferSyntax).c_str(), s.imageCount, s.frameCount, (long long)s.dims[0],
                    (long long)s.dims[1], (long long)s.dims[2], s.spacing[0], s.spacing[1], s.spacing[2]);
        for (std::size_t w = 0; w < s.warnings.size(); ++w)
            std::printf("%s\"%s\"", w ? ", " : "", jsonEscape(s.warnings[w]).c_str());
        std::printf("]}");
    }
    std::printf("\n  ],\n  \"skipped\": [");
    for (std::size_t i = 0; i < scan.skipped.size(); ++i)
        std::printf("%s\n    \"%s\"", i ? "," : "", jsonEscape(scan.skipped[i]).c_str());
    std::printf("%s]\n}\n", scan.skipped.empty() ? "" : "\n  ");
}

/** Patient and study of a DICOM input, carried into DICOM outputs. */
DicomExportInfo g_exportInfo;

/** Loads INPUT; for a DICOM folder with --info prints the series and returns nothing. */
std::optional<Volume> loadInput(const Args& a) {
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
    const std::filesystem::path path(a.input);
    if (std::filesystem::is_directory(path)) {
        const auto scan = scanDicomFolder(path);
        if (a.info && a.series.empty()) {
            printSeriesJson(scan);
            return std::nullopt;
        }
        const DicomSeriesInfo* chosen = nullptr;
        for (const auto& s : scan.series)
            if (a.series.empty() ? (!chosen || s.frameCount > chosen->frameCount)
                                 : (s.key == a.series || s.seriesUid == a.series))
                chosen = &s;
        if (!chosen) throw LoadError(a.input + ": series '" + a.series + "' not found (see --info)");
        if (a.series.empty() && scan.series.size() > 1)
            std::fprintf(stderr, "fvr-render: %zu series in %s; using %s (%d slices); pick one with --series\n",
                         scan.series.size(), a.input.c_str(), chosen->key.c_str(), chosen->frameCount);
        auto loaded = loadDicomSeries(*chosen);
        printWarnings(loaded.warnings);
        g_exportInfo.patientName = chosen->patientName;
        g_exportInfo.patientId = chosen->patientId;
        g_exportInfo.studyInstanceUid = chosen->studyUid;
        return std::move(loaded.volume);
    }
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == ".dcm" || ext == ".dicom" || ext.empty()) {
        auto loaded = loadDicomFile(path);
        printWarnings(loaded.warnings);
        return std::move(loaded.volume);
    }
    return loadVolume(path);
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

std::string settingsJson(const Args& a, const Spectrum& s, double d, int threads, const std::string& backend) {
    std::ostringstream o;
    o << "{\"input\": \"" << jsonEscape(a.input) << "\", \"backend\": \"" << jsonEscape(backend) << "\", \"kernel\": \"" << kernelName(a.kernel)
      << "\", \"transform\": \"" << transformName(a.transform) << "\", \"size\": " << a.size
      << ", \"pixel_size_mm\": " << d << ", \"oversampling\": " << a.oversampling << ", \"values\": \""
      << valueMappingName(a.values) << "\", \"deapodized\": " << (s.deapodizedFor ? "true" : "false")
      << ", \"volume_dims\": [" << s.volumeDims[0] << ", " << s.volumeDims[1] << ", "
      << s.volumeDims[2] << "], \"padded_dims\": [" << s.padded[0] << ", " << s.padded[1] << ", " << s.padded[2]
      << "], \"spectrum_mb\": " << double(s.bytes()) / (1 << 20) << ", \"threads\": " << threads
      << ", \"voxel_model\": \"" << voxelModelName(a.voxelModel) << "\", \"pixel_aperture\": " << (a.pixelAperture ? "true" : "false")
      << ", \"non_negative\": " << (!a.keepNegative && s.nonNegative ? "true" : "false")
      << ", \"clip_to_volume\": " << (a.clip ? "true" : "false") << ", \"depth_cue\": " << a.depthCue << ", \"filter\": {\"sharpen\": " << a.filter.sharpenAmount
      << ", \"sharpen_radius_mm\": " << a.filter.sharpenSigmaMm << ", \"band_limit_lp_per_mm\": "
      << a.filter.bandLimitLpMm << "}}";
    return o.str();
}

/** Views from --views FILE: "dx dy dz ux uy uz" per line. Throws SettingsError naming file:line. */
std::vector<ViewFrame> readViewsFile(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw LoadError(path + ": cannot open the views file");
    std::vector<ViewFrame> views;
    std::string line;
    int n = 0;
    while (std::getline(in, line)) {
        ++n;
        if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
        std::replace(line.begin(), line.end(), ',', ' ');
        std::istringstream ss(line);
        std::vector<double> v;
        double x;
        while (ss >> x) v.push_back(x);
        if (!ss.eof()) throw SettingsError(path + ":" + std::to_string(n) + ": expected numbers");
        if (v.empty()) continue;
        if (v.size() != 6)
            throw SettingsError(path + ":" + std::to_string(n) + ": expected 6 numbers (dx dy dz ux uy uz), found " +
                                std::to_string(v.size()));
        try {
            views.push_back(ViewFrame::fromDirUp({v[0], v[1], v[2]}, {v[3], v[4], v[5]}));
        } catch (const SettingsError& e) {
            throw SettingsError(path + ":" + std::to_string(n) + ": " + e.what());
        }
    }
    if (views.empty()) throw SettingsError(path + ": no views in the file");
    return views;
}

/** FILE.ext -> FILE_0007.ext */
std::string numberedPath(const std::string& out, std::size_t i) {
    const std::filesystem::path p(out);
    char num[16];
    std::snprintf(num, sizeof num, "_%04zu", i);
    return (p.parent_path() / (p.stem().string() + num + p.extension().string())).string();
}

void writeTextAtomic(const std::string& path, const std::string& text) {
    const std::string tmp = path + ".part";
    {
        std::ofstream o(tmp, std::ios::trunc);
        o << text;
        if (!o) throw WriteError(path + ": write failed");
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        std::remove(tmp.c_str());
        throw WriteError(path + ": cannot move the written file into place");
    }
}

#ifdef FVR_HAVE_GPU
/** A Qt GUI application without windows, an offscreen GL 4.3 context and the GPU renderer. */
struct GpuSession {
    int argc = 1;
    char name[16] = "fvr-render";
    char* argv[2] = {name, nullptr};
    std::unique_ptr<QGuiApplication> app;
    std::unique_ptr<fvr::gpu::OffscreenContext> context;
    std::unique_ptr<fvr::gpu::GpuFourierRenderer> renderer;
    GpuSession() {
        // Try X first, then Qt's offscreen platform; a missing display must not abort the program.
        if (!std::getenv("QT_QPA_PLATFORM")) setenv("QT_QPA_PLATFORM", std::getenv("DISPLAY") ? "xcb;offscreen" : "offscreen", 1);
        if (!std::getenv("XDG_RUNTIME_DIR")) {
            const std::string dir = "/tmp/fvr-runtime-" + std::to_string(getuid());
            mkdir(dir.c_str(), 0700);
            setenv("XDG_RUNTIME_DIR", dir.c_str(), 1);
        }
        app = std::make_unique<QGuiApplication>(argc, argv);
        context = std::make_unique<fvr::gpu::OffscreenContext>();
        renderer = std::make_unique<fvr::gpu::GpuFourierRenderer>();
    }
    ~GpuSession() {
        if (renderer && context) {
            context->makeCurrent();
            renderer.reset();
        }
        context.reset();
        app.reset();
    }
};
#endif

int run(int argc, char** argv) {
    const Args a = parseArgs(argc, argv);
    auto loadedInput = loadInput(a);
    if (!loadedInput) return 0; // DICOM folder --info: the series list was printed
    const Volume volume = std::move(*loadedInput);
    if (a.info) {
        printInfo(volume);
        if (a.out.empty() && a.bench <= 0) return 0;
    }
    PreprocessOptions po;
    po.mapping = a.values;
    po.transform = a.transform;
    po.oversampling = a.oversampling;
    po.threads = a.threads;
    const bool kbKernel = a.kernel == Kernel::KaiserBessel4 || a.kernel == Kernel::KaiserBessel6;
    if (a.deapodize.value_or(kbKernel)) po.deapodizeFor = a.kernel;
    else if (kbKernel)
        std::fprintf(stderr, "fvr-render: warning: kaiser-bessel without deapodization is less accurate than trilinear\n");
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
    const int threads = a.threads > 0 ? a.threads : hardwareThreads();
    const ViewFrame base = a.view ? patientViewFrame(volume, *a.view) : ViewFrame::fromDirUp(a.dir, a.up);

#ifdef FVR_HAVE_GPU
    GpuSession* gpu = nullptr;
    std::unique_ptr<GpuSession> gpuHolder;
    if (a.gpu) {
        try {
            gpuHolder = std::make_unique<GpuSession>();
            gpuHolder->renderer->setSpectrum(spectrum, a.fp16 ? fvr::gpu::SpectrumPrecision::Float16
                                                              : fvr::gpu::SpectrumPrecision::Float32);
            gpu = gpuHolder.get();
        } catch (const std::exception& e) {
            gpuHolder.reset();
            std::fprintf(stderr, "fvr-render: GPU backend unavailable (%s); rendering on the CPU\n", e.what());
        }
    }
#else
    if (a.gpu) std::fprintf(stderr, "fvr-render: built without the GPU renderer; rendering on the CPU\n");
#endif
    std::unique_ptr<CpuFourierRenderer> cpu;
    std::string backendName = "cpu";
#ifdef FVR_HAVE_GPU
    if (gpu) backendName = "gpu: " + gpu->renderer->rendererInfo() + (a.fp16 ? ", fp16" : "");
#endif
    if (backendName == "cpu") cpu = std::make_unique<CpuFourierRenderer>(spectrum, a.threads);

    // Every view is rendered with the same settings (the CPU and the GPU renderer take the same).
    auto params = [&](const ViewFrame& view) {
        RenderParams p{view, geom, a.kernel};
        p.depthCue = a.depthCue;
        p.filter = a.filter;
        p.clipToVolume = a.clip;
        p.voxelModel = a.voxelModel;
        p.pixelAperture = a.pixelAperture;
        p.nonNegative = !a.keepNegative;
        return p;
    };
    validateRenderParams(params(base));
    // One view on whichever renderer runs (the line integrals, before any transmission).
    auto renderOne = [&](const ViewFrame& view) {
#ifdef FVR_HAVE_GPU
        if (gpu) return gpu->renderer->render(params(view));
#endif
        return cpu->render(params(view));
    };

    if (a.bench > 0) {
        std::vector<double> sl, inv, tot, fusedTot;
        auto viewAt = [&](int i) {
            // Views over a cone of directions, so the spectrum is read along varied planes.
            return base.rotated({0.3, 1.0, 0.2}, 2.0 * std::numbers::pi * i / a.bench);
        };
        if (cpu) {
            cpu->render(params(base)); // warm-up: plans and buffers
            for (int i = 0; i < a.bench; ++i) {
                StageTimes t;
                cpu->render(params(viewAt(i)), &t);
                sl.push_back(t.sliceMs);
                inv.push_back(t.inverseMs);
                tot.push_back(t.totalMs);
            }
        }
#ifdef FVR_HAVE_GPU
        else {
            auto& r = *gpu->renderer;
            // Fused as the workstation renders a frame: slice in the row pass, display mapping
            // (line integrals to an 8-bit texture) in the last pass.
            const DisplayWindow window{0.0, 1.0, false, {}};
            for (bool fuse : {false, true}) {
                r.setFuseSlice(fuse);
                r.renderToGpu(params(base), fuse ? &window : nullptr); // warm-up: shader compilation, buffers
                r.lastTimes();
                for (int i = 0; i < a.bench; ++i) {
                    r.renderToGpu(params(viewAt(i)), fuse ? &window : nullptr);
                    const auto t = r.lastTimes(); // GPU timer queries
                    if (fuse) fusedTot.push_back(t.totalMs);
                    else {
                        sl.push_back(t.sliceMs);
                        inv.push_back(t.inverseMs);
                        tot.push_back(t.totalMs);
                    }
                }
            }
        }
#endif
        const Stat s1 = stats(sl), s2 = stats(inv), s3 = stats(tot);
        std::printf("{\n  \"settings\": %s,\n  \"frames\": %d,\n",
                    settingsJson(a, *spectrum, d, threads, backendName).c_str(), a.bench);
        std::printf("  \"preprocess\": {\"median_ms\": %.3f, \"p95_ms\": %.3f},\n", preprocessMs, preprocessMs);
        std::printf("  \"slice\": {\"median_ms\": %.3f, \"p95_ms\": %.3f},\n", s1.median, s1.p95);
        std::printf("  \"inverse\": {\"median_ms\": %.3f, \"p95_ms\": %.3f},\n", s2.median, s2.p95);
        std::printf("  \"total\": {\"median_ms\": %.3f, \"p95_ms\": %.3f, \"fps\": %.1f}", s3.median, s3.p95,
                    1000.0 / s3.median);
        double fvrMs = s3.median;
        if (!fusedTot.empty()) {
            const Stat s4 = stats(fusedTot);
            fvrMs = s4.median;
            std::printf(",\n  \"total_fused\": {\"median_ms\": %.3f, \"p95_ms\": %.3f, \"fps\": %.1f, "
                        "\"passes\": \"slice+row FFT, column FFT%s+display\"}",
                        s4.median, s4.p95, 1000.0 / s4.median, spectrum->kind == TransformKind::Fht ? ", eq. 4" : "");
        }
        // The same views by ray casting (the spatial reference projector, all cores), in this run,
        // with the same voxel model, depth cueing and pixel sampling, and the accuracy against it.
        // It cannot apply the slice filters: said below, and then only the timings compare.
        const SpatialProjectorOptions spo = matchingProjectorOptions(params(base), a.values, a.threads);
        SpatialProjector sp(volume, spo);
        std::vector<double> spatialMs;
        std::ostringstream psnr, lowest;
        const int spatialViews = std::min(a.bench, 3);
        for (int i = 0; i < spatialViews; ++i) {
            const auto t0 = std::chrono::steady_clock::now();
            const ProjectionImage ref = sp.project(viewAt(i), geom);
            spatialMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
            const ProjectionImage img = renderOne(viewAt(i));
            psnr << (i ? ", " : "") << numberText(std::round(compareImages(img.pixels, ref.pixels).psnr * 100) / 100);
            lowest << (i ? ", " : "") << numberText(std::round(mostNegativeFraction(img.pixels) * 1e5) / 1e3);
        }
        const Stat s5 = stats(spatialMs);
        std::printf(",\n  \"spatial_projector\": {\"median_ms\": %.3f, \"views\": %d, \"reference\": \"%s\"},"
                    "\n  \"speedup_per_view\": %.1f",
                    s5.median, spatialViews, jsonEscape(describeProjector(spo, a.voxelModel)).c_str(), s5.median / fvrMs);
        if (a.filter.active())
            std::printf(",\n  \"note\": \"the spatial projector cannot apply the slice filter (--sharpen, --band-limit): "
                        "it ray-casts unfiltered images, so only the timings compare, not the images\"");
        else
            std::printf(",\n  \"accuracy\": {\"psnr_db\": [%s], \"most_negative_percent\": [%s]}", psnr.str().c_str(),
                        lowest.str().c_str());
        std::printf("\n}\n");
    }
    if (!a.out.empty()) {
        std::vector<ViewFrame> views{base};
        if (a.sweep > 0) {
            const auto& dir = volume.direction;
            const Vec3 axis = a.axis ? *a.axis : Vec3{dir[0][2], dir[1][2], dir[2][2]}; // head-feet
            views.clear();
            for (int i = 0; i < a.sweep; ++i) views.push_back(base.rotated(axis, 2.0 * std::numbers::pi * i / a.sweep));
        } else if (!a.viewsFile.empty()) {
            views = readViewsFile(a.viewsFile);
        }
        std::string ext = std::filesystem::path(a.out).extension().string();
        std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
        if (ext != ".npy" && ext != ".pfm" && ext != ".png" && ext != ".dcm")
            throw SettingsError("--out: unknown output format '" + ext + "' (expected .npy, .pfm, .png or .dcm)");
        const std::string valuesText = a.beerLambert ? "transmitted intensity exposure x exp(-mu_water x line integral)"
                                                     : projectionUnits(a.values, volume.units);
        g_exportInfo.valueDescription = valuesText;
        if (a.depthCue > 0) g_exportInfo.valueDescription += "; depth cue " + numberText(a.depthCue);
        if (a.filter.active()) g_exportInfo.valueDescription += "; slice-filtered (sharpen, band limit)";
        const bool stacked = views.size() > 1 && ext == ".npy" && !a.numbered;
        std::vector<float> stack;
        std::vector<std::string> written;
        const int M = a.size;
        const auto t0 = std::chrono::steady_clock::now();
        auto lastReport = t0;
        for (std::size_t i = 0; i < views.size(); ++i) {
            ProjectionImage img = renderOne(views[i]);
            // A Beer-Lambert PNG shows the film, as the workstation does: the window on the log
            // exposure of the signal, bone white (the float outputs hold the intensity itself).
            std::optional<DisplayWindow> film;
            std::vector<float> lineIntegrals;
            if (a.beerLambert && ext == ".png") {
                lineIntegrals = img.pixels;
                std::vector<float> logE = img.pixels;
                applyLogExposure(logE, a.transmission);
                film = autoWindow(logE);
                film->invert = true;
                film->transmission = a.transmission;
            }
            if (a.beerLambert) applyTransmission(img.pixels, a.transmission);
            if (stacked) {
                if (stack.empty()) stack.reserve(views.size() * img.pixels.size());
                stack.insert(stack.end(), img.pixels.begin(), img.pixels.end());
            } else {
                const std::string path = views.size() > 1 ? numberedPath(a.out, i) : a.out;
                if (ext == ".png")
                    writePng(path, film ? lineIntegrals.data() : img.pixels.data(), M, M,
                             film ? *film : autoWindow(img.pixels), a.bitDepth);
                else if (ext == ".dcm") writeDicomProjection(path, img, g_exportInfo);
                else writeProjection(path, img);
                written.push_back(path);
            }
            const auto now = std::chrono::steady_clock::now();
            if (views.size() > 1 && (now - lastReport > std::chrono::seconds(1) || i + 1 == views.size())) {
                std::fprintf(stderr, "%sview %zu/%zu%s", isatty(2) ? "\r" : "", i + 1, views.size(), isatty(2) ? "" : "\n");
                lastReport = now;
            }
        }
        if (views.size() > 1 && isatty(2)) std::fprintf(stderr, "\n");
        const double renderMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        if (stacked) {
            writeNpy(a.out, stack.data(), M, M, std::int64_t(views.size()));
            written.push_back(a.out);
        }
        // JSON sidecar: every parameter, so the output can be reproduced and registered.
        std::ostringstream j;
        j << "{\n  \"generator\": \"fvr-render\",\n  \"settings\": " << settingsJson(a, *spectrum, d, threads, backendName)
          << ",\n  \"volume\": {\"name\": \"" << jsonEscape(volume.name) << "\", \"dims\": [" << volume.dims[0] << ", "
          << volume.dims[1] << ", " << volume.dims[2] << "], \"spacing_mm\": " << vecJson(volume.spacing)
          << ", \"origin_mm\": " << vecJson(volume.origin) << ", \"direction\": [" << vecJson(volume.direction[0]) << ", "
          << vecJson(volume.direction[1]) << ", " << vecJson(volume.direction[2]) << "], \"units\": \""
          << unitsName(volume.units) << "\"},\n  \"output\": {\"values\": \""
          << valuesText << "\", \"mu_water_per_mm\": " << (a.beerLambert ? a.transmission.muWaterPerMm : 0.0)
          << ", \"energy_kev\": " << (a.beerLambert && a.energy ? numberText(*a.energy) : std::string("null"))
          << ", \"exposure\": " << (a.beerLambert ? a.transmission.exposure : 0.0)
          << ", \"stacked\": " << (stacked ? "true" : "false")
          << ", \"files\": [";
        for (std::size_t i = 0; i < written.size(); ++i) j << (i ? ", " : "") << "\"" << jsonEscape(written[i]) << "\"";
        j << "], \"preprocess_ms\": " << preprocessMs << ", \"render_ms_per_view\": " << renderMs / double(views.size())
          << "},\n  \"image\": {\"size\": " << M << ", \"pixel_size_mm\": " << d
          << ", \"pixel\": \"(col, row) is the line integral along dir through centre + (col - M/2) d right - (row - M/2) d up\"},"
          << "\n  \"views\": [";
        for (std::size_t i = 0; i < views.size(); ++i)
            j << (i ? "," : "") << "\n    {\"dir\": " << vecJson(views[i].d) << ", \"up\": " << vecJson(views[i].u)
              << ", \"right\": " << vecJson(views[i].r) << "}";
        j << "\n  ]\n}\n";
        writeTextAtomic(a.out + ".json", j.str());
        std::fprintf(stderr, "wrote %s%s (%zu view%s, %dx%d, pixel %.4g mm, %s, %s, %s, %s; %.2f ms per view)\n",
                     stacked || views.size() == 1 ? a.out.c_str() : numberedPath(a.out, 0).c_str(),
                     views.size() > 1 && !stacked ? " ..." : "", views.size(), views.size() > 1 ? "s" : "", M, M, d,
                     kernelName(a.kernel), transformName(a.transform),
                     a.beerLambert ? "transmission" : projectionUnits(a.values, volume.units).c_str(), backendName.c_str(),
                     renderMs / double(views.size()));
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
