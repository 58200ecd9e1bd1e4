// C-FIND (Study Root) at STUDY and SERIES level; records from datasets with UTF-8 strings.
#include "pacs_internal.h"

#include <dcmtk/dcmnet/diutil.h>

#include "../dicom/dicom_charset.h"

#include <fvr/core/text.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>

namespace fvr::core::pacs {
namespace {

/** YYYYMMDD naming a day of the calendar (20231301 and 20230229 do not). */
bool isDate(const std::string& s) {
    if (s.size() != 8 ||
        !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
        return false;
    const std::string_view v = s; // eight digits (checked above): every part parses
    const std::chrono::year_month_day day{
        std::chrono::year{*parseNumber<int>(v.substr(0, 4))},
        std::chrono::month{*parseNumber<unsigned>(v.substr(4, 2))},
        std::chrono::day{*parseNumber<unsigned>(v.substr(6, 2))}};
    return day.ok();
}

std::string get(DcmItem& item, const DcmTagKey& tag) {
    OFString value;
    if (item.findAndGetOFStringArray(tag, value).bad()) return "";
    return std::string(value.c_str());
}

/** An IS (integer string) value, -1 where it is absent or no integer. */
int getInt(DcmItem& item, const DcmTagKey& tag) {
    return parseNumber<int>(get(item, tag)).value_or(-1);
}

/** Sends one C-FIND with `keys`, returns the matches (each converted to UTF-8). */
std::vector<std::unique_ptr<DcmDataset>> find(const Node& node, const LocalAe& local,
                                              DcmDataset& keys, const char* level) {
    detail::Scu scu(node, local);
    scu.addPresentationContext(UID_FINDStudyRootQueryRetrieveInformationModel,
                               detail::uncompressedSyntaxes());
    scu.connect("Study Root C-FIND");
    const T_ASC_PresentationContextID pc =
        scu.context(UID_FINDStudyRootQueryRetrieveInformationModel, "Study Root C-FIND");
    OFList<QRResponse*> responses;
    const OFCondition cond = scu.sendFINDRequest(pc, &keys, &responses);
    std::vector<std::unique_ptr<DcmDataset>> out;
    std::optional<Uint16> final; // the response that ends the C-FIND, if it came
    for (QRResponse* r : responses) {
        std::unique_ptr<QRResponse> owned(r);
        if (!DICOM_PENDING_STATUS(r->m_status)) final = r->m_status;
        if (r->m_dataset && DICOM_PENDING_STATUS(r->m_status)) {
            out.emplace_back(r->m_dataset);
            r->m_dataset = nullptr;
            detail::toUtf8(*out.back());
        }
    }
    const std::string what = std::string("C-FIND at ") + level + " level";
    scu.check(cond, what);
    // Matches without the final response are not the answer: the PACS went silent or away
    // before it said it had sent them all.
    if (!final) {
        const std::string link = scu.linkFailure();
        throw PacsError(link.empty() ? describe(node) + ": " + what +
                                           " ended without the PACS's final response"
                                     : link + " (during " + what + ")");
    }
    if (*final != STATUS_Success)
        throw PacsError(describe(node) + ": " + what + " failed: " + DU_cfindStatusString(*final));
    scu.close(false);
    return out;
}

} // namespace

namespace detail {

std::string toUtf8(DcmItem& item) { return dicom_detail::convertTextToUtf8(item); }

StudyRecord studyRecordFrom(DcmItem& item) {
    StudyRecord s;
    s.studyUid = get(item, DCM_StudyInstanceUID);
    s.patientName = get(item, DCM_PatientName);
    s.patientId = get(item, DCM_PatientID);
    s.patientBirthDate = get(item, DCM_PatientBirthDate);
    s.studyDate = get(item, DCM_StudyDate);
    s.studyTime = get(item, DCM_StudyTime);
    s.accessionNumber = get(item, DCM_AccessionNumber);
    s.description = get(item, DCM_StudyDescription);
    s.modalities = get(item, DCM_ModalitiesInStudy);
    if (s.modalities.empty()) s.modalities = get(item, DCM_Modality);
    s.numberOfSeries = getInt(item, DCM_NumberOfStudyRelatedSeries);
    s.numberOfInstances = getInt(item, DCM_NumberOfStudyRelatedInstances);
    return s;
}

SeriesRecord seriesRecordFrom(DcmItem& item) {
    SeriesRecord s;
    s.seriesUid = get(item, DCM_SeriesInstanceUID);
    s.modality = get(item, DCM_Modality);
    s.description = get(item, DCM_SeriesDescription);
    s.seriesNumber = getInt(item, DCM_SeriesNumber);
    s.numberOfInstances = getInt(item, DCM_NumberOfSeriesRelatedInstances);
    return s;
}

} // namespace detail

std::string studyDateMatch(const StudyQuery& q) {
    for (const auto* d : {&q.dateFrom, &q.dateTo})
        if (!d->empty() && !isDate(*d))
            throw PacsError("the study date \"" + *d + "\" is not a date YYYYMMDD");
    if (!q.dateFrom.empty() && !q.dateTo.empty() && q.dateFrom > q.dateTo)
        throw PacsError("the study date range " + q.dateFrom + "-" + q.dateTo +
                        " ends before it begins");
    if (q.dateFrom.empty() && q.dateTo.empty()) return "";
    if (q.dateFrom == q.dateTo) return q.dateFrom;
    return q.dateFrom + "-" + q.dateTo;
}

std::vector<StudyRecord> findStudies(const Node& node, const LocalAe& local,
                                     const StudyQuery& query) {
    DcmDataset keys;
    keys.putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 192");
    keys.putAndInsertString(DCM_QueryRetrieveLevel, "STUDY");
    keys.putAndInsertString(DCM_StudyInstanceUID, "");
    keys.putAndInsertString(DCM_PatientName, query.patientName.c_str());
    keys.putAndInsertString(DCM_PatientID, query.patientId.c_str());
    keys.putAndInsertString(DCM_AccessionNumber, query.accessionNumber.c_str());
    keys.putAndInsertString(DCM_StudyDate, studyDateMatch(query).c_str());
    keys.putAndInsertString(DCM_ModalitiesInStudy, query.modality.c_str());
    for (const DcmTagKey& tag : {DCM_PatientBirthDate, DCM_StudyTime, DCM_StudyDescription,
                                 DCM_NumberOfStudyRelatedSeries, DCM_NumberOfStudyRelatedInstances})
        keys.insertEmptyElement(tag);
    std::vector<StudyRecord> out;
    for (auto& ds : find(node, local, keys, "STUDY")) out.push_back(detail::studyRecordFrom(*ds));
    std::sort(out.begin(), out.end(), [](const StudyRecord& a, const StudyRecord& b) {
        return std::tie(b.studyDate, b.studyTime, a.studyUid) <
               std::tie(a.studyDate, a.studyTime, b.studyUid);
    });
    return out;
}

std::vector<SeriesRecord> findSeries(const Node& node, const LocalAe& local,
                                     const std::string& studyUid) {
    if (studyUid.empty()) throw PacsError("findSeries needs a study UID");
    DcmDataset keys;
    keys.putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 192");
    keys.putAndInsertString(DCM_QueryRetrieveLevel, "SERIES");
    keys.putAndInsertString(DCM_StudyInstanceUID, studyUid.c_str());
    for (const DcmTagKey& tag : {DCM_SeriesInstanceUID, DCM_Modality, DCM_SeriesDescription,
                                 DCM_SeriesNumber, DCM_NumberOfSeriesRelatedInstances})
        keys.insertEmptyElement(tag);
    std::vector<SeriesRecord> out;
    for (auto& ds : find(node, local, keys, "SERIES")) out.push_back(detail::seriesRecordFrom(*ds));
    std::sort(out.begin(), out.end(), [](const SeriesRecord& a, const SeriesRecord& b) {
        return std::tie(a.seriesNumber, a.seriesUid) < std::tie(b.seriesNumber, b.seriesUid);
    });
    return out;
}

std::vector<InstanceRecord> findInstances(const Node& node, const LocalAe& local,
                                          const std::string& studyUid,
                                          const std::string& seriesUid) {
    if (studyUid.empty()) throw PacsError("findInstances needs a study UID");
    DcmDataset keys;
    keys.putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 192");
    keys.putAndInsertString(DCM_QueryRetrieveLevel, "IMAGE");
    keys.putAndInsertString(DCM_StudyInstanceUID, studyUid.c_str());
    keys.putAndInsertString(DCM_SeriesInstanceUID, seriesUid.c_str());
    keys.insertEmptyElement(DCM_SOPInstanceUID);
    std::vector<InstanceRecord> out;
    for (auto& ds : find(node, local, keys, "IMAGE"))
        out.push_back({get(*ds, DCM_SeriesInstanceUID), get(*ds, DCM_SOPInstanceUID)});
    std::sort(out.begin(), out.end(), [](const InstanceRecord& a, const InstanceRecord& b) {
        return std::tie(a.seriesUid, a.sopInstanceUid) < std::tie(b.seriesUid, b.sopInstanceUid);
    });
    return out;
}

} // namespace fvr::core::pacs
