#pragma once
/** fvr-render's settings, declared once with CLI11 (options.cpp): the help text, the parser and
 *  the checks of every value and combination come from the same declarations, and all of them
 *  run before any input is loaded. */
#include <optional>
#include <string>
#include <vector>

#include <fvr/core/dicom/rt_plan.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/geometry/treatment_beam.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/render/kernels.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/volume.h>
#include <fvr/core/xray/patient_views.h>
#include <fvr/core/xray/polychromatic.h>
#include <fvr/core/xray/xray.h>

namespace fvr::cli {

/** --geometry cone: a point source and a flat detector (core/geometry/camera.h), ray cast by
 *  core::ConeProjector (cone.h runs it). */
struct ConeOptions {
    bool enabled = false; ///< --geometry cone (else parallel, the Fourier renderers)
    /** --primary-angle, --secondary-angle, --sid, --sod; the isocentre is set per volume. */
    core::CArm arm;
    std::optional<glm::dvec3> isocentre; ///< --isocenter (default: the volume's centre)
    int width = 0, height = 0; ///< --detector-size (0: settings.size square)
    double pitchU = 0.0, pitchV = 0.0; ///< --pitch (0: core::framingPitch)
    glm::dvec2 principalOffset{0.0}; ///< --principal-point, pixels
    core::RayModel model = core::RayModel::Trilinear; ///< --ray-model
    double step = 0.0; ///< --step, a fraction of the smallest spacing
    bool flatField = false; ///< --flat-field (with --beer-lambert or --kvp)
    /** --pixel-subsamples: with --pixel-aperture, n x n rays per pixel averaged (1..16). */
    int pixelSubsamples = 4;
    std::string matrixFile; ///< --projection-matrix FILE (instead of the C-arm)
    /** --orbit FROM:TO:N: N primary angles from FROM to TO inclusive. */
    std::optional<double> orbitFrom, orbitTo;
    int orbitViews = 0;
    /** Treatment beams (IEC 61217) instead of the C-arm (options.cpp, declareBeam): --beam
     *  GANTRY,COUCH,COLL with --sad and --patient-position, or the beams of --rtplan FILE
     *  (--beam-number N: that one only; read before the input loads). --sid is the imager's
     *  distance from the source, 1500 mm unless given; the isocentre the plan's, else
     *  --isocenter, else the volume's centre. */
    std::optional<core::TreatmentBeam> beam; ///< resolved from the four options below
    double sad = 1000.0; ///< --sad
    core::PatientPosition patientPosition = core::PatientPosition::HFS; ///< --patient-position
    std::string rtplan;
    std::optional<int> beamNumber;
    std::vector<core::RtPlanBeam> planBeams; ///< the beams to render, from --rtplan
    std::vector<std::string> planWarnings; ///< what the reader assumed (said when rendering)
    bool beams() const { return beam.has_value() || !rtplan.empty(); }
    /** --geometry-from XRAY.dcm: the camera of an X-ray's frame (its C-arm, detector and pitch)
     *  instead of the C-arm options; --frame K (0-based, default 0) or --frame all. */
    std::string geometryFrom;
    int frame = 0;
    bool allFrames = false;
};

/** Output file formats, from the extension of --out. */
enum class OutputFormat { None, Npy, Pfm, Png, Dicom };

struct Options {
    std::string input;
    /** Every rendering choice (kernel, spectrum, voxel model, size, view, ...), the defaults
     *  the workstation's; --preset and the rendering options write it. */
    core::RenderSettings settings;
    core::Vec3 dir{0, 0, 1}; ///< --dir (with dirUpGiven: instead of settings.view)
    core::Vec3 up{0, -1, 0}; ///< --up
    bool dirUpGiven = false; ///< --dir or --up given
    bool viewGiven = false; ///< --view, --dir or --up given (else the default view)
    bool valuesGiven = false; ///< --values given (not the default)
    int kernelWidth = 0; ///< --kernel-width, resolved into settings.kernel
    int threads = 0;
    /** --backend: auto (the GPU when it is hardware, else the CPU, saying why), cpu or gpu
     *  (the GPU even when it is a software renderer). */
    enum class Backend { Auto, Cpu, Gpu } backend = Backend::Auto;
    bool fp16 = false;
    std::optional<core::RawSpec> raw;
    std::string series;
    int sweep = 0;
    std::optional<core::Vec3> axis;
    std::string viewsFile;
    bool numbered = false;
    int bitDepth = 8;
    bool beerLambert = false;
    std::optional<double> muWater; ///< --mu-water
    std::optional<double> energy; ///< --energy, keV
    std::optional<double> exposure;
    core::Transmission transmission; ///< resolved from the three above; active with --beer-lambert
    std::string out;
    OutputFormat format = OutputFormat::None; ///< from the extension of `out`
    bool info = false;
    bool gpuInfo = false; ///< --gpu-info: the EGL devices and the GL facts as JSON
    int bench = 0;
    // PACS (render_cli/pacs.h): INPUT dicom://AE@host:port/STUDY[/SERIES], --query, --send.
    std::string aeTitle = "FVR"; ///< --ae-title: ours (the calling AE)
    core::pacs::RetrieveMethod retrieve = core::pacs::RetrieveMethod::Get; ///< --retrieve
    int listenPort = 11112; ///< --listen-port: our storage listener, for --retrieve move
    std::string listenAddress = "127.0.0.1"; ///< --listen-address: the address it binds
    std::vector<std::string> query; ///< --query KEY=VALUE[,KEY=VALUE] (repeatable)
    bool queryGiven = false;
    bool querySeries = false; ///< --query-series: each study's series too
    std::string send; ///< --send dicom://AE@host:port
    std::string store; ///< --store DIR: the local study store (default: the user's)
    bool refresh = false; ///< --refresh: retrieve INPUT again even when the store has it complete
    int pacsTimeout = 10; ///< --pacs-timeout S: seconds without a reply before a PACS call fails
    // DICOM TLS (--tls): to the PACS of INPUT and --send, and for --retrieve move's listener.
    bool tls = false;
    std::string tlsCert, tlsKey; ///< --tls-cert, --tls-key: ours (PEM)
    std::vector<std::string> tlsCa; ///< --tls-ca FILE (repeatable): the CAs we trust (PEM)
    bool tlsNoVerify = false; ///< --tls-no-verify: take any certificate the peer shows

    /** Polychromatic X-ray, on with --kvp: the output holds I/I0. */
    std::optional<double> kvp;
    double filtrationAlMm = 0.0;
    double filtrationCuMm = 0.0;
    core::DetectorModel detector;
    std::vector<core::Material> materials = core::defaultMaterials();
    double noiseMas = 0.0; ///< 0: no noise
    double electronicNoise = 0.0; ///< Gaussian, standard deviation in quanta per pixel
    std::uint64_t seed = 1;
    std::string materialOut; ///< --material-out FILE.npy: rhoL (k, M, M) in g/cm^2

    ConeOptions cone; ///< --geometry cone and its camera

    bool polychromatic() const { return kvp.has_value(); }
    bool kaiserBessel() const {
        return settings.kernel == core::Kernel::KaiserBessel4 ||
               settings.kernel == core::Kernel::KaiserBessel6;
    }
};

/** Parses and checks the command line. Returns nothing when --help was asked for (the help is
 *  printed on stdout). Throws core::SettingsError naming the option for every bad value or
 *  combination (exit status 2). */
std::optional<Options> parseOptions(int argc, char** argv);

/** Parses and checks settings alone, by the same declarations ("--kernel", "sinc4", ...; no
 *  INPUT, --out or --info needed): the Python module's settings. Throws core::SettingsError
 *  naming the option. */
Options parseSettings(std::vector<std::string> args);

/** Throws core::SettingsError "argument N holds a NUL character: '...'" for the first argument
 *  holding one: arguments from Python reach the parser and the files as C strings, which would
 *  end at the NUL (a command line's arguments cannot hold one). */
void refuseNulArguments(const std::vector<std::string>& args);

} // namespace fvr::cli
