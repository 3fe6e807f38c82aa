# cmake --install: the CLI, the module libraries (exported as mcslam::<module> and the umbrella
# mcslam::mcslam), the public headers, the data files, the CMake package and mcslam.pc, all in
# the GNUInstallDirs places. The optional ROS module is left out of the package (the installed
# CLI has it when it was built): its ROS 1 dependencies come from pkg-config and find_library.
include(CMakePackageConfigHelpers)

set(MCSLAM_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/mcslam)
set(MCSLAM_INSTALL_DATADIR ${CMAKE_INSTALL_DATADIR}/mcslam)
# In link order: each library before those it uses.
set(MCSLAM_EXPORTED_MODULES api app slam synth eval perception optim map mapping place features io core)
set(MCSLAM_EXPORTED_TARGETS mcslam_library)
set(MCSLAM_PC_LIBS "")
foreach(module ${MCSLAM_EXPORTED_MODULES})
  list(APPEND MCSLAM_EXPORTED_TARGETS mcslam_${module})
  string(APPEND MCSLAM_PC_LIBS " -lmcslam_${module}")
endforeach()

install(TARGETS ${MCSLAM_EXPORTED_TARGETS} EXPORT mcslamTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS mcslam RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/mcslam DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        PATTERN ros EXCLUDE)
install(FILES ${PROJECT_BINARY_DIR}/include/mcslam/version.hpp
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/mcslam)
install(FILES ${PROJECT_SOURCE_DIR}/data/orb_vocabulary.bin DESTINATION ${MCSLAM_INSTALL_DATADIR})
install(FILES ${PROJECT_SOURCE_DIR}/LICENSE ${PROJECT_SOURCE_DIR}/docs/licenses.md
        DESTINATION ${CMAKE_INSTALL_DOCDIR})
# The bench report's scripts, when they were bundled (`mcslam bench --report-assets DIR`).
if(TARGET mcslam_report)
  install(FILES ${PROJECT_BINARY_DIR}/report/report.js DESTINATION ${MCSLAM_INSTALL_DATADIR}/report)
endif()
# The live viewer's page (`mcslam run --viewer`), found as a data file.
if(TARGET mcslam_viewer_page)
  install(FILES ${PROJECT_BINARY_DIR}/${MCSLAM_INSTALL_DATADIR}/viewer/viewer.js DESTINATION ${MCSLAM_INSTALL_DATADIR}/viewer)
endif()

install(EXPORT mcslamTargets NAMESPACE mcslam:: DESTINATION ${MCSLAM_INSTALL_CMAKEDIR}
        FILE mcslamTargets.cmake)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/mcslamConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/mcslamConfig.cmake
                              INSTALL_DESTINATION ${MCSLAM_INSTALL_CMAKEDIR}
                              PATH_VARS MCSLAM_INSTALL_DATADIR)
# 0.x: a minor version may break the API.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/mcslamConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/mcslamConfig.cmake ${PROJECT_BINARY_DIR}/mcslamConfigVersion.cmake
        DESTINATION ${MCSLAM_INSTALL_CMAKEDIR})

# mcslam.pc, relocatable: its prefix is found from the file's own folder (pkg-config's pcfiledir).
file(RELATIVE_PATH MCSLAM_PC_PREFIX_FROM_PCDIR ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig
     ${CMAKE_INSTALL_PREFIX})
string(REGEX REPLACE "/$" "" MCSLAM_PC_PREFIX_FROM_PCDIR "${MCSLAM_PC_PREFIX_FROM_PCDIR}")
configure_file(${PROJECT_SOURCE_DIR}/cmake/mcslam.pc.in ${PROJECT_BINARY_DIR}/mcslam.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/mcslam.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

# The Python package (python/CMakeLists.txt sets MCSLAM_PYTHON_INSTALL_DIR).
if(TARGET mcslam_python)
  install(TARGETS mcslam_python LIBRARY DESTINATION ${MCSLAM_PYTHON_INSTALL_DIR}/mcslam)
  install(FILES ${MCSLAM_PYTHON_SOURCES} DESTINATION ${MCSLAM_PYTHON_INSTALL_DIR}/mcslam)
endif()
