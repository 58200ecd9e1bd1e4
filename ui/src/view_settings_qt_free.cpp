// Compiled with core's include paths and no Qt (ui/CMakeLists.txt): view_settings.h stays plain
// data that Qt-free code (the CLI, the Python module, core's settings) can include.
#include <fvr/ui/view_settings.h>

static_assert(sizeof(fvr::ui::ViewSettings) > 0 && sizeof(fvr::ui::FrameEffects) > 0 &&
              sizeof(fvr::ui::PolychromaticSource) > 0);
