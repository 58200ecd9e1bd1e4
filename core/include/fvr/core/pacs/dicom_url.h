#pragma once
/** dicom://CALLED_AE@host:port[/STUDY_UID[/SERIES_UID]]: how fvr-render and the workstation
 *  name a PACS node and what to fetch from it. */
#include <string>

#include <fvr/core/pacs/pacs.h>

namespace fvr::core::pacs {

struct DicomUrl {
    Node node; ///< name empty, retrieve Get
    std::string studyUid, seriesUid; ///< empty when absent
};

/** True when `text` starts with "dicom://" (then parseDicomUrl decides whether it is valid). */
bool isDicomUrl(const std::string& text);

/** Parses the URL. Throws PacsError naming the URL and the problem: no "dicom://", no AE title
 *  or an invalid one, no host, a port that is not a number in 1..65535, a UID that is not
 *  digits and dots (at most 64 characters), or more than two path parts. The port defaults to
 *  104 when absent. */
DicomUrl parseDicomUrl(const std::string& text);

/** The URL again (for messages and JSON). */
std::string toString(const DicomUrl& url);

} // namespace fvr::core::pacs
