// A DICOM file's header as rows (the workstation's tag browser).
#include <fvr/core/dicom/multiframe_export.h>

#include <dcmtk/dcmdata/dctk.h>

#include <cstdio>

#include <fvr/core/errors.h>

namespace fvr::core {

namespace {

constexpr std::size_t kMaxValueChars = 256;

std::string tagText(const DcmTagKey& k) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "(%04X,%04X)", k.getGroup(), k.getElement());
    return buf;
}

/** The value as text: strings and numbers as DCMTK prints them (values split by "\"), binary
 *  data by its length; shortened beyond kMaxValueChars. */
std::string valueText(DcmElement& e) {
    const DcmEVR vr = e.ident();
    const bool binary = vr == EVR_OB || vr == EVR_OW || vr == EVR_OF || vr == EVR_OD ||
                        vr == EVR_OL || vr == EVR_OV || vr == EVR_UN || vr == EVR_pixelSQ ||
                        vr == EVR_PixelData || vr == EVR_OverlayData;
    OFString s;
    if (binary || e.getOFStringArray(s).bad()) {
        char n[32];
        std::snprintf(n, sizeof n, "<%lu bytes>", static_cast<unsigned long>(e.getLength()));
        return n;
    }
    std::string v = s.c_str();
    if (v.size() > kMaxValueChars) {
        v.resize(kMaxValueChars);
        v += "…";
    }
    return v;
}

void addItem(DcmItem& item, int depth, std::vector<DicomTagRow>& rows) {
    for (unsigned long i = 0; i < item.card(); ++i) {
        DcmElement* e = item.getElement(i);
        if (!e) continue;
        DcmTag tag = e->getTag();
        DicomTagRow row{tagText(tag), tag.getTagName(), DcmVR(e->ident()).getVRName(), "", depth};
        if (e->ident() == EVR_SQ) {
            auto* sq = static_cast<DcmSequenceOfItems*>(e);
            char n[32];
            std::snprintf(n, sizeof n, "<%lu items>", sq->card());
            row.value = n;
            rows.push_back(row);
            for (unsigned long k = 0; k < sq->card(); ++k)
                if (DcmItem* it = sq->getItem(k)) addItem(*it, depth + 1, rows);
        } else {
            row.value = valueText(*e);
            rows.push_back(row);
        }
    }
}

} // namespace

std::vector<DicomTagRow> readDicomTags(const std::filesystem::path& path) {
    DcmFileFormat file;
    const OFCondition st = file.loadFile(path.c_str());
    if (st.bad()) throw LoadError(path.string() + ": not readable as DICOM (" + st.text() + ")");
    // Values as UTF-8 whatever SpecificCharacterSet the file declares (Latin-1 names ...);
    // where DCMTK cannot convert, they stay as stored.
    file.convertToUTF8();
    std::vector<DicomTagRow> rows;
    if (DcmMetaInfo* meta = file.getMetaInfo()) addItem(*meta, 0, rows);
    addItem(*file.getDataset(), 0, rows);
    return rows;
}

} // namespace fvr::core
