# Installation: the libraries (static, exported as topocal::<module>), the CLI and its image codec plugin, the public headers under
# include/topocal/<module>/, the bundled data under share/topocal/data, a CMake package (topocalConfig.cmake +
# version), a pkg-config file, and a Debian package through CPack (`cpack -G DEB` in the build tree).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(TOPOCAL_INSTALL_DATADIR ${CMAKE_INSTALL_DATADIR}/topocal/data)
set(TOPOCAL_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/topocal)
set(TOPOCAL_MODULES util model imageio plot calib correct topo pipeline harness report)

foreach(module ${TOPOCAL_MODULES})
  set_target_properties(topocal_${module} PROPERTIES EXPORT_NAME ${module})
  # Consumers write #include <topocal/model/device.h>, and so do the installed headers (cmake/install_headers.cmake).
  target_include_directories(topocal_${module} INTERFACE $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
endforeach()
install(CODE "
  set(TOPOCAL_SOURCE_DIR \"${PROJECT_SOURCE_DIR}\")
  set(TOPOCAL_BINARY_DIR \"${PROJECT_BINARY_DIR}\")
  set(TOPOCAL_INCLUDE_DESTINATION \"${CMAKE_INSTALL_INCLUDEDIR}/topocal\")
  set(TOPOCAL_MODULES \"${TOPOCAL_MODULES}\")
  set(TOPOCAL_GENERATED_HEADERS util/version.h)
  include(\"${PROJECT_SOURCE_DIR}/cmake/install_headers.cmake\")" COMPONENT dev)
list(TRANSFORM TOPOCAL_MODULES PREPEND topocal_ OUTPUT_VARIABLE TOPOCAL_LIBRARY_TARGETS)
install(TARGETS ${TOPOCAL_LIBRARY_TARGETS} EXPORT topocalTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev)
install(TARGETS topocal RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT cli)
# Every verb, and `--version` and the sweep without OpenCV; `topocal` (tools/launcher.cc) runs them from
# <bindir>/../<libexecdir>.
install(TARGETS topocal_full topocal_sweep topocal_detect RUNTIME DESTINATION ${CMAKE_INSTALL_LIBEXECDIR} COMPONENT cli)
# imageio's codec plugin (imageio/imgcodecs_abi.h), where the installed CLI finds it relative to itself
# (<bindir>/../<libdir>/topocal) and programs linking the installed libraries find it by the configured prefix.
install(TARGETS topocal_imgcodecs LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/topocal COMPONENT cli)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/data/ DESTINATION ${TOPOCAL_INSTALL_DATADIR} COMPONENT cli)

install(EXPORT topocalTargets NAMESPACE topocal:: DESTINATION ${TOPOCAL_INSTALL_CMAKEDIR} COMPONENT dev)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/topocalConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/topocalConfig.cmake
                              INSTALL_DESTINATION ${TOPOCAL_INSTALL_CMAKEDIR}
                              PATH_VARS TOPOCAL_INSTALL_DATADIR)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/topocalConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/topocalConfig.cmake ${PROJECT_BINARY_DIR}/topocalConfigVersion.cmake
        DESTINATION ${TOPOCAL_INSTALL_CMAKEDIR} COMPONENT dev)
configure_file(${PROJECT_SOURCE_DIR}/cmake/topocal.pc.in ${PROJECT_BINARY_DIR}/topocal.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/topocal.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT dev)

# The build tree mirrors the installed layout for the data, so that build/libexec/topocal-full finds it the same way an
# installed binary does (relative to itself: <bindir>/../share/topocal/data), never through a source path.
add_custom_target(topocal_data ALL
  COMMAND ${CMAKE_COMMAND} -E copy_directory ${PROJECT_SOURCE_DIR}/data ${PROJECT_BINARY_DIR}/share/topocal/data
  COMMENT "Copying the bundled data into the build tree")
add_dependencies(topocal_full topocal_data)

# Debian package: `cpack -G DEB` in the build tree. Runtime dependencies are Debian 12's packages.
set(CPACK_PACKAGE_NAME topocal)
set(CPACK_PACKAGE_VENDOR "topocal")
set(CPACK_PACKAGE_CONTACT "topocal developers <topocal@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${PROJECT_DESCRIPTION}")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_DEPENDS
    "libopencv-dev (>= 4.6), libceres-dev (>= 2.1), libeigen3-dev (>= 3.4), libapriltag-dev, nlohmann-json3-dev, libfmt-dev, libssl-dev, libsqlite3-dev, zlib1g-dev")
set(CPACK_GENERATOR DEB)
include(CPack)
