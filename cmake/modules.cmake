# Extra dependencies of individual modules, included by the top-level CMakeLists.txt.
# lib/fit: Ceres Solver (the only C++ file, lib/fit/ceres_bridge.cpp) and nanoflann (header only).
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
