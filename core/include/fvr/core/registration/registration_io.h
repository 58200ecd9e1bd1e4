#pragma once
/** Files around 2D/3D registration: an X-ray with its geometry (DICOM, or an image with the JSON
 *  sidecar that fvr-render writes), pose files, target points, and the overlay images. Every error
 *  is a LoadError / WriteError / SettingsError naming the file and the problem. */
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <fvr/core/registration/pose.h>
#include <fvr/core/registration/registration.h>

namespace fvr::core {

/** How an X-ray's stored values relate to line integrals. */
enum class XrayValues {
    Auto, ///< from the file: DICOM PixelIntensityRelationship (LIN: intensity; LOG, or a DRR of
          ///< ours: line integrals), a sidecar's output quantity
    LineIntegrals, ///< as stored (larger = more attenuation)
    Intensity ///< -ln(I / I0), I0 the open-beam level (see readXrayInput)
};
const char* xrayValuesName(XrayValues v); ///< "auto", "line-integrals", "intensity"
XrayValues parseXrayValues(const std::string& name);

/** An X-ray ready to register against. */
struct XrayInput {
    RegistrationView view; ///< camera at the identity pose, line integrals, mask (empty or W x H)
    std::filesystem::path file;
    int frame = 0;
    /** The conversion applied, in words: "line integrals as stored", "-ln(I/I0), I0 = ...". */
    std::string valuesNote;
    /** What says which patient and geometry frame the X-ray belongs to (DICOM PatientID,
     *  StudyInstanceUID, FrameOfReferenceUID; a sidecar's volume name and dims): two inputs
     *  whose stated frames differ are refused by checkSameFrame. Empty when unknown. */
    std::string patientId, frameOfReference;
    std::vector<std::string> warnings;
};

/** Reads frame `frame` of an X-ray: DICOM XA, RF, DX, CR or RT Image (readXrayGeometry; its
 *  camera with the isocentre at `isocentre` unless the file states one), or .npy / .pfm / .png
 *  beside the JSON sidecar fvr-render wrote for it (FILE.json, the camera of views[frame]; for
 *  the numbered files STEM_NNNN.EXT of several views unstacked, STEM.EXT.json's view at the
 *  place its "output" "files" list names the file).
 *  LoadError naming the file and what is missing (no geometry tag, no sidecar, a sidecar without
 *  a camera, a frame out of range, values that are not finite). */
XrayInput readXrayInput(const std::filesystem::path& path, const glm::dvec3& isocentre,
                        XrayValues values = XrayValues::Auto, int frame = 0);
/** SettingsError naming both files when two inputs state different patients or frames. */
void checkSameFrame(const std::vector<XrayInput>& inputs);

/** A pose file: {"matrix": 4 rows of 4 numbers} (row-major, the last row 0 0 0 1), or
 *  {"rotation_deg": [3], "translation_mm": [3], "centre_mm": [3] (optional: `centre`)}, or a
 *  registration result (its "pose" object). LoadError naming the file and the problem: not JSON,
 *  the wrong shape, not rigid (validateRigid). */
glm::dmat4 readPoseJson(const std::filesystem::path& path, const glm::dvec3& centre);
/** {"matrix", "rotation_deg", "translation_mm", "centre_mm", "convention"}: readPoseJson reads it
 *  back. */
std::string poseJsonText(const glm::dmat4& T, const glm::dvec3& centre);
void writePoseJson(const std::filesystem::path& path, const glm::dmat4& T,
                   const glm::dvec3& centre);

/** Target points (LPS mm), one "x,y,z" per line; blank lines, # comments and one header line
 *  of names allowed. LoadError naming the file and line. */
std::vector<glm::dvec3> readTargetsCsv(const std::filesystem::path& path);

/** Overlay PNGs of an X-ray and a DRR of the same camera, each windowed on its own 1st-99th
 *  percentiles: "blend" (X-ray green, DRR magenta: grey where they agree) and "checkerboard"
 *  (squares of `square` pixels alternating the two). */
void writeOverlayPng(const std::filesystem::path& path, const std::string& kind,
                     const std::vector<float>& xray, const std::vector<float>& drr, int width,
                     int height, int square = 32);

} // namespace fvr::core
