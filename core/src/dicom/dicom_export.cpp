#include <fvr/core/dicom/dicom_export.h>

#include <fvr/core/io/atomic_file.h>

#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>

#include <fvr/core/errors.h>

#include "dicom_write_internal.h"

namespace fvr::core {

using dicom_write::failWrite;

void writeDicomProjection(const std::filesystem::path& path, const ProjectionImage& image,
                          const DicomExportInfo& info) {
    const int W = image.width, H = image.height;
    if (W <= 0 || H <= 0 || image.pixels.size() != std::size_t(W) * H)
        failWrite(path, "no image to export");
    const dicom_write::Quantized q = dicom_write::quantize(image.pixels);
    const double lo = q.lo, hi = q.hi, slope = q.slope;

    DcmFileFormat file;
    DcmDataset* ds = file.getDataset();
    const dicom_write::PutTag put = dicom_write::putterFor(ds, path);
    // The Secondary Capture IOD's type 2 attributes: present, empty when unknown.
    dicom_write::putNewInstance(put, UID_SecondaryCaptureImageStorage, info,
                                {DCM_PatientBirthDate, DCM_PatientSex, DCM_ReferringPhysicianName,
                                 DCM_StudyID, DCM_AccessionNumber, DCM_Laterality,
                                 DCM_PatientOrientation, DCM_StudyTime});
    put(DCM_Modality, "OT");
    put(DCM_ConversionType, "WSD"); // workstation
    put(DCM_SeriesDescription, info.seriesDescription);
    put(DCM_SeriesNumber, "1");
    put(DCM_InstanceNumber, "1");
    put(DCM_ImageType, "DERIVED\\SECONDARY\\PROJECTION");
    put(DCM_PhotometricInterpretation, "MONOCHROME2");
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
    const double center = (double(lo) + hi) / 2, width = std::max(1e-6, double(hi) - lo);
    std::snprintf(buf, sizeof buf, "%.8g", center);
    put(DCM_WindowCenter, buf);
    std::snprintf(buf, sizeof buf, "%.8g", width);
    put(DCM_WindowWidth, buf);
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
    }
    return info;
}

} // namespace fvr::core
