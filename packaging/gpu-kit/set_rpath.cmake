# cmake -DFILE=PROGRAM -P set_rpath.cmake: the kit program's DT_RPATH exactly $ORIGIN/../lib.
# The build tree's may carry CMake's install padding ("$ORIGIN/../lib:"), whose empty entry
# would make the loader search the current directory. CMake's own ELF editor, no patchelf.
file(RPATH_SET FILE "${FILE}" NEW_RPATH "\$ORIGIN/../lib")
