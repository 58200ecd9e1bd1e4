#pragma once
/** fvr-render and a PACS (core/pacs): INPUT dicom://AE@host:port/STUDY[/SERIES] retrieved into
 *  the local store, --query printing studies as JSON, --send storing the views. */
#include <filesystem>
#include <string>
#include <vector>

#include <fvr/core/pacs/dicom_url.h>
#include <fvr/core/pacs/pacs.h>

#include "options.h"

namespace fvr::cli {

/** Us, from --ae-title, --listen-port, --pacs-timeout and the --tls options. */
core::pacs::LocalAe localAe(const Options& o);

/** A dicom:// URL (INPUT or --send) with the node's --retrieve method and --tls. */
core::pacs::DicomUrl parseNode(const Options& o, const std::string& text);

/** --query's KEY=VALUE terms (each option may hold several, comma-separated): PatientName,
 *  PatientID, AccessionNumber, StudyDate (YYYYMMDD, YYYYMMDD-YYYYMMDD, -YYYYMMDD, YYYYMMDD-),
 *  Modality. Throws SettingsError naming the term. */
core::pacs::StudyQuery parseStudyQuery(const std::vector<std::string>& terms);

/** The checks of the PACS options against each other and INPUT (SettingsError). */
void checkPacsOptions(const Options& o);

/** INPUT dicom://AE@host:port/STUDY[/SERIES]: the folder of the study (series) in the local
 *  store (--store, default core::pacs::defaultLocalStoreRoot()). Taken from the store without
 *  the network when it lists it complete (unless --refresh); else what the store lacks is
 *  retrieved with --retrieve (core::pacs::retrieveMissing: the missing instances of a partial
 *  study, all of it otherwise), progress and a summary on stderr. Throws PacsError. */
std::filesystem::path retrieveInput(const Options& o);

/** --query: the matching studies as JSON on stdout (with their series for --query-series). */
int runQuery(const Options& o);

/** --send: C-STORE of the views' files (`what`: Secondary Capture, or a cone-beam run's X-Ray
 *  Angiographic files, one of which may hold every view) to the node; "sent N <noun>s to ..."
 *  on stderr. */
void sendViews(const Options& o, const std::vector<std::filesystem::path>& files,
               const char* what = "Secondary Capture", const char* noun = "view");

} // namespace fvr::cli
