// What the DICOM writers share (dicom_write_internal.h).
#include "dicom_write_internal.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
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

int seriesNumberNow() {
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    return tm.tm_hour * 10000 + tm.tm_min * 100 + tm.tm_sec;
}

void putNewInstance(const PutTag& put, const char* sopClassUid, const DicomExportInfo& info,
                    std::initializer_list<DcmTagKey> emptyType2) {
    char uid[100];
    // Every text we hold is UTF-8 (the reader converts from the source's character set).
    put(DCM_SpecificCharacterSet, "ISO_IR 192");
    put(DCM_SOPClassUID, sopClassUid);
    put(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT));
    put(DCM_StudyInstanceUID, info.studyInstanceUid.empty()
                                  ? dcmGenerateUniqueIdentifier(uid, SITE_STUDY_UID_ROOT)
                                  : info.studyInstanceUid);
    put(DCM_SeriesInstanceUID,
        info.seriesInstanceUid.empty() ? newSeriesInstanceUid() : info.seriesInstanceUid);
    put(DCM_SeriesNumber,
        std::to_string(info.seriesNumber > 0 ? info.seriesNumber : newExportSeriesNumber()));
    put(DCM_InstanceNumber, std::to_string(std::max(1, info.instanceNumber)));
    put(DCM_PatientName, info.patientName);
    put(DCM_PatientID, info.patientId);
    for (const DcmTagKey& t : emptyType2) put(t, "");
    // The source's study and patient (type 2: present, empty when unknown).
    const DicomStudyFields& st = info.study;
    put(DCM_StudyDate, info.studyDate);
    put(DCM_StudyTime, st.studyTime);
    put(DCM_StudyID, st.studyId);
    put(DCM_AccessionNumber, st.accessionNumber);
    put(DCM_ReferringPhysicianName, st.referringPhysicianName);
    put(DCM_PatientSex, st.patientSex);
    put(DCM_PatientBirthDate, st.patientBirthDate);
    if (!st.studyDescription.empty()) put(DCM_StudyDescription, st.studyDescription);
    char date[16], time[16];
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    std::strftime(date, sizeof date, "%Y%m%d", &tm);
    std::strftime(time, sizeof time, "%H%M%S", &tm);
    put(DCM_ContentDate, date);
    put(DCM_ContentTime, time);
}

void putWindow(const PutTag& put, const Quantized& q, const std::optional<DisplayWindowValues>& w) {
    const double centre = w ? w->centre : 0.5 * (q.lo + q.hi);
    const double width = std::max(1e-6, w ? w->width : q.hi - q.lo);
    put(DCM_WindowCenter, decimalString(centre));
    put(DCM_WindowWidth, decimalString(width));
    if (width < 1.0) put(DCM_VOILUTFunction, "LINEAR_EXACT");
}

bool sameCamera(const ConeCamera& expected, const ConeCamera& actual, int width, int height,
                double scale) {
    const double tol = 1e-6 * std::max(1.0, scale);
    return actual.width == width && actual.height == height &&
           glm::length(expected.source - actual.source) <= tol &&
           glm::length(expected.detectorCentre - actual.detectorCentre) <= tol &&
           glm::length(expected.u - actual.u) <= 1e-6 && glm::length(expected.v - actual.v) <= 1e-6;
}

PutTag putterFor(DcmDataset* dset, const std::filesystem::path& path) {
    return [dset, path](const DcmTagKey& tag, const std::string& value) {
        if (dset->putAndInsertString(tag, value.c_str()).bad())
            failWrite(path, std::string("cannot set DICOM tag ") + DcmTag(tag).getTagName());
    };
}

std::string decimalString(double v) {
    char buf[64];
    for (int precision = 16; precision > 1; --precision) {
        std::snprintf(buf, sizeof buf, "%.*g", precision, v);
        if (std::string(buf).size() <= 16) return buf;
    }
    return "0";
}

void putPixels16(const PutTag& put, DcmDataset* dset, const Quantized& q, int rows, int cols,
                 const std::filesystem::path& path,
                 const std::optional<DisplayWindowValues>& window) {
    dset->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    dset->putAndInsertUint16(DCM_Rows, Uint16(rows));
    dset->putAndInsertUint16(DCM_Columns, Uint16(cols));
    dset->putAndInsertUint16(DCM_BitsAllocated, 16);
    dset->putAndInsertUint16(DCM_BitsStored, 16);
    dset->putAndInsertUint16(DCM_HighBit, 15);
    dset->putAndInsertUint16(DCM_PixelRepresentation, 0);
    put(DCM_RescaleSlope, decimalString(q.slope));
    put(DCM_RescaleIntercept, decimalString(q.lo));
    put(DCM_RescaleType, "US");
    putWindow(put, q, window);
    if (dset->putAndInsertUint16Array(DCM_PixelData, q.stored.data(), q.stored.size()).bad())
        failWrite(path, "cannot store the pixel data");
}

} // namespace fvr::core::dicom_write

namespace fvr::core {

int newExportSeriesNumber() {
    static std::atomic<int> last{0};
    int previous = last.load();
    int next = 0;
    do {
        next = std::max(dicom_write::seriesNumberNow(), previous + 1);
    } while (!last.compare_exchange_weak(previous, next));
    return next;
}

std::string newSeriesInstanceUid() {
    char uid[100];
    return dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT);
}

} // namespace fvr::core
