# End-to-end checks of the haarlight command (bad input, identical output
# of OpenCL and reference, info, interruption).
foreach(c bad_input bad_options cl_equals_ref info interrupt opencl_faults relight relight_bad relight_surroundings)
  add_test(NAME hl.cli.${c} COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_cli.sh ${c})
  set_tests_properties(hl.cli.${c} PROPERTIES
    ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data;HL_SRC=${CMAKE_SOURCE_DIR}"
    TIMEOUT 600)
endforeach()
