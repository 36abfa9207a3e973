# Stamps mmval/core/BuildInfo.hpp at every build, not at configure time, so
# that a build tree configured at one commit and rebuilt at another reports
# the commit (and dirty state) it was built from. The script rewrites the
# header only when its text changes, so an unchanged commit rebuilds nothing.
find_package(Git QUIET)
set(MMVAL_GENERATED_DIR ${CMAKE_BINARY_DIR}/generated)
add_custom_target(mmval_buildinfo
  COMMAND ${CMAKE_COMMAND}
          -DSRC=${CMAKE_SOURCE_DIR}
          -DOUT=${MMVAL_GENERATED_DIR}/mmval/core/BuildInfo.hpp
          -DGIT=${GIT_EXECUTABLE}
          -DCXX_ID=${CMAKE_CXX_COMPILER_ID}
          -DCXX_VERSION=${CMAKE_CXX_COMPILER_VERSION}
          -DBUILD_TYPE=${CMAKE_BUILD_TYPE}
          -DOPENCV_VERSION=${OpenCV_VERSION}
          -DEIGEN_VERSION=${Eigen3_VERSION}
          -DGSL_VERSION=${GSL_VERSION}
          -DPETSC_VERSION=${PETSC_VERSION}
          -DMPI_VERSION=${MPI_CXX_VERSION}
          -DTOML_VERSION=${tomlplusplus_VERSION}
          -DJSON_VERSION=${nlohmann_json_VERSION}
          -DPROJECT_VERSION=${PROJECT_VERSION}
          -P ${CMAKE_SOURCE_DIR}/cmake/WriteBuildInfo.cmake
  BYPRODUCTS ${MMVAL_GENERATED_DIR}/mmval/core/BuildInfo.hpp
  COMMENT "Stamping build information (git commit)"
  VERBATIM)
