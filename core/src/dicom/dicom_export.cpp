#include <fvr/core/dicom/dicom_export.h>

#include <fvr/core/io/atomic_file.h>

#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>

#include <fvr/core/errors.h>

namespace fvr::core {

namespace {
/** Throws WriteError naming the file and the problem: "<path>: <detail>". */
[[noreturn]] void failWrite(const std::filesystem::path& path, const std::string& detail) {
    throw WriteError(path.string() + ": " + detail);
}

/** Type 2 attributes of the Secondary Capture IOD: present, empty when unknown (dciodvfy); the
 *  study's date is the source's (a study has one date), the content's is now (UTC). */
template <class Put>
void putType2(const Put& put, const DicomExportInfo& info) {
    for (const DcmTagKey& t :
         {DCM_PatientBirthDate, DCM_PatientSex, DCM_ReferringPhysicianName, DCM_StudyID,
          DCM_AccessionNumber, DCM_Laterality, DCM_PatientOrientation, DCM_StudyTime})
        put(t, "");
    put(DCM_StudyDate, info.studyDate);
    char date[16], time[16];
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    std::strftime(date, sizeof date, "%Y%m%d", &tm);
    std::strftime(time, sizeof time, "%H%M%S", &tm);
    put(DCM_ContentDate, date);
    put(DCM_ContentTime, time);
}

} // namespace

void writeDicomProjection(const std::filesystem::path& path, const ProjectionImage& image,
                          const DicomExportInfo& info) {
    const int M = image.size;
    if (M <= 0 || image.pixels.size() != std::size_t(M) * M) failWrite(path, "no image to export");
    float lo = image.pixels[0], hi = image.pixels[0];
    for (float v : image.pixels)
        if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    // stored = (value - lo) / slope, 0..65535
    const double slope = hi > lo ? (double(hi) - lo) / 65535.0 : 1.0;
    std::vector<Uint16> stored(image.pixels.size());
    for (std::size_t i = 0; i < stored.size(); ++i) {
        const double v = std::isfinite(image.pixels[i]) ? image.pixels[i] : lo;
        stored[i] = Uint16(std::clamp(std::lround((v - lo) / slope), 0L, 65535L));
    }

    DcmFileFormat file;
    DcmDataset* ds = file.getDataset();
    char uid[100];
    auto put = [&](const DcmTagKey& tag, const std::string& value) {
        if (ds->putAndInsertString(tag, value.c_str()).bad())
            failWrite(path, std::string("cannot set DICOM tag ") + DcmTag(tag).getTagName());
    };
    put(DCM_SOPClassUID, UID_SecondaryCaptureImageStorage);
    put(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT));
    put(DCM_StudyInstanceUID, info.studyInstanceUid.empty()
                                  ? dcmGenerateUniqueIdentifier(uid, SITE_STUDY_UID_ROOT)
                                  : info.studyInstanceUid);
    put(DCM_SeriesInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT));
    put(DCM_PatientName, info.patientName);
    put(DCM_PatientID, info.patientId);
    putType2(put, info);
    put(DCM_Modality, "OT");
    put(DCM_ConversionType, "WSD"); // workstation
    put(DCM_SeriesDescription, info.seriesDescription);
    put(DCM_SeriesNumber, "1");
    put(DCM_InstanceNumber, "1");
    put(DCM_ImageType, "DERIVED\\SECONDARY\\PROJECTION");
    put(DCM_PhotometricInterpretation, "MONOCHROME2");
    ds->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    ds->putAndInsertUint16(DCM_Rows, Uint16(M));
    ds->putAndInsertUint16(DCM_Columns, Uint16(M));
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
      << " (volume index frame); pixel (col,row) at centre + (col - M/2) d right - (row - M/2) d "
         "up";
    put(DCM_ImageComments, c.str());
    if (ds->putAndInsertUint16Array(DCM_PixelData, stored.data(), stored.size()).bad())
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
