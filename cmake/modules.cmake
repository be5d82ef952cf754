# Extra dependencies of individual modules, included by the top-level CMakeLists.txt.
# lib/fit: Ceres Solver (the only C++ file, lib/fit/ceres_bridge.cpp) and nanoflann (header only).
set(SPX_FIT_BRIDGE ${CMAKE_SOURCE_DIR}/lib/fit/ceres_bridge.cpp)
if(SPX_FUZZ AND NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  # -fsanitize=fuzzer-no-link is clang-only: with g++ as the C++ compiler the bridge is left out of
  # the fuzz build (the parsers being fuzzed never reach the registration code)
  message(STATUS "smplpix: fuzz build without clang++: ${SPX_FIT_BRIDGE} left out (set CXX=clang++ to include it)")
  set_source_files_properties(${SPX_FIT_BRIDGE} PROPERTIES HEADER_FILE_ONLY ON)
  return()
endif()
find_package(Ceres REQUIRED)
find_path(SPX_NANOFLANN_INCLUDE nanoflann.hpp REQUIRED)
# Ceres::ceres carries Eigen/glog include paths; mark them SYSTEM so their warnings never trip -Werror
get_target_property(_spx_ceres_inc Ceres::ceres INTERFACE_INCLUDE_DIRECTORIES)
if(_spx_ceres_inc)
  target_include_directories(smplpix SYSTEM PRIVATE ${_spx_ceres_inc})
endif()
target_include_directories(smplpix SYSTEM PRIVATE ${SPX_NANOFLANN_INCLUDE})
target_link_libraries(smplpix PRIVATE Ceres::ceres)
set(SPX_CXX_WARN -Wall -Wextra -Wshadow -Wno-unused-parameter)
if(SPX_WERROR)
  list(APPEND SPX_CXX_WARN -Werror)
endif()
target_compile_options(smplpix PRIVATE $<$<COMPILE_LANGUAGE:CXX>:${SPX_CXX_WARN}>)
