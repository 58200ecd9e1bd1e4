# Packages: a Debian package on Linux (runtime dependencies from dpkg-shlibdeps), a tarball
# elsewhere. `make package` builds it into the build folder.
set(CPACK_PACKAGE_NAME "fvr-workstation")
set(CPACK_PACKAGE_VENDOR "FVR Workstation developers")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "X-ray-like projections of CT/MR studies by Fourier volume rendering")
set(CPACK_PACKAGE_DESCRIPTION
    "FVR Workstation opens DICOM folders, NIfTI and MetaImage volumes and renders X-ray-like
projections by Fourier volume rendering on the GPU (OpenGL 4.3 compute shaders) or the CPU.
It compares interpolation kernels side by side, exports images and DICOM, and fvr-render
generates many digitally reconstructed radiographs quickly from the command line.")
set(CPACK_PACKAGE_CONTACT "FVR Workstation developers <fvr-workstation@localhost>")
set(CPACK_STRIP_FILES ON)
if(CMAKE_SYSTEM_NAME STREQUAL "Linux")
  set(CPACK_GENERATOR "DEB")
  set(CPACK_DEBIAN_PACKAGE_MAINTAINER "FVR Workstation developers <fvr-workstation@localhost>")
  set(CPACK_DEBIAN_PACKAGE_SECTION "science")
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
  set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
  # Mesa or a vendor driver provides OpenGL; the CPU renderer works without.
  set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "libgl1-mesa-dri")
  # The Python module fvr (/usr/lib/python3/dist-packages/fvr) runs on Debian's python3 with
  # numpy; python3 -m fvr.dataset needs Dask (and Zarr for --format zarr).
  if(TARGET fvr_python)
    set(CPACK_DEBIAN_PACKAGE_DEPENDS "python3 (>= 3.11), python3 (<< 3.12), python3-numpy")
    set(CPACK_DEBIAN_PACKAGE_SUGGESTS "python3-distributed, python3-zarr")
  endif()
else()
  set(CPACK_GENERATOR "TGZ")
endif()
include(CPack)
