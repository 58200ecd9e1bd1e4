// A cone-beam DRR as an X-Ray Angiographic image whose XA Positioner module holds its C-arm
// (xray_geometry.h). Why XA: the camera is a C-arm's by DICOM's own positioner angles
// (PS3.3 C.8.7.5), which readXrayGeometry reads from any X-ray; an RT Image would need the
// IEC 61217 gantry and couch angles instead, which express a cranial tilt only through a couch
// rotation.
#include <fvr/core/dicom/xray_geometry.h>

#include <fvr/core/io/atomic_file.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>

#include <fvr/core/errors.h>

#include "dicom_write_internal.h"

namespace fvr::core {

namespace {

using dicom_write::failWrite;
using dicom_write::quantize;
using dicom_write::Quantized;

std::string ds(double v) { return dicom_write::decimalString(v); }

/** Throws SettingsError unless the image's camera is the C-arm's. */
void checkCamera(const DetectorImage& image, const CArm& arm) {
    const ConeCamera& c = image.camera;
    const ConeCamera e =
        cArmCamera(arm, image.width, image.height, c.pitchU, c.pitchV, c.principalOffset);
    if (!dicom_write::sameCamera(e, c, image.width, image.height, arm.sid))
        throw SettingsError("the DRR's camera is not the C-arm's (primary " + ds(arm.primaryDeg) +
                            ", secondary " + ds(arm.secondaryDeg) + " deg, SID " + ds(arm.sid) +
                            ", SOD " + ds(arm.sod) +
                            " mm): an X-ray image can only carry a C-arm's geometry");
}

/** Throws unless the views make one run: images of one size, each the camera of its C-arm, the
 *  C-arms differing only in their angles (an XA's increments hold nothing else). */
void checkRun(const std::filesystem::path& path, const std::vector<DetectorImage>& views,
              const std::vector<CArm>& arms) {
    if (views.empty() || views.size() != arms.size())
        failWrite(path, "expected one C-arm per view, found " + std::to_string(views.size()) +
                            " views and " + std::to_string(arms.size()) + " C-arms");
    const DetectorImage& a = views[0];
    for (std::size_t k = 0; k < views.size(); ++k) {
        const DetectorImage& v = views[k];
        if (v.width < 1 || v.height < 1 || v.width > 65535 || v.height > 65535 ||
            v.pixels.size() != std::size_t(v.width) * std::size_t(v.height))
            failWrite(path, "view " + std::to_string(k + 1) + ": no image to export");
        checkCamera(v, arms[k]);
        if (v.width != a.width || v.height != a.height || v.camera.pitchU != a.camera.pitchU ||
            v.camera.pitchV != a.camera.pitchV ||
            v.camera.principalOffset != a.camera.principalOffset || arms[k].sid != arms[0].sid ||
            arms[k].sod != arms[0].sod || arms[k].isocentre != arms[0].isocentre)
            throw SettingsError("view " + std::to_string(k + 1) +
                                " differs from the first in its detector, SID, SOD or isocentre: "
                                "an X-ray run's frames differ only in their positioner angles");
    }
    if (views.size() > 16384)
        throw SettingsError("a run of " + std::to_string(views.size()) +
                            " views: at most 16384 frames");
}

/** A rotational run: the positioner moved (DYNAMIC), each frame's angles as offsets from the
 *  first (PS3.3 C.8.7.5.1.3), and the Cine and Multi-frame modules. */
void putRun(const std::function<void(const DcmTagKey&, const std::string&)>& put, DcmDataset* dset,
            const std::vector<CArm>& arms, const std::filesystem::path& path) {
    std::string primary, secondary;
    for (std::size_t k = 0; k < arms.size(); ++k) {
        if (k > 0) {
            primary += '\\';
            secondary += '\\';
        }
        primary += ds(arms[k].primaryDeg - arms[0].primaryDeg);
        secondary += ds(arms[k].secondaryDeg - arms[0].secondaryDeg);
    }
    put(DCM_NumberOfFrames, std::to_string(arms.size()));
    if (dset->putAndInsertTagKey(DCM_FrameIncrementPointer, DCM_FrameTime).bad())
        failWrite(path, "cannot set FrameIncrementPointer");
    put(DCM_FrameTime, "100"); // nominal: a DRR run has no time
    put(DCM_PositionerMotion, "DYNAMIC");
    put(DCM_PositionerPrimaryAngleIncrement, primary);
    put(DCM_PositionerSecondaryAngleIncrement, secondary);
}

using Put = dicom_write::PutTag;

/** Patient, study, series, equipment and image identification (XA IOD's type 1 and 2). */
void putIdentity(const Put& put, const DicomExportInfo& info) {
    // The XA IOD's type 2 attributes: present, empty when unknown.
    dicom_write::putNewInstance(
        put, UID_XRayAngiographicImageStorage, info,
        {DCM_Laterality, DCM_KVP, DCM_XRayTubeCurrent, DCM_ExposureTime, DCM_Exposure});
    put(DCM_Modality, "XA");
    put(DCM_Manufacturer, "FVR Workstation");
    put(DCM_SeriesDescription, info.seriesDescription);
    put(DCM_ImageType, "DERIVED\\SECONDARY\\SINGLE PLANE");
    put(DCM_DerivationDescription,
        "cone-beam DRR (digitally reconstructed radiograph); values: " + info.valueDescription);
    put(DCM_RadiationSetting, "GR");
}

/** The XA Positioner module and the detector from the C-arm; the isocentre and the principal
 *  offset, which no X-ray attribute holds, in private tags. */
void putGeometry(const Put& put, DcmDataset* ds_, const DetectorImage& image, const CArm& arm,
                 const std::filesystem::path& path) {
    const ConeCamera& c = image.camera;
    put(DCM_DistanceSourceToDetector, ds(arm.sid));
    put(DCM_DistanceSourceToPatient, ds(arm.sod));
    put(DCM_EstimatedRadiographicMagnificationFactor, ds(arm.sid / arm.sod));
    put(DCM_PositionerPrimaryAngle, ds(arm.primaryDeg));
    put(DCM_PositionerSecondaryAngle, ds(arm.secondaryDeg));
    put(DCM_ImagerPixelSpacing, ds(c.pitchV) + "\\" + ds(c.pitchU)); // rows, then columns
    put(DCM_PatientOrientation,
        patientOrientationLetters(c.u) + "\\" + patientOrientationLetters(c.v));
    put(DcmTagKey(0x0009, 0x0010), "FVR Workstation");
    auto putDoubles = [&](Uint16 element, const std::vector<double>& v) {
        auto* e = new DcmFloatingPointDouble(DcmTag(0x0009, element, EVR_FD));
        if (e->putFloat64Array(v.data(), v.size()).bad() || ds_->insert(e, true).bad())
            failWrite(path, "cannot store the private geometry tags");
    };
    putDoubles(0x1001, {arm.isocentre.x, arm.isocentre.y, arm.isocentre.z});
    putDoubles(0x1002, {c.principalOffset.x, c.principalOffset.y});
}

} // namespace

void writeXrayDicom(const std::filesystem::path& path, const DetectorImage& image, const CArm& arm,
                    const DicomExportInfo& info) {
    writeXrayDicomRun(path, {image}, {arm}, info);
}

void writeXrayDicomRun(const std::filesystem::path& path, const std::vector<DetectorImage>& views,
                       const std::vector<CArm>& arms, const DicomExportInfo& info) {
    checkRun(path, views, arms);
    const DetectorImage& first = views[0];
    std::vector<float> all;
    all.reserve(first.pixels.size() * views.size());
    for (const DetectorImage& v : views) all.insert(all.end(), v.pixels.begin(), v.pixels.end());
    const Quantized q = quantize(all);
    all.clear();
    all.shrink_to_fit();

    DcmFileFormat file;
    DcmDataset* dset = file.getDataset();
    const Put put = dicom_write::putterFor(dset, path);
    putIdentity(put, info);
    putGeometry(put, dset, first, arms[0], path);
    if (views.size() > 1) putRun(put, dset, arms, path);
    put(DCM_PhotometricInterpretation, "MONOCHROME2");
    // The X-Ray Image module's defined terms: LOG for attenuation (line integrals, the log of
    // the transmitted intensity), LIN for values proportional to the beam's intensity.
    put(DCM_PixelIntensityRelationship, info.transmission ? "LIN" : "LOG");
    dicom_write::putPixels16(put, dset, q, first.height, first.width, path, info.window);
    writeAtomically(path, [&](const std::filesystem::path& tmp) {
        const OFCondition st = file.saveFile(tmp.c_str(), EXS_LittleEndianExplicit);
        if (st.bad()) failWrite(path, st.text());
    });
}

} // namespace fvr::core
