# Tests that are not a single C executable.
if(NOT SPX_SANITIZE)
  add_test(NAME install_consumer COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/install/check_install.sh ${CMAKE_BINARY_DIR})
  set_tests_properties(install_consumer PROPERTIES ENVIRONMENT "SPX_CACHE_DIR=${CMAKE_BINARY_DIR}/cl-cache")
endif()
