# Installs the public headers of topocal's modules (run by `cmake --install`, `make install` and cpack, through the
# install(CODE) in cmake/install.cmake) under <includedir>/topocal/<module>/, with their includes of one another
# rewritten from the build tree's "model/device.h" to <topocal/model/device.h>. The installed headers then resolve
# only inside the package: a consumer's own util/io.h or model/config.h on its include path cannot shadow them, and
# consumers need only <includedir> on theirs.
#
# In:  TOPOCAL_SOURCE_DIR, TOPOCAL_BINARY_DIR, TOPOCAL_INCLUDE_DESTINATION (<includedir>/topocal, relative to the
#      prefix or absolute), TOPOCAL_MODULES (the module directories), TOPOCAL_GENERATED_HEADERS (generated headers
#      under ${TOPOCAL_BINARY_DIR}/generated, e.g. util/version.h).
list(JOIN TOPOCAL_MODULES "|" module_alternatives)
set(include_pattern "#include \"((${module_alternatives})/[^\"]+)\"")
set(staging ${TOPOCAL_BINARY_DIR}/installed-headers)
if(IS_ABSOLUTE "${TOPOCAL_INCLUDE_DESTINATION}")
  set(destination "${TOPOCAL_INCLUDE_DESTINATION}")
else()
  set(destination "${CMAKE_INSTALL_PREFIX}/${TOPOCAL_INCLUDE_DESTINATION}")
endif()

set(headers)
foreach(module ${TOPOCAL_MODULES})
  file(GLOB_RECURSE module_headers RELATIVE ${TOPOCAL_SOURCE_DIR} ${TOPOCAL_SOURCE_DIR}/${module}/*.h)
  foreach(header ${module_headers})
    list(APPEND headers "${TOPOCAL_SOURCE_DIR}|${header}")
  endforeach()
endforeach()
foreach(header ${TOPOCAL_GENERATED_HEADERS})
  list(APPEND headers "${TOPOCAL_BINARY_DIR}/generated|${header}")
endforeach()

foreach(entry ${headers})
  string(REPLACE "|" ";" parts "${entry}")
  list(GET parts 0 root)
  list(GET parts 1 header)
  file(READ ${root}/${header} text)
  string(REGEX REPLACE "${include_pattern}" "#include <topocal/\\1>" text "${text}")
  # Written only when changed, so that an unchanged header keeps its time stamp and file(INSTALL) can skip it.
  set(staged ${staging}/${header})
  set(old "")
  if(EXISTS ${staged})
    file(READ ${staged} old)
  endif()
  if(NOT old STREQUAL text)
    file(WRITE ${staged} "${text}")
  endif()
  get_filename_component(subdirectory ${header} DIRECTORY)
  file(INSTALL DESTINATION "${destination}/${subdirectory}" TYPE FILE FILES ${staged})
endforeach()
