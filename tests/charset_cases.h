#pragma once
// Patient names in the character sets a PACS sends, as DICOM files the tests write: the bytes
// each set encodes a name with (PS3.5 Annex H and I examples, Latin-1 and Greek by the ISO 8859
// tables) and the same name in UTF-8, written out byte by byte (the oracle).
#include <algorithm>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

namespace fvr::test {

struct CharsetCase {
    std::string label; ///< a word for messages and file names
    std::string charset; ///< SpecificCharacterSet (0008,0005); "" = none written
    std::string raw; ///< PatientName bytes in that set
    std::string utf8; ///< the name in UTF-8
    std::string description; ///< StudyDescription bytes in that set (ASCII when "")
    std::string descriptionUtf8;
    /** Orthanc's name of the set (its DefaultEncoding, in which it answers a C-FIND). */
    std::string orthancEncoding;
};

inline const std::vector<CharsetCase>& charsetCases() {
    static const std::vector<CharsetCase> cases{
        {"latin1", "ISO_IR 100", "M\xFCller^Hans", "M\xC3\xBCller^Hans", "K\xF6pfe", "K\xC3\xB6pfe",
         "Latin1"},
        {"utf8", "ISO_IR 192", "M\xC3\xBCller^Hans", "M\xC3\xBCller^Hans", "", "", "Utf8"},
        // PS3.5 H.3.1: Yamada^Tarou=<kanji>=<hiragana>, JIS X 0208 under ESC $ B.
        {"japanese", "\\ISO 2022 IR 87",
         "Yamada^Tarou=\x1b$B;3ED\x1b(B^\x1b$BB@O:\x1b(B=\x1b$B$d$^$@\x1b(B^\x1b$B$?$m$&\x1b(B",
         "Yamada^Tarou=\xE5\xB1\xB1\xE7\x94\xB0^\xE5\xA4\xAA\xE9\x83\x8E="
         "\xE3\x82\x84\xE3\x81\xBE\xE3\x81\xA0^\xE3\x81\x9F\xE3\x82\x8D\xE3\x81\x86",
         "", "", "JapaneseKanji"},
        // ISO 8859-7: Dionysios^Giorgos.
        {"greek", "ISO_IR 126", "\xC4\xE9\xEF\xED\xF5\xF3\xE9\xEF\xF2^\xC3\xE9\xFE\xF1\xE3\xEF\xF2",
         "\xCE\x94\xCE\xB9\xCE\xBF\xCE\xBD\xCF\x85\xCF\x83\xCE\xB9\xCE\xBF\xCF\x82^"
         "\xCE\x93\xCE\xB9\xCF\x8E\xCF\x81\xCE\xB3\xCE\xBF\xCF\x82",
         "\xE8\xFE\xF1\xE1\xEA\xE1\xF2", "\xCE\xB8\xCF\x8E\xCF\x81\xCE\xB1\xCE\xBA\xCE\xB1\xCF\x82",
         "Greek"}};
    return cases;
}

/** The UIDs a written case study has. */
struct CharsetStudy {
    std::string studyUid, seriesUid;
};

/** Copies the DICOM files of `source` (a folder of one series) into `out` as a new study (new
 *  study, series and SOP instance UIDs) whose PatientName (and StudyDescription, when the case
 *  has one) are the case's bytes under its SpecificCharacterSet, PatientID "CS-<label>". At most
 *  `limit` files. */
inline CharsetStudy writeCharsetStudy(const CharsetCase& c, const std::filesystem::path& source,
                                      const std::filesystem::path& out, int limit = 1000) {
    namespace fs = std::filesystem;
    fs::create_directories(out);
    char uid[100];
    CharsetStudy s{dcmGenerateUniqueIdentifier(uid, SITE_STUDY_UID_ROOT),
                   dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT)};
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(source))
        if (e.is_regular_file()) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    int n = 0;
    for (const fs::path& f : files) {
        if (n >= limit) break;
        DcmFileFormat file;
        if (file.loadFile(f.c_str()).bad()) continue;
        DcmDataset* ds = file.getDataset();
        ds->putAndInsertString(DCM_StudyInstanceUID, s.studyUid.c_str());
        ds->putAndInsertString(DCM_SeriesInstanceUID, s.seriesUid.c_str());
        ds->putAndInsertString(DCM_SOPInstanceUID,
                               dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT));
        if (c.charset.empty())
            ds->findAndDeleteElement(DCM_SpecificCharacterSet);
        else
            ds->putAndInsertString(DCM_SpecificCharacterSet, c.charset.c_str());
        ds->putAndInsertOFStringArray(DCM_PatientName, OFString(c.raw.c_str(), c.raw.size()));
        ds->putAndInsertString(DCM_PatientID, ("CS-" + c.label).c_str());
        if (!c.description.empty())
            ds->putAndInsertOFStringArray(DCM_StudyDescription,
                                          OFString(c.description.c_str(), c.description.size()));
        const fs::path dst = out / ("cs_" + std::to_string(n++) + ".dcm");
        if (file.saveFile(dst.c_str(), EXS_LittleEndianExplicit).bad())
            throw std::runtime_error("cannot write " + dst.string());
    }
    if (n == 0) throw std::runtime_error("no DICOM file in " + source.string());
    return s;
}

} // namespace fvr::test
