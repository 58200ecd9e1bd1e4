// The beams of a DICOM RT Plan as treatment beams (rt_plan.h).
#include <fvr/core/dicom/rt_plan.h>

#include "dicom_internal.h"

#include <cmath>
#include <optional>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcitem.h>
#include <dcmtk/dcmdata/dcsequen.h>
#include <dcmtk/dcmdata/dcuid.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/errors.h>

namespace fvr::core {

using namespace dicom_detail;

namespace {

constexpr double kAssumedSad = 1000.0; ///< mm, every isocentric linac's

/** "GantryAngle (300A,011E)". */
std::string tagText(const DcmTagKey& tag) {
    return std::string(DcmTag(tag).getTagName()) + " " + tag.toString().c_str();
}

std::string trimmed(const OFString& s) {
    const std::string r(s.c_str());
    const auto b = r.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return {};
    return r.substr(b, r.find_last_not_of(" \t\r\n") - b + 1);
}

std::string stringOf(DcmItem* item, const DcmTagKey& tag) {
    OFString s;
    if (!item || item->findAndGetOFStringArray(tag, s).bad()) return {};
    return trimmed(s);
}

/** Every value of a numeric element (DS, IS, FL, FD); empty when absent or empty. Throws naming
 *  the file, `where` and the tag when a value is not a finite number. */
std::vector<double> numbersOf(DcmItem* item, const DcmTagKey& tag, const fs::path& file,
                              const std::string& where) {
    std::vector<double> out;
    DcmElement* e = nullptr;
    if (!item || item->findAndGetElement(tag, e).bad() || !e || e->getLength() == 0) return out;
    for (unsigned long i = 0; i < e->getVM(); ++i) {
        Float64 v = 0;
        Float32 f = 0;
        const bool ok = e->ident() == EVR_FL ? item->findAndGetFloat32(tag, f, i).good()
                                             : item->findAndGetFloat64(tag, v, i).good();
        if (e->ident() == EVR_FL) v = f;
        if (e->ident() == EVR_IS) {
            Sint32 n = 0;
            if (item->findAndGetSint32(tag, n, i).bad())
                fail(file, where + tagText(tag) + " '" + stringOf(item, tag) + "' is not a number");
            v = n;
        } else if (!ok || !std::isfinite(v)) {
            fail(file, where + tagText(tag) + " '" + stringOf(item, tag) + "' is not a number");
        }
        out.push_back(v);
    }
    return out;
}

/** The element's first value; throws naming the file, `where` and the tag when it is missing. */
double requiredNumber(DcmItem* item, const DcmTagKey& tag, const fs::path& file,
                      const std::string& where) {
    const std::vector<double> v = numbersOf(item, tag, file, where);
    if (v.empty()) fail(file, where + "no " + tagText(tag));
    return v[0];
}

DcmItem* itemOf(DcmItem* item, const DcmTagKey& seq, unsigned long index = 0) {
    DcmItem* sub = nullptr;
    if (!item || item->findAndGetSequenceItem(seq, sub, long(index)).bad()) return nullptr;
    return sub;
}

unsigned long itemCount(DcmItem* item, const DcmTagKey& seq) {
    DcmSequenceOfItems* s = nullptr;
    if (!item || item->findAndGetSequence(seq, s).bad() || !s) return 0;
    return s->card();
}

std::unique_ptr<DcmFileFormat> loadPlan(const fs::path& path) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) fail(path, "no such RT Plan file (not a regular file)");
    initDcmtk();
    auto ff = std::make_unique<DcmFileFormat>();
    const OFCondition c = ff->loadFile(OFFilename(path.c_str()));
    if (c.bad() || !ff->getDataset())
        fail(path, std::string("not a readable DICOM file (") + c.text() + ")");
    return ff;
}

void checkSopClass(DcmDataset* ds, const fs::path& path) {
    std::string uid = stringOf(ds, DCM_SOPClassUID);
    if (uid.empty()) uid = stringOf(ds, DCM_MediaStorageSOPClassUID);
    if (uid == UID_RTPlanStorage || (uid.empty() && itemCount(ds, DCM_BeamSequence) > 0)) return;
    if (uid == UID_RTIonPlanStorage || itemCount(ds, DCM_IonBeamSequence) > 0)
        fail(path, "an RT Ion Plan (Ion Beam Sequence): only photon and electron RT Plans are "
                   "read");
    fail(path, "not an RT Plan: its SOP class is " +
                   (uid.empty() ? std::string("not stated") : describeSopClass(uid)));
}

/** The patient position of the setup that the beam references. */
PatientPosition setupPosition(DcmDataset* ds, DcmItem* beamItem, const fs::path& path,
                              const std::string& where) {
    const unsigned long setups = itemCount(ds, DCM_PatientSetupSequence);
    if (setups == 0) fail(path, "no " + tagText(DCM_PatientSetupSequence));
    const std::vector<double> ref =
        numbersOf(beamItem, DCM_ReferencedPatientSetupNumber, path, where);
    DcmItem* setup = nullptr;
    if (ref.empty()) {
        if (setups > 1)
            fail(path, where + "no " + tagText(DCM_ReferencedPatientSetupNumber) + " and " +
                           std::to_string(setups) + " patient setups to choose from");
        setup = itemOf(ds, DCM_PatientSetupSequence, 0);
    } else {
        for (unsigned long i = 0; i < setups && !setup; ++i) {
            DcmItem* s = itemOf(ds, DCM_PatientSetupSequence, i);
            const std::vector<double> n = numbersOf(s, DCM_PatientSetupNumber, path, "");
            if (!n.empty() && n[0] == ref[0]) setup = s;
        }
        if (!setup)
            fail(path, where + tagText(DCM_ReferencedPatientSetupNumber) + " " +
                           std::to_string(int(ref[0])) + " names no item of " +
                           tagText(DCM_PatientSetupSequence));
    }
    const std::string position = stringOf(setup, DCM_PatientPosition);
    if (position.empty())
        fail(path, where + "its patient setup has no " + tagText(DCM_PatientPosition) +
                       (stringOf(setup, DCM_PatientAdditionalPosition).empty()
                            ? std::string()
                            : " (only a Patient Additional Position, which is not read)"));
    try {
        return parsePatientPosition(position);
    } catch (const SettingsError& e) {
        fail(path, where + tagText(DCM_PatientPosition) + ": " + e.what());
    }
}

RtPlanBeam readBeam(DcmDataset* ds, DcmItem* item, unsigned long index, RtPlan& plan) {
    const fs::path& path = plan.file;
    std::string where =
        "beam " + std::to_string(index + 1) + " of " + tagText(DCM_BeamSequence) + ": ";
    RtPlanBeam b;
    b.number = int(requiredNumber(item, DCM_BeamNumber, path, where));
    where = "beam number " + std::to_string(b.number) + ": ";
    b.name = stringOf(item, DCM_BeamName);
    b.deliveryType = stringOf(item, DCM_TreatmentDeliveryType);
    const std::vector<double> sad = numbersOf(item, DCM_SourceAxisDistance, path, where);
    b.sadStated = !sad.empty();
    b.beam.sad = b.sadStated ? sad[0] : kAssumedSad;
    if (!(b.beam.sad > 0.0))
        fail(path, where + tagText(DCM_SourceAxisDistance) +
                       ": expected a positive distance, "
                       "found " +
                       stringOf(item, DCM_SourceAxisDistance));
    if (!b.sadStated)
        plan.warnings.push_back(where + "no " + tagText(DCM_SourceAxisDistance) +
                                ": 1000 mm assumed");
    DcmItem* cp = itemOf(item, DCM_ControlPointSequence, 0);
    if (!cp) fail(path, where + "no " + tagText(DCM_ControlPointSequence));
    where += "control point 0: ";
    b.beam.gantryDeg = requiredNumber(cp, DCM_GantryAngle, path, where);
    b.beam.collimatorDeg = requiredNumber(cp, DCM_BeamLimitingDeviceAngle, path, where);
    b.beam.couchDeg = requiredNumber(cp, DCM_PatientSupportAngle, path, where);
    const std::vector<double> iso = numbersOf(cp, DCM_IsocenterPosition, path, where);
    if (iso.size() != 3)
        fail(path,
             where + (iso.empty() ? "no " + tagText(DCM_IsocenterPosition)
                                  : tagText(DCM_IsocenterPosition) + ": expected x\\y\\z, found " +
                                        std::to_string(iso.size()) + " values"));
    b.beam.isocentre = {iso[0], iso[1], iso[2]};
    b.beam.position =
        setupPosition(ds, item, path, "beam number " + std::to_string(b.number) + ": ");
    return b;
}

} // namespace

RtPlan readRtPlan(const fs::path& path) {
    const std::unique_ptr<DcmFileFormat> ff = loadPlan(path);
    DcmDataset* ds = ff->getDataset();
    checkSopClass(ds, path);
    RtPlan plan;
    plan.file = path;
    plan.label = stringOf(ds, DCM_RTPlanLabel);
    const unsigned long n = itemCount(ds, DCM_BeamSequence);
    if (n == 0) fail(path, "no beams: " + tagText(DCM_BeamSequence) + " is missing or empty");
    for (unsigned long i = 0; i < n; ++i)
        plan.beams.push_back(readBeam(ds, itemOf(ds, DCM_BeamSequence, i), i, plan));
    return plan;
}

std::vector<RtPlanBeam> readRtPlanBeams(const fs::path& path) { return readRtPlan(path).beams; }

} // namespace fvr::core
