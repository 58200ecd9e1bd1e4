#pragma once
/** A treatment beam's DRR as a DICOM RT Image (PS3.3 A.17, RT Image module C.8.8.2): the beam's
 *  eye view, which no X-ray IOD holds (an X-ray's positioner angles place a C-arm, whose image
 *  is seen from the detector's side), so a treatment beam's image is written as the IOD that
 *  radiotherapy systems exchange such DRRs in.
 *
 *  What the standard says, and what is written (PS3.3 C.8.8.2.7): "When RT Image Plane
 *  (3002,000C) is NORMAL and RT Image Orientation (3002,0010) is not provided ... The image
 *  viewing direction shall be from the radiation source to the image (i.e., in the sense of a
 *  beam's eye view, or along the negative Zr direction of the IEC X-RAY IMAGE RECEPTOR
 *  coordinate system) ... The direction of rows shall be along the positive Xr direction and
 *  the direction of the columns shall be along the negative Yr direction". That is the camera
 *  of treatmentBeamCamera: columns along +Xb, rows along -Yb. The receptor turns with the
 *  collimator there (a beam's eye view), so XRayImageReceptorAngle (3002,000E) = the collimator
 *  angle ("A positive angle corresponds to a counter-clockwise rotation of the X-Ray Image
 *  Receptor as viewed from the radiation source in the IEC GANTRY coordinate system", PS3.3:
 *  the sense of IEC 61217's right-handed rotation about Zg, as the collimator's).
 *   - RTImagePosition (3002,0012): x, y in mm of the first pixel's centre in the receptor
 *     system: (-(W-1)/2 pu, +(H-1)/2 pv), the receptor's origin at the image's centre.
 *   - XRayImageReceptorTranslation (3002,000D): the receptor's origin in IEC GANTRY (mm):
 *     (0, 0, SAD - SID) ("the Z coordinate ... equal to Radiation Machine SAD minus RT Image
 *     SID"), plus, for a principal point offset (du, dv) pixels, the panel's shift
 *     Rz(collimator) (du pu, -dv pv, 0).
 *   - ImagePlanePixelSpacing (3002,0011): the detector's pitch at the image plane (SID), rows
 *     then columns; RTImageSID (3002,0026), RadiationMachineSAD (3002,0022).
 *   - GantryAngle, BeamLimitingDeviceAngle, PatientSupportAngle (IEC 61217 degrees),
 *     IsocenterPosition (300A,012C) (patient LPS mm, the isocentre the DRR was rendered about)
 *     and PatientPosition (0018,5100).
 *  readXrayGeometry reads such a file (and other RT Images: any receptor translation, angle
 *  and in-plane RT Image Orientation) back to the same camera. */
#include <filesystem>

#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/dicom/rt_plan.h>
#include <fvr/core/render/cone_projector.h>

namespace fvr::core {

/**
 * Writes a treatment beam's DRR as an RT Image (single frame, MONOCHROME2, 16-bit stored values
 * whose RescaleSlope/Intercept give back the values within 1/65535 of their range; ImageType
 * DERIVED\SECONDARY\DRR, ConversionType WSD). `beam.number`/`name` (an RT Plan's beam; 0 and
 * empty for --beam) go into ReferencedBeamNumber and RTImageLabel. Throws SettingsError when
 * the image's camera is not the beam's imager (treatmentBeamCamera with the image's size, pitch
 * and principal offset), WriteError naming the path when it cannot be written.
 */
void writeRtImageDicom(const std::filesystem::path& path, const DetectorImage& image,
                       const RtPlanBeam& beam, const DicomExportInfo& info = {});
/** The same for a beam that no plan numbers (--beam). */
void writeRtImageDicom(const std::filesystem::path& path, const DetectorImage& image,
                       const TreatmentBeam& beam, const DicomExportInfo& info = {});

} // namespace fvr::core
