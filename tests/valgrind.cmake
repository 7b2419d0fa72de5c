# Valgrind memcheck over a small scene, OpenCL and reference (label valgrind).
# (Not in a sanitizer build: memcheck cannot run AddressSanitizer binaries.)
if(NOT HL_SANITIZE)
add_test(NAME hl.valgrind.small_scene COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_valgrind.sh)
set_tests_properties(hl.valgrind.small_scene PROPERTIES
  ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_SRC=${CMAKE_SOURCE_DIR}"
  LABELS valgrind SKIP_RETURN_CODE 77 TIMEOUT 900)
endif()
