# Warnings and sanitizers shared by every target of the project (via fvr_compile_options).
# Aggregates such as RenderParams are meant to be brace-initialised partially (the rest keeps its
# defaults), so -Wmissing-field-initializers is off.
add_library(fvr_compile_options INTERFACE)
target_compile_options(fvr_compile_options INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wshadow -Wno-unused-parameter
                                  -Wno-missing-field-initializers>
  $<$<BOOL:${FVR_STRICT_BUILD}>:-Werror>)
if(FVR_SANITIZE)
  target_compile_options(fvr_compile_options INTERFACE
    -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  target_link_options(fvr_compile_options INTERFACE -fsanitize=address,undefined)
endif()
# Release builds: let the compiler use the instructions of the build machine's baseline (x86-64)
# only; the hot loops are written to vectorise with SSE2.
