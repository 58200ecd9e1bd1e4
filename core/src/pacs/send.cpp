// C-STORE of files to a PACS.
#include "pacs_internal.h"

#include <dcmtk/dcmnet/diutil.h>

#include <map>
#include <set>

namespace fs = std::filesystem;

namespace fvr::core::pacs {
namespace {

struct FileInfo {
    fs::path path;
    std::string sopClass, transferSyntax;
};

FileInfo readInfo(const fs::path& path) {
    DcmFileFormat file;
    OFCondition cond = file.loadFile(path.c_str(), EXS_Unknown, EGL_noChange, 4096);
    if (cond.bad())
        throw PacsError(path.string() + ": cannot be sent: not a readable DICOM file (" +
                        cond.text() + ")");
    OFString sopClass, sopInstance;
    DcmMetaInfo* meta = file.getMetaInfo();
    meta->findAndGetOFString(DCM_MediaStorageSOPClassUID, sopClass);
    if (sopClass.empty()) file.getDataset()->findAndGetOFString(DCM_SOPClassUID, sopClass);
    file.getDataset()->findAndGetOFString(DCM_SOPInstanceUID, sopInstance);
    if (sopClass.empty() || sopInstance.empty())
        throw PacsError(path.string() + ": cannot be sent: no SOP class or instance UID");
    const DcmXfer xfer(file.getDataset()->getOriginalXfer());
    return {path, sopClass.c_str(), xfer.getXferID()};
}

} // namespace

void sendFiles(const Node& node, const LocalAe& local, const std::vector<fs::path>& files) {
    if (files.empty()) return;
    std::vector<FileInfo> infos;
    std::map<std::string, std::set<std::string>> syntaxes; // by SOP class
    for (const auto& path : files) {
        infos.push_back(readInfo(path));
        syntaxes[infos.back().sopClass].insert(infos.back().transferSyntax);
    }
    detail::Scu scu(node, local);
    for (const auto& [sopClass, ts] : syntaxes)
        for (const auto& t : ts) { // one context per (class, syntax): the file goes as it is
            OFList<OFString> one;
            one.push_back(t.c_str());
            scu.addPresentationContext(sopClass.c_str(), one);
        }
    scu.connect("storage of " + std::to_string(syntaxes.size()) + " SOP classes");
    for (const FileInfo& info : infos) {
        const T_ASC_PresentationContextID pc =
            scu.findPresentationContextID(info.sopClass.c_str(), info.transferSyntax.c_str());
        if (pc == 0)
            throw PacsError(describe(node) + ": the PACS does not accept " +
                            dcmFindNameOfUID(info.sopClass.c_str(), info.sopClass.c_str()) +
                            " in " + DcmXfer(info.transferSyntax.c_str()).getXferName() + " (" +
                            info.path.string() + ")");
        Uint16 status = 0;
        const OFCondition cond = scu.sendSTORERequest(pc, info.path.c_str(), nullptr, status);
        scu.check(cond, "C-STORE of " + info.path.string());
        if (status != STATUS_Success && (status & 0xF000) != 0xB000)
            throw PacsError(describe(node) + ": the PACS refused " + info.path.string() + ": " +
                            DU_cstoreStatusString(status));
    }
    scu.close(false);
}

} // namespace fvr::core::pacs
