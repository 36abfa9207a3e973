# What `cmake --install build --prefix P` lays out (included last by the
# top-level CMakeLists.txt):
#   P/bin/mmval
#   P/share/mmval/reference-data/          literature and experiment values
#   P/share/mmval/cases/                   example cases: those that need nothing outside the
#                                          repository, and those that read a shared data set
#                                          installed below (their "../../shared/data/" paths
#                                          rewritten to "../shared-data/")
#   P/share/mmval/cases/NOT-INSTALLED.txt  the cases left out, and why
#   P/share/mmval/shared-data/<set>/       the shared data sets those cases read, copied whole
#                                          from MMVAL_SHARED_DATA_DIR with PROVENANCE.md and licence
#   P/share/man/man1/mmval.1               from `mmval --help` (cmake/GenerateDocs.cmake)
#   P/share/bash-completion/completions/mmval
#   P/share/doc/mmval/                     README, LICENSE, CITATION.cff
#   P/include/mmval/core/, P/lib/libmmval_core.a, P/lib/cmake/mmval/
#                                          the core library as a CMake package:
#                                          find_package(mmval), target mmval::core
# An installed mmval finds share/mmval from its own location
# (core/include/mmval/core/DataPaths.hpp); MMVAL_DATA_DIR overrides it.
include(GNUInstallDirs)

install(TARGETS mmval RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The libraries are static by default and live inside the binary; a
# -DBUILD_SHARED_LIBS=ON build installs them beside it, in ../lib (the run path).
if(BUILD_SHARED_LIBS)
  foreach(lib mmval_tracking mmval_simulate mmval_openfoam mmval_particles mmval_compare mmval_reports mmval_validate)
    if(TARGET ${lib})
      install(TARGETS ${lib} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
    endif()
  endforeach()
endif()

# The core library (units, case files, tracks CSV, result.json, VTK output) as a CMake
# package for programs that read or write mmval's files (cmake/mmvalConfig.cmake.in).
install(TARGETS mmval_core EXPORT mmvalTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${CMAKE_SOURCE_DIR}/core/include/mmval DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(FILES ${MMVAL_GENERATED_DIR}/mmval/core/BuildInfo.hpp DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/mmval/core)
install(EXPORT mmvalTargets NAMESPACE mmval:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/mmval)
include(CMakePackageConfigHelpers)
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/mmvalConfig.cmake.in ${CMAKE_BINARY_DIR}/share/cmake/mmvalConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/mmval)
write_basic_package_version_file(${CMAKE_BINARY_DIR}/share/cmake/mmvalConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/share/cmake/mmvalConfig.cmake ${CMAKE_BINARY_DIR}/share/cmake/mmvalConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/mmval)

set(MMVAL_INSTALL_DATADIR ${CMAKE_INSTALL_DATADIR}/mmval)
install(DIRECTORY ${CMAKE_SOURCE_DIR}/reference-data/ DESTINATION ${MMVAL_INSTALL_DATADIR}/reference-data)

# The shared data sets beside a checkout (one folder per set, each with its
# PROVENANCE.md and licence). They stay out of the repository; an install copies
# the sets its cases read, so that the installed cases run without the checkout.
if(IS_DIRECTORY ${CMAKE_SOURCE_DIR}/../shared/data)
  get_filename_component(mmval_shared_default ${CMAKE_SOURCE_DIR}/../shared/data ABSOLUTE)
else()
  set(mmval_shared_default "")
endif()
set(MMVAL_SHARED_DATA_DIR "${mmval_shared_default}" CACHE PATH
    "Folder of shared data sets (<set>/ with PROVENANCE.md and a licence); the sets the example cases read are installed in share/mmval/shared-data")

# A data set is installed only with its provenance and licence; returns the
# reason it cannot be, or "" when it can.
function(mmval_shared_set_problem set out_var)
  set(dir ${MMVAL_SHARED_DATA_DIR}/${set})
  if(NOT MMVAL_SHARED_DATA_DIR)
    set(problem "no shared data folder (MMVAL_SHARED_DATA_DIR is empty)")
  elseif(NOT IS_DIRECTORY ${dir})
    set(problem "data set ${set} not found in MMVAL_SHARED_DATA_DIR (${MMVAL_SHARED_DATA_DIR})")
  elseif(NOT EXISTS ${dir}/PROVENANCE.md)
    set(problem "data set ${set} has no PROVENANCE.md (${dir})")
  else()
    file(GLOB licence ${dir}/LICENSE* ${dir}/LICENCE* ${dir}/COPYING*)
    if(licence)
      set(problem "")
    else()
      set(problem "data set ${set} has no LICENSE file (${dir})")
    endif()
  endif()
  set(${out_var} "${problem}" PARENT_SCOPE)
endfunction()

# Case files point at data relative to themselves. A path into the shared data
# ("../../shared/data/<set>/...") works once installed when <set> is installed
# too; any other path beyond the repository ("../../...", absolute) cannot, and
# its case is left out. The classification reads the case files, so editing
# one re-runs the configure step.
file(GLOB mmval_case_files CONFIGURE_DEPENDS ${CMAKE_SOURCE_DIR}/cases/*.toml)
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${mmval_case_files})
set(mmval_installed_cases "")
set(mmval_rewritten_cases "")
set(mmval_skipped_cases "")
set(MMVAL_INSTALLED_SHARED_SETS "")  # also read by tests/apps (the install test)
foreach(f IN LISTS mmval_case_files)
  get_filename_component(name ${f} NAME)
  file(STRINGS ${f} outside REGEX "^[^#]*\"(\\.\\./\\.\\./|/)[^\"]*\"")
  set(reason "")
  set(sets "")
  foreach(line IN LISTS outside)
    string(REGEX MATCHALL "\"(\\.\\./\\.\\./|/)[^\"]*\"" paths "${line}")
    foreach(path IN LISTS paths)
      if(path MATCHES "^\"\\.\\./\\.\\./shared/data/([^/\"]+)(/[^\"]*)?\"$")
        set(set_name ${CMAKE_MATCH_1})
        mmval_shared_set_problem(${set_name} problem)
        if(NOT problem)
          list(APPEND sets ${set_name})
          continue()
        endif()
        set(reason "${path}: ${problem}")
      else()
        set(reason "${path} lies outside the repository")
      endif()
      break()
    endforeach()
    if(reason)
      break()
    endif()
  endforeach()
  if(reason)
    list(APPEND mmval_skipped_cases "${name}: ${reason}")
  elseif(sets)
    # Installed with every "../../shared/data/" (paths and comments) pointing at the installed copy.
    file(READ ${f} text)
    string(REPLACE "../../shared/data/" "../shared-data/" text "${text}")
    set(copy ${CMAKE_BINARY_DIR}/share/cases/${name})
    set(old "")
    if(EXISTS ${copy})
      file(READ ${copy} old)
    endif()
    if(NOT old STREQUAL text)
      file(WRITE ${copy} "${text}")
    endif()
    list(APPEND mmval_rewritten_cases ${copy})
    list(APPEND MMVAL_INSTALLED_SHARED_SETS ${sets})
  else()
    list(APPEND mmval_installed_cases ${f})
  endif()
endforeach()
list(REMOVE_DUPLICATES MMVAL_INSTALLED_SHARED_SETS)
foreach(s IN LISTS MMVAL_INSTALLED_SHARED_SETS)
  # The whole folder: PROVENANCE.md and the licence travel with the data.
  install(DIRECTORY ${MMVAL_SHARED_DATA_DIR}/${s}/ DESTINATION ${MMVAL_INSTALL_DATADIR}/shared-data/${s})
  message(STATUS "mmval install: shared data set ${s} from ${MMVAL_SHARED_DATA_DIR}/${s}")
endforeach()
if(NOT MMVAL_INSTALLED_SHARED_SETS)
  message(STATUS "mmval install: no shared data sets (MMVAL_SHARED_DATA_DIR: \"${MMVAL_SHARED_DATA_DIR}\")")
endif()
install(FILES ${mmval_installed_cases} ${mmval_rewritten_cases} DESTINATION ${MMVAL_INSTALL_DATADIR}/cases)
# Inputs the cases read beside them (generated masks, with their README).
install(DIRECTORY ${CMAKE_SOURCE_DIR}/cases/data DESTINATION ${MMVAL_INSTALL_DATADIR}/cases)
list(LENGTH mmval_installed_cases n_own)
list(LENGTH mmval_rewritten_cases n_shared)
list(LENGTH mmval_skipped_cases n_out)
math(EXPR n_in "${n_own} + ${n_shared}")
message(STATUS "mmval install: ${n_in} example cases (${n_shared} of them read installed shared data); "
               "${n_out} left out (they read data outside the repository that this build did not find)")
if(mmval_skipped_cases)
  list(JOIN mmval_skipped_cases "\n" skipped_text)
else()
  set(skipped_text "(none: every example case is installed)")
endif()
file(WRITE ${CMAKE_BINARY_DIR}/share/NOT-INSTALLED.txt
     "Example cases of the mmval repository that are not installed: each reads data outside the\n"
     "repository that this build did not find or cannot install (MMVAL_SHARED_DATA_DIR, the shared\n"
     "data sets beside a checkout, with their PROVENANCE.md and licence), so it can only run from a checkout.\n"
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
