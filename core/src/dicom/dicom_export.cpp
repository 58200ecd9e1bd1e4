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

namespace {
/** Overlay plane 6000 (PS3.3 C.9.2): a graphics overlay of the image's size at its origin, one
 *  bit per pixel packed into 16-bit words, the first pixel in the lowest bit. */
void putOverlay(DcmDataset* ds, const DicomOverlay& o, int rows, int cols,
                const std::filesystem::path& path) {
    if (o.bits.size() != std::size_t(rows) * std::size_t(cols))
        failWrite(path, "the overlay is " + std::to_string(o.bits.size()) +
                            " pixels, not the image's " + std::to_string(rows) + " x " +
                            std::to_string(cols));
    std::vector<Uint16> words((o.bits.size() + 15) / 16, 0);
    for (std::size_t i = 0; i < o.bits.size(); ++i)
        if (o.bits[i]) words[i / 16] = Uint16(words[i / 16] | (1u << (i % 16)));
    const Sint16 origin[2] = {1, 1};
    bool ok = ds->putAndInsertUint16(DCM_OverlayRows, Uint16(rows)).good() &&
              ds->putAndInsertUint16(DCM_OverlayColumns, Uint16(cols)).good() &&
              ds->putAndInsertString(DCM_OverlayType, "G").good() &&
              ds->putAndInsertSint16Array(DCM_OverlayOrigin, origin, 2).good() &&
              ds->putAndInsertUint16(DCM_OverlayBitsAllocated, 1).good() &&
              ds->putAndInsertUint16(DCM_OverlayBitPosition, 0).good() &&
              ds->putAndInsertString(DCM_OverlayDescription, o.description.c_str()).good();
    auto* data = new DcmOtherByteOtherWord(DcmTag(DCM_OverlayData, EVR_OW));
    ok = ok && data->putUint16Array(words.data(), unsigned(words.size())).good();
    if (!ok || ds->insert(data, true).bad()) {
        delete data; // not in the data set
        failWrite(path, "cannot store the overlay plane");
    }
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
    if (!info.overlay.bits.empty()) putOverlay(ds, info.overlay, H, W, path);
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
