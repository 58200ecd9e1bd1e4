#pragma once
/** X-ray geometry in and out of DICOM: the C-arm (or radiograph) that took an XA, RF, DX or CR
 *  image, per frame, and a DRR written as an X-Ray Angiographic image that carries its camera.
 *
 *  Read (PS3.3 C.8.7.5 XA Positioner, C.8.7.6 XRF Positioner, C.8.11.5 DX Positioning, C.8.19.6
 *  Enhanced XA functional groups):
 *   - DistanceSourceToDetector (0018,1110): SID; DistanceSourceToPatient (0018,1111) or, in an
 *     Enhanced XA's X-Ray Geometry Sequence (0018,9476), DistanceSourceToIsocenter (0018,9402):
 *     SOD; EstimatedRadiographicMagnificationFactor (0018,1114) = SID / SOD fills in either.
 *   - PositionerPrimaryAngle (0018,1510), PositionerSecondaryAngle (0018,1511): the first
 *     frame's; later frames add PositionerPrimary/SecondaryAngleIncrement (0018,1520/1521):
 *     one value = a constant change per frame, one value per frame = each frame's offset from
 *     the first angles (C.8.7.5.1.3). Enhanced XA: the Positioner Position Sequence (0018,9405)
 *     of each frame's (else the shared) functional groups.
 *   - ImagerPixelSpacing (0018,1164) (the detector's pitch, rows then columns; Enhanced XA: in
 *     the Frame Pixel Data Properties Sequence (0028,9443)), Rows, Columns, NumberOfFrames.
 *   - DX and CR: the angles are a C-arm's only when PositionerType (0018,1508) is CARM (or
 *     absent); a MAMMOGRAPHIC positioner's angles mean something else (C.8.11.7) and are
 *     refused. DetectorPrimary/SecondaryAngle (0018,1530/1531) and ColumnAngulation (0018,1450)
 *     (a detector not square to the central ray) are not modelled: ignored with a warning. With no
 *     angles, ViewPosition (0018,5101) PA, AP, LL or RL gives them (0/0, 180/0, 90/0, -90/0).
 *   - PatientOrientation (0020,0020), when stated, is checked against the camera's columns and
 *     rows; an image mirrored relative to the camera (an AP radiograph displayed as read) has
 *     its columns (or rows) flipped to match the camera, with a warning. When it is missing, the
 *     pixels are taken as the camera sees them, and a warning gives the letters assumed.
 *  Every missing value is assumed and said in a warning that names the tag and the value. The
 *  isocentre is not in any X-ray IOD: it is left to the caller (the volume's centre by default),
 *  except in files that this project wrote, which carry it (and a principal-point offset) in
 *  private tags of the creator "FVR Workstation" (0009,00xx). */
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/geometry/camera.h>
#include <fvr/core/geometry/treatment_beam.h>
#include <fvr/core/render/cone_projector.h>

namespace fvr::core {

struct XrayGeometry {
    std::filesystem::path file;
    std::string modality; ///< XA, RF, DX, CR, ...
    std::string sopClassUid;
    int width = 0; ///< Columns
    int height = 0; ///< Rows
    double pitchU = 1.0; ///< mm between column centres on the detector
    double pitchV = 1.0; ///< mm between row centres on the detector
    glm::dvec2 principalOffset{0.0}; ///< pixels; 0 unless the file is one of ours
    /** One C-arm per frame. Its isocentre is (0, 0, 0) unless `isocentreStated`. Empty for an
     *  RT Image, whose frames are `beams`. */
    std::vector<CArm> frames;
    /** An RT Image (Modality RTIMAGE, rt_image.h): each frame's treatment beam (IEC 61217
     *  angles, SAD, SID, patient position; its isocentre (0, 0, 0) unless `isocentreStated`) and
     *  its imager's camera about that isocentre (RTImagePosition, ImagePlanePixelSpacing,
     *  XRayImageReceptorTranslation and Angle, RTImageOrientation); empty for an X-ray. */
    std::vector<TreatmentBeam> beams;
    std::vector<ConeCamera> beamCameras;
    /** Whether the isocentre is the file's: a file this project wrote (X-ray), or an RT Image's
     *  IsocenterPosition (300A,012C). */
    bool isocentreStated = false;
    /** frames x rows x columns real values (rescale or Modality LUT applied, MONOCHROME1
     *  inverted so that larger is brighter), frame f at f * W * H, row 0 at the top; empty when
     *  read without pixels. */
    std::vector<float> pixels;
    std::vector<std::string> warnings;

    /** The number of frames: C-arms, or an RT Image's beams. */
    std::size_t frameCount() const { return beams.empty() ? frames.size() : beams.size(); }
    /** The camera of frame `frame` with the isocentre at `isocentre` (ignored when the file
     *  states one). */
    ConeCamera camera(std::size_t frame, const glm::dvec3& isocentre) const;
};

/** The PatientOrientation (0020,0020) letters of an LPS direction, strongest first, components
 *  above 1e-4 only: (1, 0, 0) "L", (0.6, -0.8, 0) "AL", (0, 0, -1) "F". */
std::string patientOrientationLetters(const glm::dvec3& direction);

/** Reads the geometry (and, when `withPixels`, the pixel values) of a DICOM X-ray image, or
 *  of an RT Image (its treatment beam and imager, rt_image.h; a missing RTImageSID is refused,
 *  other missing values assumed with a warning naming the tag; a NON_NORMAL image plane and an
 *  RT Image Orientation out of the receptor's plane are refused).
 *  Throws DicomError (a LoadError) naming the file and the problem: unreadable, no image,
 *  colour, angles or distances that are not numbers, SOD not below SID, an angle increment
 *  vector whose length is neither 1 nor the number of frames, a mammographic positioner. */
XrayGeometry readXrayGeometry(const std::filesystem::path& path, bool withPixels = true);

/** The C-arm whose camera (cArmCamera with the camera's size, pitch and principal offset) is
 *  `camera`: the angles from its columns' direction u = (cos a, sin a, 0) and its principal ray,
 *  SID from source to detector centre, the isocentre the point of the principal ray nearest to
 *  `near` (for instance the volume's centre). Throws SettingsError when no C-arm has this
 *  camera (a rolled or tilted detector, rows not along u x d) or when the isocentre would not lie
 *  strictly between source and detector. */
CArm cArmFromCamera(const ConeCamera& camera, const glm::dvec3& near);

/**
 * Writes a cone-beam DRR as an X-Ray Angiographic Image (single frame, MONOCHROME2, 16-bit
 * stored values whose RescaleSlope/Intercept give back the line integrals within 1/65535 of
 * their range) whose XA Positioner module holds the C-arm: DistanceSourceToDetector,
 * DistanceSourceToPatient, PositionerPrimary/SecondaryAngle, ImagerPixelSpacing and
 * PatientOrientation from the camera; the isocentre (LPS mm) and the principal offset also in
 * private tags, so that readXrayGeometry gives back the same camera. Patient and study as in
 * `info` (exportInfoFor). Throws SettingsError when the image's camera is not `arm`'s (compare
 * cArmFromCamera), WriteError naming the path when it cannot be written.
 */
void writeXrayDicom(const std::filesystem::path& path, const DetectorImage& image, const CArm& arm,
                    const DicomExportInfo& info = {});

/** A rotational run (an orbit sweep) as one multi-frame X-Ray Angiographic image, as a
 *  rotational C-arm writes it: PositionerMotion DYNAMIC, the first view's angles and each
 *  frame's offsets from them in PositionerPrimary/SecondaryAngleIncrement (PS3.3 C.8.7.5.1.3),
 *  one rescale for all frames, FrameTime a nominal 100 ms. The views must share their detector,
 *  SID, SOD and isocentre (SettingsError naming the first view that does not). */
void writeXrayDicomRun(const std::filesystem::path& path, const std::vector<DetectorImage>& views,
                       const std::vector<CArm>& arms, const DicomExportInfo& info = {});

} // namespace fvr::core
