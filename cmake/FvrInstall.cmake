# Install rules: the programs, the desktop entry and the icon (shaders are embedded).
include(GNUInstallDirs)
set(_fvr_programs fvr-render fvr-register)
if(TARGET fvr-workstation)
  list(APPEND _fvr_programs fvr-workstation)
endif()
install(TARGETS ${_fvr_programs} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT applications)
if(TARGET fvr-workstation)
  install(FILES ${PROJECT_SOURCE_DIR}/packaging/fvr-workstation.desktop
          DESTINATION ${CMAKE_INSTALL_DATADIR}/applications COMPONENT applications)
  install(FILES ${PROJECT_SOURCE_DIR}/resources/icons/fvr-workstation.svg
          DESTINATION ${CMAKE_INSTALL_DATADIR}/icons/hicolor/scalable/apps COMPONENT applications)
endif()
