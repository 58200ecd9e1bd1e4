// What the DICOM writers share (dicom_write_internal.h).
#include "dicom_write_internal.h"

#include <algorithm>
#include <cmath>
#include <ctime>

#include <fvr/core/errors.h>

namespace fvr::core::dicom_write {

void failWrite(const std::filesystem::path& path, const std::string& detail) {
    throw WriteError(path.string() + ": " + detail);
}

Quantized quantize(const std::vector<float>& pixels) {
    Quantized q;
    bool any = false;
    for (float v : pixels)
        if (std::isfinite(v)) {
            q.lo = any ? std::min(q.lo, double(v)) : v;
            q.hi = any ? std::max(q.hi, double(v)) : v;
            any = true;
        }
    q.slope = q.hi > q.lo ? (q.hi - q.lo) / 65535.0 : 1.0;
    q.stored.resize(pixels.size());
    for (std::size_t i = 0; i < pixels.size(); ++i) {
        const double v = std::isfinite(pixels[i]) ? pixels[i] : q.lo;
        q.stored[i] = Uint16(std::clamp(std::lround((v - q.lo) / q.slope), 0L, 65535L));
    }
    return q;
}

void putNewInstance(const PutTag& put, const char* sopClassUid, const DicomExportInfo& info,
                    std::initializer_list<DcmTagKey> emptyType2) {
    char uid[100];
    put(DCM_SOPClassUID, sopClassUid);
    put(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT));
    put(DCM_StudyInstanceUID, info.studyInstanceUid.empty()
                                  ? dcmGenerateUniqueIdentifier(uid, SITE_STUDY_UID_ROOT)
                                  : info.studyInstanceUid);
    put(DCM_SeriesInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT));
    put(DCM_PatientName, info.patientName);
    put(DCM_PatientID, info.patientId);
    for (const DcmTagKey& t : emptyType2) put(t, "");
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

} // namespace fvr::core::dicom_write
