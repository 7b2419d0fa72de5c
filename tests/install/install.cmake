# Installation (host/install.cmake): the build installed into a new
# prefix, and tests/install/example.c built and run against it through
# CMake's find_package and through pkg-config. Not under the sanitizers:
# the example would need their runtime too.
if(NOT HL_SANITIZE)
  foreach(how cmake pkgconfig)
    add_test(NAME hl.install.${how}
             COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/test_install.sh ${how} ${CMAKE_BINARY_DIR} ${CMAKE_SOURCE_DIR})
    set_tests_properties(hl.install.${how} PROPERTIES ENVIRONMENT "HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp" TIMEOUT 600)
  endforeach()
endif()
