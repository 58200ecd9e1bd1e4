#include <fvr/gpu/bindings.h>

namespace fvr::gpu {

std::string bindingsGlsl() {
    std::string text = "// common/bindings.glsl: generated from fvr/gpu/bindings.h (the binding "
                       "points the host uses).\n";
    for (const auto& b : kGlslBindings)
        text += "#define FVR_" + std::string(b.glsl) + " " + std::to_string(b.point) + "\n";
    return text;
}

} // namespace fvr::gpu
