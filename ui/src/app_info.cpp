#include <fvr/ui/app_info.h>

namespace fvr::ui {
const char* applicationName() { return "FVR Workstation"; }
const char* organizationName() { return "fvr-workstation"; }
const char* applicationVersion() { return FVR_VERSION; }
} // namespace fvr::ui
