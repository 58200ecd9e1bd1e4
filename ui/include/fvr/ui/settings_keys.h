#pragma once
/** Every QSettings key the workstation reads or writes, in one table. The strings are what
 *  users' saved settings hold: never change one (a renamed key silently loses that setting). */
namespace fvr::ui::keys {

// Rendering panel
// Choices are saved by name (kernelName, transformName, valueMappingName, voxelModelName,
// xrayOutputName); earlier versions saved the enum numbers, which still load.
inline constexpr char kRenderKernel[] = "render/kernel";
inline constexpr char kRenderSize[] = "render/size";
inline constexpr char kRenderTransform[] = "render/transform";
inline constexpr char kRenderOversampling[] = "render/oversampling";
inline constexpr char kRenderDeapodize[] = "render/deapodize";
inline constexpr char kRenderValues[] = "render/values";
inline constexpr char kRenderTargetFps[] = "render/targetFps";
inline constexpr char kRenderClip[] = "render/clip";
inline constexpr char kRenderNonNegative[] = "render/nonNegative";
inline constexpr char kRenderPixelAperture[] = "render/pixelAperture";
inline constexpr char kRenderSoftwareGpu[] = "render/softwareGpu";
inline constexpr char kRenderVoxelModel[] = "render/voxelModel"; ///< a name (voxelModelName)

// Geometry panel
inline constexpr char kGeometryProjection[] = "geometry/projection"; ///< "parallel" or "cone"
inline constexpr char kGeometrySid[] = "geometry/sid";
inline constexpr char kGeometrySod[] = "geometry/sod";
inline constexpr char kGeometryRayModel[] = "geometry/rayModel"; ///< a name (rayModelName)

// Display panel
inline constexpr char kDisplayInvert[] = "display/invert";

// X-ray panel
inline constexpr char kXrayOutput[] = "xray/output";
inline constexpr char kXrayEnergyKeV[] = "xray/energyKeV";
inline constexpr char kXrayExposure[] = "xray/exposure";
inline constexpr char kXrayDepthCue[] = "xray/depthCue";
inline constexpr char kXraySharpen[] = "xray/sharpen";
inline constexpr char kXraySharpenRadius[] = "xray/sharpenRadius";
inline constexpr char kXrayBandLimit[] = "xray/bandLimit";
// Polychromatic X-ray.
inline constexpr char kXrayKvp[] = "xray/kvp";
inline constexpr char kXrayFiltrationAl[] = "xray/filtrationAlMm";
inline constexpr char kXrayFiltrationCu[] = "xray/filtrationCuMm";
inline constexpr char kXrayDetector[] = "xray/detector"; ///< 0 energy-integrating, 1 counting
inline constexpr char kXrayCsiUm[] = "xray/csiUm";
inline constexpr char kXrayNoiseMas[] = "xray/noiseMas";

// Main window
inline constexpr char kWindowGeometry[] = "window/geometry";
inline constexpr char kWindowState[] = "window/state";
inline constexpr char kViewOverlay[] = "view/overlay";
inline constexpr char kRecentStudies[] = "recent";
inline constexpr char kLastFolder[] = "lastFolder"; ///< the last study's folder (open dialogs)
inline constexpr char kLastExportFolder[] = "export/lastFolder"; ///< where exports went last

// PACS (pacs_settings.cpp)
inline constexpr char kPacsNodes[] =
    "pacs/nodes"; ///< array: name, calledAe, host, port, retrieve, tls
inline constexpr char kPacsAeTitle[] = "pacs/aeTitle";
inline constexpr char kPacsListenPort[] = "pacs/listenPort";
inline constexpr char kPacsListen[] = "pacs/listen";
inline constexpr char kPacsListenAddress[] = "pacs/listenAddress"; ///< the listener binds it
inline constexpr char kPacsAllowedPeers[] = "pacs/allowedPeers"; ///< "AE" or "AE@host" each
inline constexpr char kPacsTimeout[] = "pacs/timeoutSeconds";
inline constexpr char kPacsTlsCertificate[] = "pacs/tlsCertificate"; ///< our certificate (PEM)
inline constexpr char kPacsTlsPrivateKey[] = "pacs/tlsPrivateKey";
inline constexpr char kPacsTlsTrustedCa[] = "pacs/tlsTrustedCa"; ///< list of PEM files
inline constexpr char kPacsTlsVerifyPeer[] = "pacs/tlsVerifyPeer";
inline constexpr char kPacsListenTls[] = "pacs/listenTls";
inline constexpr char kPacsLastNode[] = "pacs/lastNode"; ///< the node the PACS dialog used last

} // namespace fvr::ui::keys
