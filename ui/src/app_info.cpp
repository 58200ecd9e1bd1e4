#include <fvr/ui/app_info.h>

#include "fvr_git_commit.h"

namespace fvr::ui {
const char* applicationName() { return "FVR Workstation"; }
const char* organizationName() { return "fvr-workstation"; }
const char* applicationVersion() { return FVR_VERSION; }
const char* applicationCommit() { return FVR_GIT_COMMIT; }
} // namespace fvr::ui
