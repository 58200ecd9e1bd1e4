#pragma once
/** Every rendering choice in one place, with one set of defaults: fvr-render's options, the
 *  Python module, the workstation's panels and the dataset manifests read and write this, so
 *  that the same study renders to the same image everywhere.
 *
 *  The defaults are the workstation's best picture: the patient's AP view, attenuation (mu) for
 *  Hounsfield data, Kaiser-Bessel 4 with gridding correction at 1.25x oversampling, the
 *  trilinear voxel model, clipped to the volume's shadow, never below zero. preset("paper")
 *  gives the setting of the paper's Table 1 (linear, 1x, raw values, band-limited). */
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/renderer.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/volume.h>
#include <fvr/core/xray/patient_views.h>
#include <fvr/core/xray/xray.h>

namespace fvr::core {

/** What an image holds: line integrals, the Beer-Lambert transmission of a monochromatic beam,
 *  or a polychromatic radiograph (TASMIP spectrum through the CT's materials). */
enum class XrayOutput { LineIntegrals = 0, Transmission = 1, Polychromatic = 2 };
const char* xrayOutputName(XrayOutput o); ///< "line-integrals", "transmission", "polychromatic"
XrayOutput parseXrayOutput(const std::string& s); ///< throws SettingsError naming the choices

struct RenderSettings {
    // The spectrum (made once per study and per kernel with gridding correction).
    Kernel kernel = Kernel::KaiserBessel4;
    /** Gridding correction (deapodization for the kernel). Empty: where it helps the kernel
     *  (griddingCorrectionHelps: every kernel but linear); true: always; false: never. */
    std::optional<bool> deapodize;
    TransformKind transform = TransformKind::Fft;
    double oversampling = 1.25; ///< zero padding per axis, 1..2
    /** Mu for Hounsfield data; forVolume() takes raw values for any other data. */
    ValueMapping values = ValueMapping::Mu;

    // Each frame.
    VoxelModel voxelModel = VoxelModel::Trilinear;
    bool clip = true; ///< RenderParams::clipToVolume
    bool pixelAperture = false;
    bool nonNegative = true; ///< RenderParams::nonNegative
    double depthCue = 0.0;
    SliceFilter filter;

    // The image and the view.
    int size = 512; ///< W, the columns: kMinImage..kMaxImage (the workstation offers kMinSize..)
    int height = 0; ///< H, the rows; 0: as many as the columns (a square image)
    std::optional<double> pixelSize; ///< mm; empty: defaultPixelSize (the diagonal / min(W, H))
    PatientView view = PatientView::AP;

    // The X-ray output: line integrals or the Beer-Lambert transmission of beam(). The
    // polychromatic output's tube, materials and detector are the X-ray physics' own settings.
    XrayOutput output = XrayOutput::LineIntegrals;
    double energyKeV = 70.0; ///< the beam's photon energy: mu of water from NIST XCOM
    std::optional<double> muWaterPerMm; ///< instead of the energy's (fvr-render --mu-water)
    double exposure = 1.0; ///< the unattenuated beam's intensity (1: full scale)

    /** The image sizes users choose from (the renderers also render the progressive levels'
     *  smaller sizes, down to validateImageGeometry's 16). */
    static constexpr int kMinSize = 128;
    static constexpr int kMaxSize = 2048;
    /** Any W and H in this range render (the Fourier renderers transform a square of
     *  fourierSide() and crop it; view.h). */
    static constexpr int kMinImage = 16;
    static constexpr int kMaxImage = 4096;

    /** "default" (these defaults) or "paper" (the paper's Table 1: linear, no oversampling, raw
     *  values, band-limited, no gridding correction, no clipping, negative values kept). Throws
     *  SettingsError naming the presets. */
    static RenderSettings preset(std::string_view name);
    static std::vector<std::string> presetNames();

    /** The settings a volume renders with, and why they differ from these: attenuation only
     *  means something for Hounsfield units, so other data integrate their raw values (`note`
     *  gets one sentence saying so; empty when nothing changed). */
    RenderSettings forVolume(const Volume& volume, std::string* note = nullptr) const;

    /** The spectrum these settings need (threads and planner effort as PreprocessOptions'). */
    PreprocessOptions toPreprocessOptions() const;
    /** One frame's parameters for a view and an image geometry. */
    RenderParams toRenderParams(const ViewFrame& view, const ImageGeometry& image) const;
    /** size and pixelSize (or the default for the volume), checked against the volume. */
    ImageGeometry imageGeometry(const Volume& volume) const;
    /** The monochromatic beam: mu of water (muWaterPerMm, else the energy's) and exposure. */
    Transmission beam() const;
    /** Whether the spectrum is deapodized for the kernel (deapodize, else the rule). */
    bool griddingCorrected() const;

    bool operator==(const RenderSettings&) const = default;
};

/** Throws SettingsError "size: expected 16..4096 pixels, found N" (`what` names the option). */
void validateSettingsSize(int size, const std::string& what = "size");
/** An image size as users write it: "N" (square) or "WxH", each kMinImage..kMaxImage;
 *  SettingsError naming `what` and the text otherwise. Returns {W, H}. */
std::pair<int, int> parseImageSize(const std::string& text, const std::string& what = "size");
/** The choices the workstation offers: 128, 256, ..., 2048. */
std::vector<int> settingsSizes();

} // namespace fvr::core
