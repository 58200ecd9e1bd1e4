#pragma once
/** Writes small DICOM RT Plans with DCMTK for the tests (no binary files in the repository):
 *  each beam's first control point with the angles and isocentre asked for, any of them left
 *  out to test the reader's messages. */
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcitem.h>
#include <dcmtk/dcmdata/dcuid.h>

namespace fvr::test {

struct TestBeam {
    int number = 1;
    std::string name = "Field 1";
    std::optional<std::string> gantry = "0", collimator = "0", couch = "0";
    std::optional<std::string> isocentre = "0\\0\\0"; ///< IsocenterPosition, DS backslash list
    std::optional<std::string> sad = "1000";
    std::optional<int> setupReference; ///< ReferencedPatientSetupNumber
    bool controlPoints = true;
};

struct TestPlan {
    std::string sopClass = UID_RTPlanStorage;
    std::string label = "TEST PLAN";
    std::vector<TestBeam> beams{TestBeam{}};
    std::vector<std::pair<int, std::string>> setups{{1, "HFS"}}; ///< number, PatientPosition
    bool beamSequence = true;
};

inline void writeTestRtPlan(const std::filesystem::path& path, const TestPlan& p) {
    DcmFileFormat ff;
    DcmDataset* d = ff.getDataset();
    char uid[100];
    d->putAndInsertString(DCM_SOPClassUID, p.sopClass.c_str());
    d->putAndInsertString(DCM_SOPInstanceUID,
                          dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT));
    d->putAndInsertString(DCM_StudyInstanceUID,
                          dcmGenerateUniqueIdentifier(uid, SITE_STUDY_UID_ROOT));
    d->putAndInsertString(DCM_SeriesInstanceUID,
                          dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT));
    d->putAndInsertString(DCM_Modality, "RTPLAN");
    d->putAndInsertString(DCM_PatientName, "Synthetic^Plan");
    d->putAndInsertString(DCM_PatientID, "FVR-TEST");
    d->putAndInsertString(DCM_RTPlanLabel, p.label.c_str());
    for (const auto& [number, position] : p.setups) {
        DcmItem* s = nullptr;
        d->findOrCreateSequenceItem(DCM_PatientSetupSequence, s, -2);
        s->putAndInsertString(DCM_PatientSetupNumber, std::to_string(number).c_str());
        if (!position.empty()) s->putAndInsertString(DCM_PatientPosition, position.c_str());
    }
    for (const TestBeam& b : p.beamSequence ? p.beams : std::vector<TestBeam>{}) {
        DcmItem* item = nullptr;
        d->findOrCreateSequenceItem(DCM_BeamSequence, item, -2);
        item->putAndInsertString(DCM_BeamNumber, std::to_string(b.number).c_str());
        item->putAndInsertString(DCM_BeamName, b.name.c_str());
        item->putAndInsertString(DCM_TreatmentDeliveryType, "TREATMENT");
        if (b.sad) item->putAndInsertString(DCM_SourceAxisDistance, b.sad->c_str());
        if (b.setupReference)
            item->putAndInsertString(DCM_ReferencedPatientSetupNumber,
                                     std::to_string(*b.setupReference).c_str());
        if (!b.controlPoints) continue;
        DcmItem* cp = nullptr;
        item->findOrCreateSequenceItem(DCM_ControlPointSequence, cp, -2);
        cp->putAndInsertString(DCM_ControlPointIndex, "0");
        if (b.gantry) cp->putAndInsertString(DCM_GantryAngle, b.gantry->c_str());
        if (b.collimator)
            cp->putAndInsertString(DCM_BeamLimitingDeviceAngle, b.collimator->c_str());
        if (b.couch) cp->putAndInsertString(DCM_PatientSupportAngle, b.couch->c_str());
        if (b.isocentre) cp->putAndInsertString(DCM_IsocenterPosition, b.isocentre->c_str());
        DcmItem* cp1 = nullptr; // a second control point, as every plan has (ignored)
        item->findOrCreateSequenceItem(DCM_ControlPointSequence, cp1, -2);
        cp1->putAndInsertString(DCM_ControlPointIndex, "1");
        cp1->putAndInsertString(DCM_GantryAngle, "123");
    }
    if (ff.saveFile(path.c_str(), EXS_LittleEndianExplicit).bad())
        throw std::runtime_error("cannot write the test RT Plan " + path.string());
}

} // namespace fvr::test
