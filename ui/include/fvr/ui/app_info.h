#pragma once
/** Application identity used for QSettings, window titles and the about box. */
namespace fvr::ui {
const char* applicationName(); ///< "FVR Workstation"
const char* organizationName(); ///< QSettings organisation
const char* applicationVersion(); ///< project version
/** The source commit it was built from (short hash, "+" with local changes; "unknown"). */
const char* applicationCommit();
} // namespace fvr::ui
