# What `cmake --install build --prefix P` lays out (included last by the
# top-level CMakeLists.txt):
#   P/bin/mmval
#   P/share/mmval/reference-data/          literature and experiment values
#   P/share/mmval/cases/                   example cases that need nothing outside the repository
#   P/share/mmval/cases/NOT-INSTALLED.txt  the cases left out, and why
#   P/share/man/man1/mmval.1               from `mmval --help` (cmake/GenerateDocs.cmake)
#   P/share/bash-completion/completions/mmval
#   P/share/doc/mmval/                     README, LICENSE, CITATION.cff
# An installed mmval finds share/mmval from its own location
# (core/include/mmval/core/DataPaths.hpp); MMVAL_DATA_DIR overrides it.
include(GNUInstallDirs)

install(TARGETS mmval RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The libraries are static by default and live inside the binary; a
# -DBUILD_SHARED_LIBS=ON build installs them beside it, in ../lib (the run path).
if(BUILD_SHARED_LIBS)
  foreach(lib mmval_core mmval_tracking mmval_simulate mmval_openfoam mmval_particles mmval_compare mmval_reports mmval_validate)
    if(TARGET ${lib})
      install(TARGETS ${lib} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
    endif()
  endforeach()
endif()

set(MMVAL_INSTALL_DATADIR ${CMAKE_INSTALL_DATADIR}/mmval)
install(DIRECTORY ${CMAKE_SOURCE_DIR}/reference-data/ DESTINATION ${MMVAL_INSTALL_DATADIR}/reference-data)

# Case files point at data relative to themselves; those that reach beyond the
# repository ("../../shared/...", absolute paths) cannot work once installed.
file(GLOB mmval_case_files CONFIGURE_DEPENDS ${CMAKE_SOURCE_DIR}/cases/*.toml)
set(mmval_installed_cases "")
set(mmval_skipped_cases "")
foreach(f IN LISTS mmval_case_files)
  file(STRINGS ${f} outside REGEX "^[^#]*=[^#]*\"(\\.\\./\\.\\./|/)[^\"]*\"")
  get_filename_component(name ${f} NAME)
  if(outside)
    list(GET outside 0 first)
    string(STRIP "${first}" first)
    list(APPEND mmval_skipped_cases "${name}: ${first}")
  else()
    list(APPEND mmval_installed_cases ${f})
  endif()
endforeach()
install(FILES ${mmval_installed_cases} DESTINATION ${MMVAL_INSTALL_DATADIR}/cases)
# Inputs the cases read beside them (generated masks, with their README).
install(DIRECTORY ${CMAKE_SOURCE_DIR}/cases/data DESTINATION ${MMVAL_INSTALL_DATADIR}/cases)
list(LENGTH mmval_installed_cases n_in)
list(LENGTH mmval_skipped_cases n_out)
message(STATUS "mmval install: ${n_in} example cases; ${n_out} left out (they read data outside the repository)")
list(JOIN mmval_skipped_cases "\n" skipped_text)
file(WRITE ${CMAKE_BINARY_DIR}/share/NOT-INSTALLED.txt
     "Example cases of the mmval repository that are not installed: each reads data from outside the\n"
     "repository (the shared data sets beside a checkout), so it can only run from a checkout.\n"
     "Run them there, or copy a case and point its paths at your own data.\n\n${skipped_text}\n")
install(FILES ${CMAKE_BINARY_DIR}/share/NOT-INSTALLED.txt DESTINATION ${MMVAL_INSTALL_DATADIR}/cases)

# Man page and bash completion, generated from the built command's --help.
set(MMVAL_MAN_PAGE ${CMAKE_BINARY_DIR}/share/man/man1/mmval.1)
set(MMVAL_COMPLETION ${CMAKE_BINARY_DIR}/share/bash-completion/completions/mmval)
add_custom_command(OUTPUT ${MMVAL_MAN_PAGE} ${MMVAL_COMPLETION}
  COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/share/man/man1 ${CMAKE_BINARY_DIR}/share/bash-completion/completions
  COMMAND ${CMAKE_COMMAND} -DMMVAL=$<TARGET_FILE:mmval> -DMAN=${MMVAL_MAN_PAGE} -DCOMPLETION=${MMVAL_COMPLETION}
          -DVERSION=${PROJECT_VERSION} -P ${CMAKE_SOURCE_DIR}/cmake/GenerateDocs.cmake
  DEPENDS mmval ${CMAKE_SOURCE_DIR}/cmake/GenerateDocs.cmake
  COMMENT "Generating the mmval man page and bash completion from --help")
add_custom_target(mmval_docs ALL DEPENDS ${MMVAL_MAN_PAGE} ${MMVAL_COMPLETION})
install(FILES ${MMVAL_MAN_PAGE} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
install(FILES ${MMVAL_COMPLETION} DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions)

set(mmval_doc_files ${CMAKE_SOURCE_DIR}/README.md)
foreach(f LICENSE CITATION.cff)
  if(EXISTS ${CMAKE_SOURCE_DIR}/${f})
    list(APPEND mmval_doc_files ${CMAKE_SOURCE_DIR}/${f})
  endif()
endforeach()
install(FILES ${mmval_doc_files} DESTINATION ${CMAKE_INSTALL_DOCDIR})
