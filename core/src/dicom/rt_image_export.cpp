// A treatment beam's DRR as a DICOM RT Image whose RT Image module holds its beam and imager
// (rt_image.h).
#include <fvr/core/dicom/rt_image.h>

#include <fvr/core/io/atomic_file.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/errors.h>

#include "dicom_write_internal.h"

namespace fvr::core {

namespace {

using dicom_write::failWrite;
using dicom_write::Quantized;
using Put = dicom_write::PutTag;

std::string ds(double v) { return dicom_write::decimalString(v); }

std::string ds3(const glm::dvec3& v) { return ds(v.x) + "\\" + ds(v.y) + "\\" + ds(v.z); }

/** Throws SettingsError unless the image's camera is the beam's imager. */
void checkCamera(const DetectorImage& image, const TreatmentBeam& beam) {
    const ConeCamera& c = image.camera;
    const ConeCamera e =
        treatmentBeamCamera(beam, image.width, image.height, c.pitchU, c.pitchV, c.principalOffset);
    if (!dicom_write::sameCamera(e, c, image.width, image.height, beam.sid))
        throw SettingsError("the DRR's camera is not the treatment beam's imager (gantry " +
                            ds(beam.gantryDeg) + ", couch " + ds(beam.couchDeg) + ", collimator " +
                            ds(beam.collimatorDeg) + " deg, SAD " + ds(beam.sad) + ", SID " +
                            ds(beam.sid) +
                            " mm): an RT Image carries only a treatment beam's geometry");
}

/** Patient, study, series, equipment and image identification (the RT Image IOD's type 1 and
 *  2 attributes outside the RT Image module). */
void putIdentity(const Put& put, const DicomExportInfo& info) {
    dicom_write::putNewInstance(
        put, UID_RTImageStorage, info,
        {DCM_OperatorsName, DCM_RadiationMachineName, DCM_PrimaryDosimeterUnit});
    put(DCM_Modality, "RTIMAGE");
    put(DCM_Manufacturer, "FVR Workstation");
    put(DCM_SeriesDescription, info.seriesDescription);
    put(DCM_ImageType, "DERIVED\\SECONDARY\\DRR");
    put(DCM_ConversionType, "WSD"); // workstation
    put(DCM_DerivationDescription,
        "DRR (digitally reconstructed radiograph) of a treatment beam, beam's eye view; values: " +
            info.valueDescription);
}

/** The RT Image module's geometry: the beam (IEC 61217), the receptor and the pixels' place
 *  on it (rt_image.h). */
void putGeometry(const Put& put, const DetectorImage& image, const RtPlanBeam& planBeam) {
    const TreatmentBeam& b = planBeam.beam;
    const ConeCamera& c = image.camera;
    // The camera is in the patient's frame (LPS, beamLimitingDeviceToLps): the patient
    // directions of the rows and columns, as the XA says them.
    put(DCM_PatientOrientation,
        patientOrientationLetters(c.u) + "\\" + patientOrientationLetters(c.v));
    std::string label = planBeam.name.empty() ? "DRR" : "DRR " + planBeam.name;
    if (label.size() > 16) label.resize(16); // RTImageLabel is a SH
    put(DCM_RTImageLabel, label);
    put(DCM_RTImageName,
        planBeam.name.empty() ? "DRR of a treatment beam" : "DRR of beam " + planBeam.name);
    put(DCM_RTImagePlane, "NORMAL");
    // The receptor's origin: on the beam axis at SID, shifted by a principal point offset; its
    // axes turn with the collimator (the beam's eye view).
    const double coll = b.collimatorDeg * 3.14159265358979323846 / 180.0;
    const double sx = c.principalOffset.x * c.pitchU, sy = -c.principalOffset.y * c.pitchV;
    const glm::dvec3 translation(std::cos(coll) * sx - std::sin(coll) * sy,
                                 std::sin(coll) * sx + std::cos(coll) * sy, b.sad - b.sid);
    put(DCM_XRayImageReceptorTranslation, ds3(translation));
    put(DCM_XRayImageReceptorAngle, ds(b.collimatorDeg));
    put(DCM_ImagePlanePixelSpacing, ds(c.pitchV) + "\\" + ds(c.pitchU)); // rows, then columns
    put(DCM_RTImagePosition,
        ds(-0.5 * (c.width - 1) * c.pitchU) + "\\" + ds(0.5 * (c.height - 1) * c.pitchV));
    put(DCM_RadiationMachineSAD, ds(b.sad));
    put(DCM_RTImageSID, ds(b.sid));
    if (planBeam.number != 0) put(DCM_ReferencedBeamNumber, std::to_string(planBeam.number));
    put(DCM_GantryAngle, ds(b.gantryDeg));
    put(DCM_BeamLimitingDeviceAngle, ds(b.collimatorDeg));
    put(DCM_PatientSupportAngle, ds(b.couchDeg));
    put(DCM_IsocenterPosition, ds3(b.isocentre));
    put(DCM_PatientPosition, patientPositionName(b.position));
}

} // namespace

void writeRtImageDicom(const std::filesystem::path& path, const DetectorImage& image,
                       const TreatmentBeam& beam, const DicomExportInfo& info) {
    RtPlanBeam b;
    b.beam = beam;
    writeRtImageDicom(path, image, b, info);
}

void writeRtImageDicom(const std::filesystem::path& path, const DetectorImage& image,
                       const RtPlanBeam& beam, const DicomExportInfo& info) {
    if (image.width < 1 || image.height < 1 || image.width > 65535 || image.height > 65535 ||
        image.pixels.size() != std::size_t(image.width) * std::size_t(image.height))
        failWrite(path, "no image to export");
    checkCamera(image, beam.beam);
    const Quantized q = dicom_write::quantize(image.pixels);

    DcmFileFormat file;
    DcmDataset* dset = file.getDataset();
    const Put put = dicom_write::putterFor(dset, path);
    putIdentity(put, info);
    putGeometry(put, image, beam);
    put(DCM_PhotometricInterpretation, "MONOCHROME2");
    // PS3.3 C.8.19.6.4.1.1's terms, as the XA writer uses them: LOG for line integrals, LIN for
    // transmitted intensities; the sign +1: larger values, more intensity (LIN) or attenuation
    // the other way (LOG: larger line integrals, less intensity: -1).
    put(DCM_PixelIntensityRelationship, info.transmission ? "LIN" : "LOG");
    dset->putAndInsertSint16(DCM_PixelIntensityRelationshipSign, info.transmission ? 1 : -1);
    dicom_write::putPixels16(put, dset, q, image.height, image.width, path, info.window);
    writeAtomically(path, [&](const std::filesystem::path& tmp) {
        const OFCondition st = file.saveFile(tmp.c_str(), EXS_LittleEndianExplicit);
        if (st.bad()) failWrite(path, st.text());
    });
}

} // namespace fvr::core
