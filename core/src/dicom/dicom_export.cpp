#include <fvr/core/dicom/dicom_export.h>

#include <fvr/core/io/atomic_file.h>

#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/errors.h>

#include "dicom_write_internal.h"

namespace fvr::core {

using dicom_write::failWrite;

namespace {

/** PatientOrientation (0020,0020): the patient directions of the rows (towards the image's
 *  right) and of the columns (downwards), "L\\F" for an AP view; empty when the volume's
 *  orientation is unknown (type 2C). */
std::string patientOrientationOf(const ViewFrame& view, const DicomExportInfo& info) {
    if (!info.patientDirection) return "";
    const glm::dmat3& m = *info.patientDirection;
    return patientOrientationLetters(m * glm::dvec3(view.r[0], view.r[1], view.r[2])) + "\\" +
           patientOrientationLetters(m * -glm::dvec3(view.u[0], view.u[1], view.u[2]));
}

} // namespace

void writeDicomProjection(const std::filesystem::path& path, const ProjectionImage& image,
                          const DicomExportInfo& info) {
    const int W = image.width, H = image.height;
    if (W <= 0 || H <= 0 || image.pixels.size() != std::size_t(W) * H)
        failWrite(path, "no image to export");
    const dicom_write::Quantized q = dicom_write::quantize(image.pixels);
    const double lo = q.lo, slope = q.slope;

    DcmFileFormat file;
    DcmDataset* ds = file.getDataset();
    const dicom_write::PutTag put = dicom_write::putterFor(ds, path);
    // The Secondary Capture IOD's type 2 attributes: present, empty when unknown.
    dicom_write::putNewInstance(put, UID_SecondaryCaptureImageStorage, info,
                                {DCM_Laterality, DCM_PatientOrientation, DCM_StudyTime});
    put(DCM_Modality, "OT");
    put(DCM_ConversionType, "WSD"); // workstation
    // The equipment that made the source images; this program is the capture device.
    put(DCM_Manufacturer, info.study.manufacturer);
    put(DCM_SecondaryCaptureDeviceManufacturer, "FVR Workstation");
    put(DCM_PatientOrientation, patientOrientationOf(image.view, info));
    put(DCM_SeriesDescription, info.seriesDescription);
    put(DCM_ImageType, "DERIVED\\SECONDARY\\PROJECTION");
    // An inverted window shows low values bright: MONOCHROME1 says so to any viewer.
    put(DCM_PhotometricInterpretation,
        info.window && info.window->inverted ? "MONOCHROME1" : "MONOCHROME2");
    ds->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    ds->putAndInsertUint16(DCM_Rows, Uint16(H));
    ds->putAndInsertUint16(DCM_Columns, Uint16(W));
    ds->putAndInsertUint16(DCM_BitsAllocated, 16);
    ds->putAndInsertUint16(DCM_BitsStored, 16);
    ds->putAndInsertUint16(DCM_HighBit, 15);
    ds->putAndInsertUint16(DCM_PixelRepresentation, 0);
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.10g", slope);
    put(DCM_RescaleSlope, buf);
    std::snprintf(buf, sizeof buf, "%.10g", double(lo));
    put(DCM_RescaleIntercept, buf);
    put(DCM_RescaleType, "US");
    std::snprintf(buf, sizeof buf, "%.8g\\%.8g", image.pixelSize, image.pixelSize);
    put(DCM_PixelSpacing, buf);
    dicom_write::putWindow(put, q, info.window);
    std::ostringstream c;
    c << "FVR parallel projection; values: " << info.valueDescription << "; dir " << image.view.d[0]
      << " " << image.view.d[1] << " " << image.view.d[2] << "; up " << image.view.u[0] << " "
      << image.view.u[1] << " " << image.view.u[2] << "; right " << image.view.r[0] << " "
      << image.view.r[1] << " " << image.view.r[2]
      << " (volume index frame); pixel (col,row) at centre + (col - W/2) d right - (row - H/2) d "
         "up, W x H = "
      << W << " x " << H << " (integer halves)";
    put(DCM_ImageComments, c.str());
    if (ds->putAndInsertUint16Array(DCM_PixelData, q.stored.data(), q.stored.size()).bad())
        failWrite(path, "cannot store the pixel data");
    writeAtomically(path, [&](const std::filesystem::path& tmp) {
        const OFCondition st = file.saveFile(tmp.c_str(), EXS_LittleEndianExplicit);
        if (st.bad()) failWrite(path, st.text());
    });
}

DicomExportInfo exportInfoFor(const std::optional<DicomSeriesInfo>& series) {
    DicomExportInfo info;
    if (series) {
        info.patientName = series->patientName;
        info.patientId = series->patientId;
        info.studyInstanceUid = series->studyUid;
        info.studyDate = series->studyDate;
        info.study = series->study;
    }
    return info;
}

} // namespace fvr::core
