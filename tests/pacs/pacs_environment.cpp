#include "pacs_environment.h"

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include "test_support.h"

namespace fs = std::filesystem;

namespace fvr::test {
namespace {

PacsEnvironment* g_env = nullptr;
const auto* g_registered = ::testing::AddGlobalTestEnvironment(g_env = new PacsEnvironment);

/** One instance of the Slicer head with a new study, a Latin-1 patient name and modality MR:
 *  the character set and modality oracles of the queries. */
std::string writeLatin1Study(const fs::path& path) {
    DcmFileFormat file;
    const fs::path src = *fs::directory_iterator(sharedData() / kSlicer);
    if (file.loadFile(src.c_str()).bad()) throw std::runtime_error("cannot read " + src.string());
    DcmDataset* ds = file.getDataset();
    char uid[100];
    const std::string study = dcmGenerateUniqueIdentifier(uid, SITE_STUDY_UID_ROOT);
    ds->putAndInsertString(DCM_StudyInstanceUID, study.c_str());
    ds->putAndInsertString(DCM_SeriesInstanceUID,
                           dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT));
    ds->putAndInsertString(DCM_SOPInstanceUID,
                           dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT));
    ds->putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 100");
    ds->putAndInsertString(DCM_PatientName, "M\xdcLLER^J\xd6RG"); // Latin-1 bytes
    ds->putAndInsertString(DCM_PatientID, "LATIN1");
    ds->putAndInsertString(DCM_StudyDate, "19991231");
    ds->putAndInsertString(DCM_Modality, "MR");
    ds->putAndInsertString(DCM_AccessionNumber, "ACC-L1");
    if (file.saveFile(path.c_str(), EXS_LittleEndianExplicit).bad())
        throw std::runtime_error("cannot write " + path.string());
    return study;
}

} // namespace

PacsEnvironment& PacsEnvironment::get() { return *g_env; }

void PacsEnvironment::SetUp() {
    if (OrthancServer::executable().empty()) {
        m_skip = "Orthanc is not installed (apt package orthanc; FVR_ORTHANC names another)";
        return;
    }
    for (const char* data : {kPhilips, kSlicer})
        if (!fs::exists(sharedData() / data)) {
            m_skip = "shared data not found: " + (sharedData() / data).string();
            return;
        }
    try {
        startOrthanc();
    } catch (const std::exception& e) {
        m_error = e.what();
    }
}

void PacsEnvironment::startOrthanc() {
    dir = tmpDir() / ("pacs-" + std::to_string(::getpid()));
    m_listenPort = freeLoopbackPort();
    m_orthanc = std::make_unique<OrthancServer>(dir / "orthanc", kOurAe, m_listenPort);
    const int philips = m_orthanc->upload(sharedData() / kPhilips);
    const int slicer = m_orthanc->upload(sharedData() / kSlicer);
    fs::create_directories(dir / "latin1");
    latin1StudyUid = writeLatin1Study(dir / "latin1" / "one.dcm");
    const int latin1 = m_orthanc->upload(dir / "latin1");
    if (philips != 140 || slicer != 93 || latin1 != 1)
        throw std::runtime_error("Orthanc stored " + std::to_string(philips) + "/140, " +
                                 std::to_string(slicer) + "/93, " + std::to_string(latin1) +
                                 "/1 instances:\n" + m_orthanc->log());
}

void PacsEnvironment::TearDown() {
    m_orthanc.reset();
    std::error_code ec;
    if (!dir.empty()) fs::remove_all(dir, ec);
}

core::pacs::Node PacsEnvironment::node() const {
    core::pacs::Node n;
    n.name = "test Orthanc";
    n.calledAe = OrthancServer::kAeTitle;
    n.host = "127.0.0.1";
    n.port = m_orthanc ? m_orthanc->dicomPort() : 104;
    return n;
}

core::pacs::LocalAe PacsEnvironment::local() const {
    core::pacs::LocalAe l;
    l.aeTitle = kOurAe;
    l.listenPort = m_listenPort;
    l.timeoutSeconds = 20;
    return l;
}

std::string dicomTag(const fs::path& file, const std::string& tagName) {
    DcmFileFormat ff;
    DcmTag tag;
    if (ff.loadFile(file.c_str()).bad() || DcmTag::findTagFromName(tagName.c_str(), tag).bad())
        return "";
    OFString value;
    ff.getDataset()->findAndGetOFStringArray(tag, value);
    return value.c_str();
}

} // namespace fvr::test
