// A received dataset (C-GET, C-MOVE or the listener) into the local store.
#include "pacs_internal.h"

#include <fvr/core/errors.h>

namespace fs = std::filesystem;

namespace fvr::core::pacs::detail {

namespace {

const DcmTagKey kRecordTags[] = {
    DCM_SpecificCharacterSet, DCM_StudyInstanceUID, DCM_PatientName,       DCM_PatientID,
    DCM_PatientBirthDate,     DCM_StudyDate,        DCM_StudyTime,         DCM_AccessionNumber,
    DCM_StudyDescription,     DCM_Modality,         DCM_SeriesInstanceUID, DCM_SeriesDescription,
    DCM_SeriesNumber};

std::string getString(DcmItem& item, const DcmTagKey& tag) {
    OFString value;
    item.findAndGetOFString(tag, value);
    return value.c_str();
}

} // namespace

StoredDataset storeDataset(LocalStore& store, DcmDataset& dataset, Area area) {
    // The records from a copy of the few elements they need, in UTF-8; the file keeps the
    // dataset as it came.
    DcmItem info;
    for (const DcmTagKey& tag : kRecordTags) {
        DcmElement* element = nullptr;
        if (dataset.findAndGetElement(tag, element).good() && element)
            info.insert(static_cast<DcmElement*>(element->clone()));
    }
    const std::string textProblem = toUtf8(info);
    const StudyRecord study = studyRecordFrom(info);
    const SeriesRecord series = seriesRecordFrom(info);
    const std::string sop = getString(dataset, DCM_SOPInstanceUID);
    if (study.studyUid.empty() || series.seriesUid.empty() || sop.empty())
        throw PacsError("a received instance lacks its study, series or SOP instance UID");
    if (!textProblem.empty())
        store.noteTextProblem("received SOP instance " + sop + " of study " + study.studyUid +
                              ": " + textProblem);
    // The UIDs name the files: storeInstance() refuses, naming them and the rule, any that
    // isValidUid() does not take, before anything is listed or written.
    E_TransferSyntax xfer = dataset.getOriginalXfer();
    if (xfer == EXS_Unknown) xfer = EXS_LittleEndianExplicit;
    DcmFileFormat file(&dataset);
    StoredDataset stored{study.studyUid, series.seriesUid, sop, {}};
    stored.outcome = store.storeInstance(
        study, series, sop,
        [&](const fs::path& tmp) {
            const OFCondition cond = file.saveFile(tmp.c_str(), xfer);
            if (cond.bad())
                throw WriteError(tmp.string() +
                                 ": cannot write the received instance: " + cond.text());
        },
        area);
    return stored;
}

} // namespace fvr::core::pacs::detail
