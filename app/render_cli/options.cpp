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

#include "options_internal.h"
#include "pacs.h"

namespace fvr::cli {
namespace {

using core::SettingsError;
using namespace detail;

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
    app.add_option_function<std::string>(
           "--size",
           [&o](const std::string& s) {
               const auto [w, h] = core::parseImageSize(s);
               o.settings.size = w;
               o.settings.height = w == h ? 0 : h;
           },
           "image size in pixels: N (square) or WxH, each " + std::to_string(kDefaults.kMinImage) +
               ".." + std::to_string(kDefaults.kMaxImage) + " " +
               defaultText(std::to_string(kDefaults.size)))
        ->check(coreCheck([](const std::string& s) { core::parseImageSize(s); }))
        ->option_text("N|WxH")
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
                 "detector pixels integrate over their area (sinc per image axis;\n"
                 "cone beam: --pixel-subsamples rays per pixel averaged) instead of\n"
                 "sampling the projection at their centres")
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
                   "it lists complete opens without the network; of a partial one only\n"
                   "the missing images are retrieved")
        ->option_text("DIR")
        ->group(g);
    app.add_flag("--refresh", o.refresh,
                 "re-retrieve a dicom:// INPUT from the PACS, all of it, even what the\n"
                 "store has complete")
        ->group(g);
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
    if (o.polychromatic() && !o.send.empty())
        throw SettingsError("--send: not with --kvp (I/I0 has no DICOM export yet)");
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
