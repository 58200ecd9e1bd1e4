// fvr-render's command line: every option declared once, with its help, its check and its group.
#include "options.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iostream>
#include <sstream>
#include <tuple>
#include <vector>

#include <CLI/CLI.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/render/view.h>
#include <fvr/core/text.h>

#include "pacs.h"

namespace fvr::cli {
namespace {

using core::SettingsError;

/** The defaults, as the help states them. */
const core::RenderSettings kDefaults;

std::string defaultText(const std::string& value) { return "(default " + value + ")"; }

std::string shortNumber(double v) {
    std::ostringstream out;
    out << v;
    return out.str();
}

const char* kUsage = R"(usage: fvr-render INPUT [options] --out FILE
       fvr-render INPUT --info
       fvr-render INPUT --bench N [options]
       fvr-render --gpu-info
       fvr-render dicom://AE@host:port --query KEY=VALUE[,KEY=VALUE...]

INPUT is a DICOM folder, its DICOMDIR or one DICOM file, a volume file (.mhd, .mha, .nii,
.nii.gz; values without units that look like CT are taken for HU), a headerless raw file with
--raw-dims, or a built-in phantom in HU with N^3 voxels: phantom:chest[:N] (an adult chest,
420 mm field, default N 160; try --view AP) or phantom:shepp-logan[:N] (3D Shepp-Logan, 256 mm
field, default N 128). The workstation opens paths by the same rule. INPUT may also be a
study (or series) on a PACS, dicom://CALLED_AE@host:port/STUDY_UID[/SERIES_UID]: retrieved
into the local study store (see --store), then opened like a folder.
)";

const char* kFooter =
    R"(JSON outputs (--info, --bench, the sidecar FILE.json) write numbers at full precision (they
read back to the same double) and write null for a number that is not finite (an infinite
value in a volume, the PSNR of identical images).
Exit status: 0 success, 2 bad input or settings, 1 other failure.)";

/** The help's usage lines are fvr-render's own (CLI11 would print "[OPTIONS] INPUT" only). */
class HelpFormatter : public CLI::Formatter {
public:
    std::string make_usage(const CLI::App*, std::string) const override { return kUsage; }
    /** One blank line between the option groups (CLI11 2.1 writes two). */
    std::string make_help(const CLI::App* app, std::string name,
                          CLI::AppFormatMode mode) const override {
        std::string text = CLI::Formatter::make_help(app, std::move(name), mode);
        for (std::size_t at; (at = text.find("\n\n\n")) != std::string::npos;) text.erase(at, 1);
        return text;
    }
};

/** A finite number, or nothing. */
std::optional<double> toNumber(const std::string& s) {
    const auto v = core::parseNumber<double>(s);
    if (!v || !std::isfinite(*v)) return std::nullopt;
    return v;
}

/** "x,y,z" as three finite numbers, or nothing. */
std::optional<core::Vec3> toVec3(const std::string& s) {
    std::vector<double> v;
    std::stringstream ss(s);
    std::string tok;
    while (std::getline(ss, tok, ',')) {
        const auto x = toNumber(tok);
        if (!x) return std::nullopt;
        v.push_back(*x);
    }
    if (v.size() != 3) return std::nullopt;
    return core::Vec3{v[0], v[1], v[2]};
}

/** Checks a number: finite, then `ok` (message "<expected>, found <value>"). CLI11 puts the
 *  option's name in front of the message. */
CLI::Validator numberCheck(std::function<bool(double)> ok = {}, std::string expected = {}) {
    return CLI::Validator(
        [ok = std::move(ok), expected = std::move(expected)](std::string& s) -> std::string {
            const auto v = toNumber(s);
            if (!v) return "expected a number, found '" + s + "'";
            if (ok && !ok(*v)) return expected + ", found " + s;
            return {};
        },
        "");
}

/** Checks a value with a core function that throws SettingsError ("what: expected ...");
 *  the message without its "what: " (the option's name takes its place). */
template <class Check>
CLI::Validator coreCheck(Check check) {
    return CLI::Validator(
        [check](std::string& s) -> std::string {
            try {
                check(s);
                return {};
            } catch (const SettingsError& e) {
                const std::string m = e.what();
                const auto colon = m.find(": ");
                return colon != std::string::npos && colon < m.find('\'') ? m.substr(colon + 2) : m;
            }
        },
        "");
}

/** An option whose value a core parser turns into `target` (an enum, optional or not). */
template <class Target, class Parse>
CLI::Option* addParsed(CLI::App& app, const std::string& name, Target& target, Parse parse,
                       const std::string& text, const std::string& help) {
    return app
        .add_option_function<std::string>(
            name, [&target, parse](const std::string& s) { target = parse(s); }, help)
        ->check(coreCheck(parse))
        ->option_text(text);
}

/** An "x,y,z" option. */
template <class Target>
CLI::Option* addVec3(CLI::App& app, const std::string& name, Target& target,
                     const std::string& help) {
    return app
        .add_option_function<std::string>(
            name, [&target](const std::string& s) { target = *toVec3(s); }, help)
        ->check(CLI::Validator(
            [](std::string& s) -> std::string {
                return toVec3(s) ? "" : "expected x,y,z, found '" + s + "'";
            },
            ""))
        ->option_text("x,y,z");
}

/** A number option (`double` or `std::optional<double>`) checked by numberCheck. */
template <class Target>
CLI::Option* addNumber(CLI::App& app, const std::string& name, Target& target,
                       const std::string& text, const std::string& help,
                       std::function<bool(double)> ok = {}, std::string expected = {}) {
    return app
        .add_option_function<std::string>(
            name, [&target](const std::string& s) { target = *toNumber(s); }, help)
        ->check(numberCheck(std::move(ok), std::move(expected)))
        ->option_text(text);
}

/** One slice filter setting, checked by the core rule on its own so that the message names
 *  the option. */
CLI::Option* addFilterNumber(CLI::App& app, const std::string& name, core::SliceFilter& filter,
                             double core::SliceFilter::*field, const std::string& text,
                             const std::string& help) {
    return app
        .add_option_function<std::string>(
            name, [&filter, field](const std::string& s) { filter.*field = *toNumber(s); }, help)
        ->check(numberCheck())
        ->check(coreCheck([field](const std::string& s) {
            core::SliceFilter f;
            f.*field = *toNumber(s);
            core::validateSliceFilter(f);
        }))
        ->option_text(text);
}

OutputFormat outputFormat(const std::string& path) {
    const std::string ext = core::asciiLower(std::filesystem::path(path).extension().string());
    if (ext == ".npy") return OutputFormat::Npy;
    if (ext == ".pfm") return OutputFormat::Pfm;
    if (ext == ".png") return OutputFormat::Png;
    if (ext == ".dcm") return OutputFormat::Dicom;
    throw SettingsError("--out: unknown output format '" + ext +
                        "' (expected .npy, .pfm, .png or .dcm)");
}

/** What the command line fills in: the options and the raw-file settings gathered apart. */
struct Parsing {
    Options o;
    core::RawSpec raw;
};

/** --preset: applied as it is parsed (the other options' values are set once the whole line is
 *  parsed), so that the options given with it win wherever they stand. */
void declarePreset(CLI::App& app, Options& o) {
    std::string names;
    for (const auto& n : core::RenderSettings::presetNames())
        names += (names.empty() ? "" : "|") + n;
    addParsed(app, "--preset", o.settings, core::RenderSettings::preset, names,
              "a set of rendering settings that the options given with it change:\n"
              "default (the workstation's picture: AP view, mu for Hounsfield data,\n"
              "kaiser-bessel4 with gridding correction at 1.25x, trilinear voxel\n"
              "model, clipped, non-negative) | paper (the paper's Table 1: linear,\n"
              "1x, raw values, band-limited, no correction, no clipping)")
        ->trigger_on_parse()
        ->group("Rendering");
}

void declareInput(CLI::App& app, Parsing& p) {
    const std::string g = "Input";
    app.add_option("INPUT", p.o.input, "DICOM folder or file, volume file, raw file or phantom")
        ->option_text(" ");
    app.add_option("--series", p.o.series,
                   "the series to load from a DICOM folder, by key or UID (default: the\n"
                   "loadable one with most slices, as in the workstation); --info lists the\n"
                   "folder's series as JSON, the default one marked")
        ->option_text("UID")
        ->group(g);
    app.add_option_function<std::string>(
           "--raw-dims",
           [&p](const std::string& s) {
               const core::Vec3 d = *toVec3(s);
               p.raw.dims = {std::int64_t(d[0]), std::int64_t(d[1]), std::int64_t(d[2])};
           },
           "INPUT is a headerless raw file of these dimensions")
        ->check(CLI::Validator(
            [](std::string& s) -> std::string {
                return toVec3(s) ? "" : "expected x,y,z, found '" + s + "'";
            },
            ""))
        ->option_text("NX,NY,NZ")
        ->group(g);
    addParsed(app, "--raw-type", p.raw.type, core::parseElementType, "T",
              "raw element type: int8|uint8|int16|uint16|int32|uint32|int64|uint64|\n"
              "float32|float64 (default int16)")
        ->group(g);
    addVec3(app, "--raw-spacing", p.raw.spacing, "raw voxel spacing in mm (default 1,1,1)")
        ->option_text("sx,sy,sz")
        ->group(g);
    app.add_flag("--raw-big-endian", p.raw.bigEndian, "raw values are big-endian")->group(g);
    app.add_option("--raw-header", p.raw.headerBytes, "bytes to skip at the start of the raw file")
        ->option_text("BYTES")
        ->group(g);
}

void declareView(CLI::App& app, Options& o) {
    const std::string g = "View and image";
    CLI::Option* dir =
        addVec3(app, "--dir", o.dir,
                "viewing direction in the volume frame, instead of --view (with --up\n"
                "0,-1,0 if not given: 0,0,1 is the plain sum of the slices, as stored)")
            ->group(g);
    CLI::Option* up = addVec3(app, "--up", o.up, "up vector with --dir (default 0,-1,0)")->group(g);
    // A patient view sets both: with --dir or --up as well, one of them would be ignored.
    addParsed(app, "--view", o.settings.view, core::parsePatientView, "V",
              "patient view from the direction cosines (instead of --dir/--up):\n"
              "AP | PA | LEFT | RIGHT | HEAD | FEET (AP: from anterior, head up,\n"
              "patient's left on the image's right) " +
                  defaultText(core::patientViewName(kDefaults.view)))
        ->group(g)
        ->excludes(dir)
        ->excludes(up);
    app.add_option("--size", o.settings.size,
                   "slice/image size, power of two " + std::to_string(kDefaults.kMinSize) + ".." +
                       std::to_string(kDefaults.kMaxSize) + " " +
                       defaultText(std::to_string(kDefaults.size)))
        ->check(coreCheck([](const std::string& s) {
            const auto m = core::parseNumber<int>(s);
            if (!m) throw SettingsError("size: expected a whole number, found '" + s + "'");
            core::validateSettingsSize(*m);
        }))
        ->option_text("M")
        ->group(g);
    addNumber(
        app, "--pixel-size", o.settings.pixelSize, "mm",
        "output pixel size (default: volume diagonal / M, no overlapping copies)",
        [](double v) { return v > 0; }, "expected a positive number of mm")
        ->group(g);
}

void declareSpectrum(CLI::App& app, Options& o) {
    const std::string g = "Rendering";
    addParsed(app, "--kernel", o.settings.kernel, core::parseKernel, "K",
              "nearest | linear | bspline | catmull-rom | sinc4 | kaiser-bessel\n" +
                  defaultText(core::kernelName(kDefaults.kernel)))
        ->group(g);
    app.add_option("--kernel-width", o.kernelWidth, "kaiser-bessel width: 4 or 6")
        ->check(CLI::IsMember({4, 6}))
        ->option_text("W")
        ->group(g);
    app.add_option_function<std::string>(
           "--deapodize", [&o](const std::string& s) { o.settings.deapodize = s == "on"; },
           "divide the volume by the kernel's Fourier transform before the 3D FFT\n"
           "(gridding correction; default on for every kernel but linear, which does\n"
           "not gain from it: core::griddingCorrectionHelps; off in --preset paper)")
        ->check(CLI::IsMember({"on", "off"}))
        ->option_text("on|off")
        ->group(g);
    addParsed(app, "--transform", o.settings.transform, core::parseTransform, "T",
              "fft | fht " + defaultText(core::transformName(kDefaults.transform)))
        ->group(g);
    addNumber(
        app, "--oversampling", o.settings.oversampling, "f",
        "zero-padding factor 1..2 " + defaultText(shortNumber(kDefaults.oversampling)) +
            "; 1 in the paper",
        [](double v) { return v >= 1 && v <= 2; }, "expected a factor in [1, 2]")
        ->group(g);
    addParsed(app, "--values", o.settings.values, core::parseValueMapping, "V",
              "raw (stored values) | mu (attenuation rel. water, max(0,1+HU/1000)) |\n"
              "mu-bone (as mu up to +100 HU, twice as steep above: bone stands out)\n" +
                  defaultText(core::valueMappingName(kDefaults.values)) +
                  " for Hounsfield data; data in other units integrate their\nraw values")
        ->group(g);
}

void declareModel(CLI::App& app, Options& o) {
    const std::string g = "Rendering";
    addParsed(app, "--voxel-model", o.settings.voxelModel, core::parseVoxelModel, "V",
              "what lies between the voxels: trilinear (the projection a trilinear\n"
              "DRR ray caster computes, no ringing) | bspline (the cubic B-spline\n"
              "through the voxels) | bandlimited (the plain FVR image, sharpest,\n"
              "rings at scan ends and between coarse slices) " +
                  defaultText(core::voxelModelName(kDefaults.voxelModel)))
        ->group(g);
    app.add_flag("--pixel-aperture", o.settings.pixelAperture,
                 "detector pixels integrate over their area (sinc per image axis)\n"
                 "instead of sampling the projection at their centres")
        ->group(g);
    CLI::Option* noClip =
        app.add_flag_callback(
               "--no-clip", [&o] { o.settings.clip = false; },
               "keep what FVR puts outside the volume's shadow (ghost copies, ringing);\n"
               "by default pixels whose ray misses the voxel model's support are 0,\n"
               "as they truly are")
            ->group(g);
    app.add_flag_callback(
           "--clip", [&o] { o.settings.clip = true; },
           "the default's clipping, with a --preset that has none (paper)")
        ->excludes(noClip)
        ->group(g);
    CLI::Option* keepNegative =
        app.add_flag_callback(
               "--keep-negative", [&o] { o.settings.nonNegative = false; },
               "keep negative line integrals of a volume without negative values\n"
               "(mu values, or raw data >= 0); by default they are 0, as they truly are")
            ->group(g);
    app.add_flag_callback(
           "--non-negative", [&o] { o.settings.nonNegative = true; },
           "the default's non-negative line integrals, with a --preset that keeps\n"
           "negative ones (paper)")
        ->excludes(keepNegative)
        ->group(g);
    addNumber(
        app, "--depth-cue", o.settings.depthCue, "S",
        "depth cueing strength 0..1 (default 0): weight 1 at the front of the\n"
        "volume's bounding sphere falling linearly to 1-S at its back (not with\n"
        "--kernel nearest)",
        [](double v) { return v >= 0 && v <= 1; }, "expected a strength in 0..1")
        ->group(g);
    addFilterNumber(app, "--sharpen", o.settings.filter, &core::SliceFilter::sharpenAmount, "A",
                    "unsharp mask on the slice: image + A x (image - Gaussian blur),\n"
                    "A >= 0 (default 0, off)")
        ->group(g);
    addFilterNumber(app, "--sharpen-radius", o.settings.filter, &core::SliceFilter::sharpenSigmaMm,
                    "mm", "sigma of the unsharp mask's Gaussian (default 1.0)")
        ->group(g);
    addFilterNumber(app, "--band-limit", o.settings.filter, &core::SliceFilter::bandLimitLpMm,
                    "lp/mm",
                    "order-8 Butterworth low-pass, -3 dB at this frequency (default 0, off)")
        ->group(g);
}

void declareBackend(CLI::App& app, Options& o) {
    const std::string g = "Rendering";
    app.add_option_function<std::string>(
           "--backend",
           [&o](const std::string& s) {
               o.backend = s == "gpu"   ? Options::Backend::Gpu
                           : s == "cpu" ? Options::Backend::Cpu
                                        : Options::Backend::Auto;
           },
           "renderer (default auto: the GPU when it is hardware, else the CPU, saying why on\n"
           "stderr: a software OpenGL such as llvmpipe is slower than the CPU renderer);\n"
           "gpu renders headless (EGL, no X server) with OpenGL 4.3 compute shaders even\n"
           "on a software renderer, and falls back to the CPU, saying why, when no GPU is\n"
           "usable; FVR_EGL_DEVICE=N|surfaceless picks the EGL device")
        ->check(CLI::IsMember({"auto", "cpu", "gpu"}))
        ->option_text("auto|cpu|gpu")
        ->group(g);
    app.add_flag("--fp16", o.fp16, "GPU: store the spectrum as float16 (2 bytes per voxel)")
        ->group(g);
    app.add_flag("--gpu-info", o.gpuInfo,
                 "print the EGL devices, the one --backend gpu takes and its OpenGL facts as\n"
                 "JSON (no INPUT needed)")
        ->group(g);
    app.add_option("--threads", o.threads, "worker threads (default: all cores)")
        ->check(numberCheck([](double v) { return v >= 0 && v <= 4096 && v == std::floor(v); },
                            "expected a whole number of threads in 0..4096 (0: all cores)"))
        ->option_text("N")
        ->group(g);
}

void declareViews(CLI::App& app, Options& o) {
    const std::string g = "Many views (DRRs)";
    auto* sweep = app.add_option("--sweep", o.sweep,
                                 "N views rotating about --axis (default: the patient's\n"
                                 "head-feet axis) from --view/--dir (without them: AP, or\n"
                                 "LEFT, or HEAD, the first across the axis)")
                      ->check(CLI::Range(0, 100000))
                      ->option_text("N")
                      ->group(g);
    addVec3(app, "--axis", o.axis, "rotation axis of --sweep in the volume frame")->group(g);
    app.add_option("--views", o.viewsFile,
                   "one view per line: dx dy dz ux uy uz (commas or spaces; # comments)")
        ->option_text("FILE")
        ->excludes(sweep)
        ->group(g);
    app.add_flag("--numbered", o.numbered,
                 "with several views and a .npy output: numbered files, not one stack")
        ->group(g);
}

void declareOutput(CLI::App& app, Options& o) {
    const std::string g = "Output";
    app.add_option_function<std::string>(
           "--out",
           [&o](const std::string& s) {
               o.out = s;
               o.format = outputFormat(s);
           },
           ".npy (float32 line integrals, shape (M, M), row 0 at the top; several\n"
           "views: one stacked (N, M, M) file), .pfm (float, rows bottom-to-top),\n"
           ".png (display-mapped, auto window), .dcm (DICOM secondary capture;\n"
           "--geometry cone: X-ray angiographic, carrying the C-arm; a run: one file);\n"
           "several views and .pfm/.png/.dcm: FILE_0000.ext, FILE_0001.ext, ...\n"
           "A JSON sidecar FILE.json records every parameter and view. The files land\n"
           "together or not at all: an interrupted or failed run leaves an earlier run's\n"
           "files as they were (a new run replaces all of them, frames it lacks removed).")
        ->check(coreCheck([](const std::string& s) { outputFormat(s); }))
        ->option_text("FILE")
        ->group(g);
    app.add_option("--bit-depth", o.bitDepth, "PNG bit depth (default 8)")
        ->check(CLI::IsMember({8, 16}))
        ->option_text("8|16")
        ->group(g);
    app.add_flag("--info", o.info, "print the volume's facts as JSON")->group(g);
}

void declareXray(CLI::App& app, Options& o) {
    const std::string g = "X-ray";
    auto* beer = app.add_flag("--beer-lambert", o.beerLambert,
                              "with --values mu or mu-bone: transmitted intensity\n"
                              "exposure x exp(-mu_water x integral) instead of line integrals\n"
                              "(a radiograph's physics)")
                     ->group(g);
    auto* muWater = addNumber(
                        app, "--mu-water", o.muWater, "1/mm",
                        "linear attenuation of water for --beer-lambert (default: that of\n"
                        "--energy)",
                        [](double v) { return v > 0 && v < 10; }, "expected 0..10 per mm")
                        ->group(g);
    addNumber(app, "--energy", o.energy, "keV",
              "photon energy 20..150 for --beer-lambert: mu_water from the NIST XCOM\n"
              "table (instead of --mu-water; 0.02059 per mm at 60 keV) " +
                  defaultText(shortNumber(kDefaults.energyKeV)))
        ->check(coreCheck([](const std::string& s) { core::waterAttenuationPerMm(*toNumber(s)); }))
        ->excludes(muWater)
        ->needs(beer)
        ->group(g);
    addNumber(
        app, "--exposure", o.exposure, "X",
        "beam intensity for --beer-lambert, > 0 (default 1: full scale)",
        [](double v) { return v > 0; }, "expected a positive beam intensity")
        ->needs(beer)
        ->group(g);
}

/** Polychromatic X-ray options: TASMIP spectrum, materials, detector and noise. */
void declarePolychromatic(CLI::App& app, Options& o) {
    const std::string g = "Polychromatic X-ray";
    auto* kvp = addNumber(
                    app, "--kvp", o.kvp, "KV",
                    "tube voltage 30..140 (TASMIP spectrum): the output holds I/I0 of\n"
                    "the spectral sum over materials from the CT numbers (HU input)",
                    [](double v) { return v >= 30 && v <= 140; }, "expected 30..140 kV")
                    ->excludes("--beer-lambert")
                    ->group(g);
    auto mm = [](double v) { return v >= 0 && v <= 100; };
    addNumber(app, "--filtration-al", o.filtrationAlMm, "MM",
              "added aluminium filtration (default 0; TASMIP's tube has about 1 mm Al)", mm,
              "expected 0..100 mm")
        ->needs(kvp)
        ->group(g);
    addNumber(app, "--filtration-cu", o.filtrationCuMm, "MM", "added copper filtration (default 0)",
              mm, "expected 0..100 mm")
        ->needs(kvp)
        ->group(g);
    addParsed(
        app, "--detector", o.detector.kind,
        [](const std::string& s) {
            if (s == "energy") return core::DetectorKind::EnergyIntegrating;
            if (s == "counting") return core::DetectorKind::PhotonCounting;
            throw SettingsError("detector: expected energy or counting, found '" + s + "'");
        },
        "energy|counting", "energy-integrating (w = E, default) or photon-counting (w = 1)")
        ->needs(kvp)
        ->group(g);
    addNumber(
        app, "--csi-um", o.detector.csiUm, "UM",
        "CsI absorber thickness (default 0: ideal detector)",
        [](double v) { return v >= 0 && v <= 10000; }, "expected 0..10000 um")
        ->needs(kvp)
        ->group(g);
    addParsed(app, "--materials", o.materials, core::parseMaterials, "LIST",
              "materials from air,lung,fat,soft,bone (default air,soft,bone)")
        ->needs(kvp)
        ->group(g);
    addNumber(
        app, "--noise-mas", o.noiseMas, "MAS",
        "Poisson quantum noise for this exposure at 1 m (default 0: none)",
        [](double v) { return v >= 0 && v <= 1e6; }, "expected 0..1e6 mAs")
        ->needs(kvp)
        ->group(g);
    addNumber(
        app, "--electronic-noise", o.electronicNoise, "Q",
        "with --noise-mas: Gaussian electronic noise, standard deviation in\n"
        "quanta per pixel (default 0)",
        [](double v) { return v >= 0 && v <= 1e9; }, "expected 0..1e9 quanta")
        ->needs("--noise-mas")
        ->group(g);
    app.add_option("--seed", o.seed, "seed of the noise (default 1)")->needs(kvp)->group(g);
    app.add_option("--material-out", o.materialOut,
                   "also write the material mass thicknesses rhoL (g/cm^2) as a float32\n"
                   "(k, M, M) .npy, in the order of settings.materials (one view)")
        ->needs(kvp)
        ->option_text("FILE.npy")
        ->group(g);
}

void declareBenchmark(CLI::App& app, Options& o) {
    app.add_option("--bench", o.bench,
                   "render N frames over varying views, print per-stage timings as JSON,\n"
                   "and the same views by ray casting (spatial projector) with the speed-up")
        ->check(numberCheck([](double v) { return v >= 0 && v == std::floor(v); },
                            "expected a whole number of frames"))
        ->option_text("N")
        ->group("Benchmark");
}

void declareTls(CLI::App& app, Options& o) {
    const std::string g = "PACS";
    CLI::Option* tls =
        app.add_flag("--tls", o.tls,
                     "DICOM TLS to the PACS (INPUT, --send) and for --retrieve move's\n"
                     "listener, which then speaks TLS only; the certificates below")
            ->group(g);
    app.add_option("--tls-cert", o.tlsCert, "our certificate (PEM; with --tls-key)")
        ->option_text("FILE")
        ->needs(tls)
        ->group(g);
    app.add_option("--tls-key", o.tlsKey, "our certificate's private key (PEM, not encrypted)")
        ->option_text("FILE")
        ->needs(tls)
        ->group(g);
    app.add_option("--tls-ca", o.tlsCa,
                   "a CA certificate we trust (PEM; repeatable): the peer's\n"
                   "certificate must be signed by one")
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
        ->option_text("FILE")
        ->needs(tls)
        ->group(g);
    app.add_flag("--tls-no-verify", o.tlsNoVerify,
                 "take any certificate the peer shows (no --tls-ca needed; not\n"
                 "recommended: anyone could pose as the PACS)")
        ->needs(tls)
        ->group(g);
}

void declarePacs(CLI::App& app, Options& o) {
    const std::string g = "PACS";
    app.add_option("--ae-title", o.aeTitle, "our AE title (the calling AE; default FVR)")
        ->option_text("AE")
        ->group(g);
    app.add_option_function<std::string>(
           "--retrieve",
           [&o](const std::string& s) {
               o.retrieve =
                   s == "move" ? core::pacs::RetrieveMethod::Move : core::pacs::RetrieveMethod::Get;
           },
           "how a dicom:// INPUT is retrieved: get (C-GET, default) or move (C-MOVE to\n"
           "our storage listener on --listen-port; the PACS must know our AE title)")
        ->check(CLI::IsMember({"get", "move"}))
        ->option_text("get|move")
        ->group(g);
    app.add_option("--listen-port", o.listenPort,
                   "our storage listener's port for --retrieve "
                   "move (default 11112)")
        ->check(CLI::Range(1, 65535))
        ->option_text("N")
        ->group(g);
    app.add_option("--listen-address", o.listenAddress,
                   "the IPv4 address our storage listener binds for --retrieve move (default\n"
                   "127.0.0.1: this machine only; 0.0.0.0: every interface, for a PACS on\n"
                   "another machine); it takes only the C-MOVE of the node retrieved from")
        ->option_text("A")
        ->group(g);
    CLI::Option* query =
        app.add_option("--query", o.query,
                       "print the studies on INPUT's PACS that match, as JSON (C-FIND); keys:\n"
                       "PatientName, PatientID, AccessionNumber (wildcards * and ?), Modality,\n"
                       "StudyDate=YYYYMMDD[-YYYYMMDD]; repeatable, or comma-separated")
            ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
            ->option_text("K=V")
            ->group(g);
    app.add_flag("--query-series", o.querySeries, "with --query: each study's series too")
        ->needs(query)
        ->group(g);
    app.add_option("--send", o.send,
                   "store every output view as DICOM Secondary Capture on this PACS\n"
                   "(C-STORE), e.g. dicom://ORTHANC@pacs:4242 (--geometry cone: X-ray\n"
                   "angiographic, carrying the C-arm: a .dcm output's files as written)")
        ->option_text("URL")
        ->group(g);
    app.add_option("--pacs-timeout", o.pacsTimeout,
                   "seconds a PACS may stay silent before a call fails (default 10;\n"
                   "the call then ends within this + 1 s)")
        ->check(CLI::Range(1, 600))
        ->option_text("S")
        ->group(g);
    declareTls(app, o);
    app.add_option("--store", o.store,
                   "the local study store for dicom:// INPUT (default\n"
                   "$XDG_DATA_HOME/fvr-workstation/studies, the workstation's); a study\n"
                   "it lists complete opens without the network")
        ->option_text("DIR")
        ->group(g);
}

/** "a,b" as two finite numbers, or nothing. */
std::optional<std::pair<double, double>> toPair(const std::string& s, char sep = ',') {
    const auto at = s.find(sep);
    if (at == std::string::npos) return std::nullopt;
    const auto a = toNumber(s.substr(0, at)), b = toNumber(s.substr(at + 1));
    if (!a || !b) return std::nullopt;
    return std::pair{*a, *b};
}

/** --detector-size "WxH" (or "N": square), each 16..4096; throws SettingsError. */
std::pair<int, int> parseDetectorSize(const std::string& s) {
    auto whole = [&](const std::string& t) {
        const auto v = core::parseNumber<int>(t);
        if (!v) throw SettingsError("detector size: expected WxH in pixels, found '" + s + "'");
        if (*v < 16 || *v > 4096)
            throw SettingsError("detector size: expected 16..4096 pixels a side, found '" + s +
                                "'");
        return *v;
    };
    const auto x = core::asciiLower(s).find('x');
    if (x == std::string::npos) return {whole(s), whole(s)};
    return {whole(s.substr(0, x)), whole(s.substr(x + 1))};
}

/** --pitch "PU[,PV]", mm, each > 0; throws SettingsError. */
std::pair<double, double> parsePitch(const std::string& s) {
    const auto one = toNumber(s);
    const auto two = toPair(s);
    if (!one && !two) throw SettingsError("pitch: expected PU or PU,PV in mm, found '" + s + "'");
    const auto p = two ? *two : std::pair{*one, *one};
    if (!(p.first > 0) || !(p.second > 0))
        throw SettingsError("pitch: expected a positive number of mm, found '" + s + "'");
    return p;
}

/** --orbit "FROM:TO:N" (degrees, N >= 2 views); throws SettingsError. */
std::tuple<double, double, int> parseOrbit(const std::string& s) {
    const auto bad = [&] {
        return SettingsError("orbit: expected FROM:TO:N (degrees, N >= 2 views), found '" + s +
                             "'");
    };
    const auto a = s.find(':'), b = s.rfind(':');
    if (a == std::string::npos || a == b) throw bad();
    const auto from = toNumber(s.substr(0, a)), to = toNumber(s.substr(a + 1, b - a - 1));
    const auto n = core::parseNumber<int>(s.substr(b + 1));
    if (!from || !to || !n || *n < 2 || *n > 100000) throw bad();
    return {*from, *to, *n};
}

/** The camera options of --geometry cone (checked together in checkGeometry). */
void declareConeCamera(CLI::App& app, ConeOptions& c) {
    const std::string g = "Cone beam (--geometry cone)";
    addNumber(app, "--primary-angle", c.arm.primaryDeg, "DEG",
              "C-arm primary angle, DICOM's PositionerPrimaryAngle: LAO +, RAO -\n"
              "(default 0: source posterior, detector anterior, the AP position)")
        ->group(g);
    addNumber(
        app, "--secondary-angle", c.arm.secondaryDeg, "DEG",
        "C-arm secondary angle -90..90, DICOM's PositionerSecondaryAngle:\n"
        "cranial +, caudal - (default 0)",
        [](double v) { return v >= -90 && v <= 90; }, "expected -90..90 degrees")
        ->group(g);
    addNumber(
        app, "--sid", c.arm.sid, "MM",
        "source to detector distance (default 1000; 1500 with --beam or --rtplan)",
        [](double v) { return v > 0; }, "expected a positive number of mm")
        ->group(g);
    addNumber(
        app, "--sod", c.arm.sod, "MM", "source to isocentre distance, < SID (default 750)",
        [](double v) { return v > 0; }, "expected a positive number of mm")
        ->group(g);
    app.add_option_function<std::string>(
           "--isocenter",
           [&c](const std::string& s) {
               const core::Vec3 v = *toVec3(s);
               c.isocentre = glm::dvec3(v[0], v[1], v[2]);
           },
           "the isocentre in patient LPS mm (default: the volume's centre)")
        ->check(CLI::Validator(
            [](std::string& s) -> std::string {
                return toVec3(s) ? "" : "expected x,y,z, found '" + s + "'";
            },
            ""))
        ->option_text("X,Y,Z")
        ->group(g);
    app.add_option_function<std::string>(
           "--detector-size",
           [&c](const std::string& s) { std::tie(c.width, c.height) = parseDetectorSize(s); },
           "detector columns x rows, 16..4096 each (default: --size square)")
        ->check(coreCheck(parseDetectorSize))
        ->option_text("WxH")
        ->group(g);
    app.add_option_function<std::string>(
           "--pitch", [&c](const std::string& s) { std::tie(c.pitchU, c.pitchV) = parsePitch(s); },
           "detector pixel pitch in mm, columns[,rows] (default: the volume's\n"
           "diagonal magnified at the isocentre fills the detector)")
        ->check(coreCheck(parsePitch))
        ->option_text("PU[,PV]")
        ->group(g);
    app.add_option_function<std::string>(
           "--principal-point",
           [&c](const std::string& s) {
               const auto p = *toPair(s);
               c.principalOffset = {p.first, p.second};
           },
           "the principal-point offset in pixels (default 0,0): pixel (i, j) lies at\n"
           "the detector centre + (i - (W-1)/2 + DU) pu u + (j - (H-1)/2 + DV) pv v,\n"
           "so the isocentre images at pixel ((W-1)/2 - DU, (H-1)/2 - DV)")
        ->check(CLI::Validator(
            [](std::string& s) -> std::string {
                return toPair(s) ? "" : "expected DU,DV in pixels, found '" + s + "'";
            },
            ""))
        ->option_text("DU,DV")
        ->group(g);
}

/** --geometry-from and --frame: the camera of an X-ray (checked in checkGeometryFrom). */
void declareConeFromXray(CLI::App& app, ConeOptions& c) {
    const std::string g = "Cone beam (--geometry cone)";
    app.add_option("--geometry-from", c.geometryFrom,
                   "the camera of a DICOM X-ray (XA, RF, DX, CR: its C-arm angles, SID, SOD,\n"
                   "detector size and pitch) instead of the C-arm options; the isocentre is\n"
                   "the file's where it states one (a DRR fvr wrote), else --isocenter,\n"
                   "else the volume's centre")
        ->option_text("XRAY.dcm")
        ->group(g);
    app.add_option_function<std::string>(
           "--frame",
           [&c](const std::string& s) {
               c.allFrames = s == "all";
               if (!c.allFrames) c.frame = *core::parseNumber<int>(s);
           },
           "with --geometry-from: the frame whose C-arm places the view, 0-based\n"
           "(default 0), or all (every frame's, one view each)")
        ->check(CLI::Validator(
            [](std::string& s) -> std::string {
                const auto k = core::parseNumber<int>(s);
                return s == "all" || (k && *k >= 0)
                           ? ""
                           : "expected a frame number 0, 1, ... or all, found '" + s + "'";
            },
            ""))
        ->option_text("K|all")
        ->group(g);
}

void declareCone(CLI::App& app, ConeOptions& c) {
    const std::string g = "Cone beam (--geometry cone)";
    app.add_option_function<std::string>(
           "--geometry", [&c](const std::string& s) { c.enabled = s == "cone"; },
           "parallel (default: Fourier volume rendering) | cone (a point source and a\n"
           "flat detector, as a C-arm or a radiograph: ray cast on the CPU)")
        ->check(CLI::IsMember({"parallel", "cone"}))
        ->option_text("parallel|cone")
        ->group(g);
    declareConeCamera(app, c);
    declareConeFromXray(app, c);
    addParsed(app, "--ray-model", c.model, core::parseRayModel, "M",
              "trilinear (default; exact per cell) | bspline (cubic B-spline, sampled)\n"
              "| box (voxels as cubes, exact path lengths: plastimatch drr -i exact)")
        ->group(g);
    addNumber(
        app, "--step", c.step, "F",
        "ray step as a fraction 0..4 of the smallest voxel spacing (trilinear:\n"
        "default 0 = exact; bspline: default 0.25; not for box)",
        [](double v) { return v >= 0 && v <= 4; }, "expected a fraction in 0..4")
        ->group(g);
    app.add_flag("--flat-field", c.flatField,
                 "with --beer-lambert: a real detector's open-beam response, inverse\n"
                 "square x obliquity, (SID/r)^3, multiplies the transmitted intensity")
        ->group(g);
    app.add_option("--projection-matrix", c.matrixFile,
                   "the camera(s) from a 3x4 projection-matrix file (detector, pitch, then\n"
                   "three rows of four numbers per view; docs/user/fvr-render.md) instead\n"
                   "of the C-arm options")
        ->option_text("FILE")
        ->group(g);
    app.add_option_function<std::string>(
           "--orbit",
           [&c](const std::string& s) {
               double from, to;
               std::tie(from, to, c.orbitViews) = parseOrbit(s);
               c.orbitFrom = from;
               c.orbitTo = to;
           },
           "a rotational run: N views with primary angles FROM to TO inclusive\n"
           "(degrees); --sweep N with --geometry cone: N views 360/N apart from\n"
           "--primary-angle")
        ->check(coreCheck(parseOrbit))
        ->option_text("FROM:TO:N")
        ->group(g);
}

/** --rtplan: the plan's beams (only --beam-number's), each checked as a camera with the
 *  imager at `sid`. */
void readPlanBeams(ConeOptions& c, double sid) {
    const core::RtPlan plan = core::readRtPlan(c.rtplan);
    c.planWarnings = plan.warnings;
    std::string numbers;
    for (const core::RtPlanBeam& b : plan.beams) {
        numbers += (numbers.empty() ? "" : ", ") + std::to_string(b.number);
        if (c.beamNumber && b.number != *c.beamNumber) continue;
        c.planBeams.push_back(b);
        c.planBeams.back().beam.sid = sid;
        try {
            core::treatmentBeamCamera(c.planBeams.back().beam, 64, 64, 1.0, 1.0);
        } catch (const SettingsError& e) {
            throw SettingsError("--rtplan " + c.rtplan + ": beam number " +
                                std::to_string(b.number) + ": " + e.what());
        }
    }
    if (c.planBeams.empty())
        throw SettingsError("--beam-number " + std::to_string(*c.beamNumber) + ": " + c.rtplan +
                            " has no such beam (its beams: " + numbers + ")");
}

/** --beam GANTRY,COUCH,COLL: three finite angles in degrees; throws SettingsError. */
glm::dvec3 parseBeamAngles(const std::string& s) {
    const auto v = toVec3(s);
    if (!v)
        throw SettingsError("beam: expected GANTRY,COUCH,COLL in degrees (IEC 61217), found '" + s +
                            "'");
    return {(*v)[0], (*v)[1], (*v)[2]};
}

/** Treatment beams (IEC 61217, core/geometry/treatment_beam.h) as the cone-beam camera, from
 *  the command line or an RT Plan (checked in checkBeam). */
void declareBeam(CLI::App& app, ConeOptions& c) {
    const std::string g = "Treatment beam (--geometry cone)";
    app.add_option_function<std::string>(
           "--beam",
           [&c](const std::string& s) {
               const glm::dvec3 a = parseBeamAngles(s);
               c.beam = core::TreatmentBeam{};
               c.beam->gantryDeg = a.x;
               c.beam->couchDeg = a.y;
               c.beam->collimatorDeg = a.z;
           },
           "a treatment beam instead of the C-arm: IEC 61217 gantry, couch (patient\n"
           "support) and collimator angles in degrees; gantry 0 = source above the\n"
           "couch (AP for HFS), 90 = source at the HFS patient's left. The image is\n"
           "the imager's at --sid (default 1500) seen from the source (columns +Xb,\n"
           "rows -Yb), about --isocenter (default: the volume's centre)")
        ->check(coreCheck(parseBeamAngles))
        ->option_text("G,C,K")
        ->group(g);
    addNumber(
        app, "--sad", c.sad, "MM",
        "with --beam: source to axis (isocentre) distance (default 1000)",
        [](double v) { return v > 0; }, "expected a positive number of mm")
        ->group(g);
    addParsed(app, "--patient-position", c.patientPosition, core::parsePatientPosition, "POS",
              "with --beam: how the patient lies on the couch, DICOM's codes HFS\n"
              "(default), HFP, FFS, FFP, HFDL, HFDR, FFDL, FFDR")
        ->group(g);
    app.add_option("--rtplan", c.rtplan,
                   "the beams of a DICOM RT Plan (each beam's first control point: angles,\n"
                   "isocentre, SAD; the patient position of its setup), one view each in\n"
                   "the plan's order, written as a stack; --sid is the imager's distance")
        ->option_text("FILE")
        ->group(g);
    app.add_option_function<int>(
           "--beam-number", [&c](int n) { c.beamNumber = n; },
           "with --rtplan: only the beam of this Beam Number (300A,00C0)")
        ->option_text("N")
        ->group(g);
}

/** The beam options that need --geometry cone, and what each treatment-beam option replaces. */
const std::vector<std::string> kBeamOptions = {"--beam", "--rtplan", "--beam-number", "--sad",
                                               "--patient-position"};
const std::vector<std::pair<std::string, std::string>> kBeamReplaces = {
    {"--primary-angle", "a C-arm angle"},
    {"--secondary-angle", "a C-arm angle"},
    {"--sod", "the beam's source-to-isocentre distance is --sad"},
    {"--orbit", "a C-arm's arc"},
    {"--sweep", "a C-arm's orbit"},
    {"--projection-matrix", "the file fixes the camera"}};
const std::vector<std::pair<std::string, std::string>> kPlanGives = {
    {"--beam", "the plan gives the beams"},
    {"--sad", "the plan gives each beam's SAD"},
    {"--isocenter", "the plan gives each beam's isocentre"},
    {"--patient-position", "the plan's patient setup gives it"}};

/** The treatment beam's checks, and the RT Plan read, before any input loads. */
void checkBeam(const CLI::App& app, Options& o) {
    ConeOptions& c = o.cone;
    if (!c.enabled) {
        for (const auto& name : kBeamOptions)
            if (app.count(name) > 0) throw SettingsError(name + ": only with --geometry cone");
        return;
    }
    if (!c.beams()) {
        for (const auto& name : {"--sad", "--patient-position"})
            if (app.count(name) > 0) throw SettingsError(std::string(name) + ": only with --beam");
        if (app.count("--beam-number") > 0)
            throw SettingsError("--beam-number: only with --rtplan");
        return;
    }
    // A beam's image is seen from the source (the C-arm's mirrored): no X-ray IOD holds it, and
    // an RT Image writer is not there yet.
    if ((!o.out.empty() && outputFormat(o.out) == OutputFormat::Dicom) || !o.send.empty())
        throw SettingsError(std::string(c.rtplan.empty() ? "--beam" : "--rtplan") +
                            ": DICOM output (.dcm, --send) of treatment beams is not written yet; "
                            "write .npy, .pfm or .png");
    const std::string way = c.beam ? "--beam" : "--rtplan";
    for (const auto& [name, why] : kBeamReplaces)
        if (app.count(name) > 0) throw SettingsError(name + ": not with " + way + " (" + why + ")");
    if (!c.rtplan.empty()) {
        for (const auto& [name, why] : kPlanGives)
            if (app.count(name) > 0)
                throw SettingsError(name + ": not with --rtplan (" + why + ")");
    } else if (app.count("--beam-number") > 0) {
        throw SettingsError("--beam-number: only with --rtplan");
    }
    const double sid = app.count("--sid") > 0 ? c.arm.sid : 1500.0;
    if (c.beam) {
        c.beam->sad = c.sad;
        c.beam->sid = sid;
        c.beam->position = c.patientPosition;
        try { // the beam's own checks (SAD < SID, finite angles) now
            core::treatmentBeamCamera(*c.beam, 64, 64, 1.0, 1.0);
        } catch (const SettingsError& e) {
            throw SettingsError(std::string("--beam: ") + e.what());
        }
        return;
    }
    readPlanBeams(c, sid);
}

/** The options that only cone beam takes. */
const std::vector<std::string> kConeOnly = {
    "--primary-angle", "--secondary-angle", "--sid",
    "--sod",           "--isocenter",       "--detector-size",
    "--pitch",         "--principal-point", "--ray-model",
    "--step",          "--flat-field",      "--projection-matrix",
    "--orbit",         "--geometry-from",   "--frame"};

/** The options that only the parallel (Fourier) renderers take, and why not in cone beam. */
const std::vector<std::pair<std::string, std::string>> kParallelOnly = {
    {"--view", "the C-arm's --primary-angle and --secondary-angle place the view"},
    {"--dir", "the C-arm's --primary-angle and --secondary-angle place the view"},
    {"--up", "the C-arm's --primary-angle and --secondary-angle place the view"},
    {"--axis", "--sweep turns the C-arm's primary angle; --orbit gives an arc"},
    {"--views", "give the views as --projection-matrix FILE"},
    {"--pixel-size", "the detector's --pitch sets the pixel size"},
    {"--kernel", "a Fourier rendering setting; cone beam ray casts: see --ray-model"},
    {"--kernel-width", "a Fourier rendering setting; cone beam ray casts: see --ray-model"},
    {"--deapodize", "a Fourier rendering setting"},
    {"--transform", "a Fourier rendering setting"},
    {"--oversampling", "a Fourier rendering setting"},
    {"--voxel-model", "cone beam takes --ray-model"},
    {"--pixel-aperture", "not in the cone-beam ray caster yet"},
    {"--clip", "cone-beam rays are clipped to the volume always"},
    {"--no-clip", "cone-beam rays are clipped to the volume always"},
    {"--keep-negative", "a Fourier rendering setting"},
    {"--non-negative", "a Fourier rendering setting"},
    {"--depth-cue", "a Fourier rendering setting"},
    {"--sharpen", "a Fourier rendering setting"},
    {"--sharpen-radius", "a Fourier rendering setting"},
    {"--band-limit", "a Fourier rendering setting"},
    {"--fp16", "the cone-beam ray caster runs on the CPU"},
    {"--kvp", "polychromatic cone beam is not implemented yet"}};

/** The options --projection-matrix replaces (the file fixes the camera). */
const std::vector<std::string> kMatrixFixes = {
    "--primary-angle",   "--secondary-angle", "--sid",   "--sod",
    "--isocenter",       "--detector-size",   "--pitch", "--size",
    "--principal-point", "--orbit",           "--sweep"};

/** The options --geometry-from replaces: the X-ray's C-arm and detector fix the camera
 *  (--isocenter stays: the isocentre where the file states none). */
const std::vector<std::string> kXrayFixes = {"--primary-angle",
                                             "--secondary-angle",
                                             "--sid",
                                             "--sod",
                                             "--detector-size",
                                             "--pitch",
                                             "--size",
                                             "--orbit",
                                             "--sweep",
                                             "--principal-point",
                                             "--beam",
                                             "--sad",
                                             "--rtplan",
                                             "--beam-number",
                                             "--patient-position"};

/** --geometry-from against the options it replaces, and --frame without it. */
void checkGeometryFrom(const CLI::App& app, const ConeOptions& c) {
    if (c.geometryFrom.empty()) {
        if (app.count("--frame") > 0)
            throw SettingsError("--frame: only with --geometry-from XRAY.dcm");
        return;
    }
    if (!c.matrixFile.empty())
        throw SettingsError("--geometry-from: not with --projection-matrix (one or the other "
                            "gives the camera)");
    for (const auto& name : kXrayFixes)
        if (app.count(name) > 0)
            throw SettingsError(name + ": not with --geometry-from (the X-ray's C-arm and "
                                       "detector fix the camera)");
}

/** The cone-beam checks that need the parsed command line: cone options without --geometry
 *  cone, parallel options with it, and the camera's own checks (before any input loads). */
void checkGeometry(const CLI::App& app, Options& o) {
    checkBeam(app, o);
    const ConeOptions& c = o.cone;
    if (!c.enabled) {
        for (const auto& name : kConeOnly)
            if (app.count(name) > 0) throw SettingsError(name + ": only with --geometry cone");
        return;
    }
    for (const auto& [name, why] : kParallelOnly)
        if (app.count(name) > 0)
            throw SettingsError(name + ": not with --geometry cone (" + why + ")");
    checkGeometryFrom(app, c);
    if (!c.matrixFile.empty())
        for (const auto& name : kMatrixFixes)
            if (app.count(name) > 0)
                throw SettingsError(name + ": not with --projection-matrix (the file fixes "
                                           "the camera and its views)");
    if (c.orbitViews > 0 && app.count("--sweep") > 0)
        throw SettingsError("--orbit: not with --sweep (one or the other gives the views)");
    if (c.orbitViews > 0 && app.count("--primary-angle") > 0)
        throw SettingsError("--orbit: not with --primary-angle (the orbit's FROM is the first "
                            "view's primary angle)");
    if (app.count("--detector-size") > 0 && app.count("--size") > 0)
        throw SettingsError("--detector-size: not with --size (both set the detector's size)");
    if (c.flatField && !o.beerLambert)
        throw SettingsError("--flat-field: multiplies transmitted intensity, so it needs "
                            "--beer-lambert");
    if (c.model == core::RayModel::Box && app.count("--step") > 0)
        throw SettingsError("--step: not with --ray-model box (exact path lengths, no step)");
    if (c.matrixFile.empty() && !c.beams() && c.geometryFrom.empty()) {
        // The C-arm's own checks (SOD < SID) now; the isocentre and a default pitch follow
        // from the volume and cannot make it fail.
        core::CArm arm = c.arm;
        arm.isocentre = glm::dvec3(0.0);
        try {
            core::cArmCamera(arm, 64, 64, c.pitchU > 0 ? c.pitchU : 1.0,
                             c.pitchV > 0 ? c.pitchV : 1.0, c.principalOffset);
        } catch (const SettingsError& e) {
            throw SettingsError(std::string("--geometry cone: ") + e.what());
        }
    }
}

/** What the command must name: INPUT, and --out, --info, --bench or --query; and the PACS
 *  options (fvr-render's own, not render settings). */
void checkCommand(const Options& o) {
    if (o.input.empty()) throw SettingsError("no INPUT given (see --help)");
    checkPacsOptions(o);
    if (!o.info && o.bench <= 0 && o.out.empty() && !o.queryGiven)
        throw SettingsError("no --out FILE given (or --info, --bench N)");
}

/** The rules that join several options (each option's own range is checked as it is parsed). */
void checkCombinations(Options& o) {
    if (o.kernelWidth != 0) {
        if (!o.kaiserBessel())
            throw SettingsError("--kernel-width: only for --kernel kaiser-bessel");
        o.settings.kernel = core::kaiserBesselKernel(o.kernelWidth);
    }
    if (o.beerLambert && !core::isAttenuation(o.settings.values))
        throw SettingsError("--beer-lambert: needs --values mu or mu-bone (transmission follows "
                            "from attenuation)");
    if (o.settings.depthCue > 0 && o.settings.kernel == core::Kernel::Nearest)
        throw SettingsError("--depth-cue: needs the derivative of the interpolation kernel; "
                            "--kernel nearest has none (choose linear or better)");
    if (o.polychromatic() && o.format == OutputFormat::Dicom)
        throw SettingsError("--kvp: writes .npy, .pfm or .png (no DICOM export yet)");
    if (o.polychromatic() && o.bench > 0)
        throw SettingsError("--kvp: not with --bench (bench/ times the polychromatic frame)");
    // --dir and --up (unless --view replaces them): the message names the vector at fault.
    if (o.dirUpGiven) core::ViewFrame::fromDirUp(o.dir, o.up);
    if (o.energy) o.settings.energyKeV = *o.energy;
    if (o.muWater) o.settings.muWaterPerMm = *o.muWater;
    if (o.exposure) o.settings.exposure = *o.exposure;
    o.transmission = o.settings.beam();
    if (o.beerLambert) o.settings.output = core::XrayOutput::Transmission;
    if (o.polychromatic()) o.settings.output = core::XrayOutput::Polychromatic;
}

void declareAll(CLI::App& app, Parsing& p) {
    app.formatter(std::make_shared<HelpFormatter>());
    app.get_formatter()->column_width(26);
    app.footer(kFooter);
    // As before: an option given twice takes its last value.
    app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    declareInput(app, p);
    declareView(app, p.o);
    declarePreset(app, p.o);
    declareSpectrum(app, p.o);
    declareModel(app, p.o);
    declareBackend(app, p.o);
    declareViews(app, p.o);
    declareOutput(app, p.o);
    declareXray(app, p.o);
    declarePolychromatic(app, p.o);
    declareBenchmark(app, p.o);
    declarePacs(app, p.o);
    declareCone(app, p.o.cone);
    declareBeam(app, p.o.cone);
}

/** The options of a parsed command line (the options counted by CLI11 resolved). */
Options parsed(const CLI::App& app, Parsing& p) {
    if (app.count("--raw-dims") > 0) p.o.raw = p.raw;
    p.o.dirUpGiven = app.count("--dir") > 0 || app.count("--up") > 0;
    p.o.viewGiven = p.o.dirUpGiven || app.count("--view") > 0;
    p.o.valuesGiven = app.count("--values") > 0;
    p.o.queryGiven = app.count("--query") > 0;
    return p.o;
}

} // namespace

std::optional<Options> parseOptions(int argc, char** argv) {
    CLI::App app("", "fvr-render");
    Parsing p;
    declareAll(app, p);
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        app.exit(e);
        return std::nullopt;
    } catch (const CLI::ParseError& e) {
        throw SettingsError(std::string(e.what()) + " (see --help)");
    }
    Options o = parsed(app, p);
    if (o.gpuInfo && o.input.empty()) return o;
    checkCommand(o);
    checkGeometry(app, o);
    checkCombinations(o);
    return o;
}

void refuseNulArguments(const std::vector<std::string>& args) {
    for (std::size_t i = 0; i < args.size(); ++i)
        core::refuseNul(args[i], "argument " + std::to_string(i + 1));
}

Options parseSettings(std::vector<std::string> args) {
    refuseNulArguments(args);
    CLI::App app("", "fvr-render");
    Parsing p;
    declareAll(app, p);
    std::reverse(args.begin(), args.end()); // CLI11 takes a vector last argument first
    try {
        app.parse(args);
    } catch (const CLI::ParseError& e) {
        throw SettingsError(e.what());
    }
    Options o = parsed(app, p);
    checkGeometry(app, o);
    checkCombinations(o);
    return o;
}

} // namespace fvr::cli
