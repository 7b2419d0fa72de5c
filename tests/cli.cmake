# End-to-end checks of the haarlight command (bad input, identical output
# of OpenCL and reference, info, interruption).
foreach(c bad_input bad_options cl_equals_ref info interrupt opencl_faults relight relight_bad relight_surroundings)
  add_test(NAME hl.cli.${c} COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_cli.sh ${c})
  set_tests_properties(hl.cli.${c} PROPERTIES
    ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data;HL_SRC=${CMAKE_SOURCE_DIR}"
    TIMEOUT 600)
endforeach()
# the GPU shape forced on the device (HL_DEVICE_SHAPE=gpu): files and
# relit colours equal to the reference's in that shape too
foreach(c cl_equals_ref relight)
  add_test(NAME hl.cli.${c}.gpu_shape COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_cli.sh ${c})
  set_tests_properties(hl.cli.${c}.gpu_shape PROPERTIES
    ENVIRONMENT "HL_DEVICE_SHAPE=gpu;HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp/gpu_shape;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data;HL_SRC=${CMAKE_SOURCE_DIR}"
    TIMEOUT 600)
endforeach()
file(MAKE_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}/tmp/gpu_shape)
