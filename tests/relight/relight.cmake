# Relighting (host/src/relight, kernels/relight): selection and dot
# products against their plain-C twins, whole relights (needs an OpenCL
# device: PoCL), and the renderer (reference backend).
hl_test_exe(test_select ${CMAKE_CURRENT_LIST_DIR}/test_select.c)
hl_test_cases(test_select select twin)
hl_test_cases_gpu_shape(test_select select twin)
hl_test_exe(test_relight ${CMAKE_CURRENT_LIST_DIR}/test_relight.c)
hl_test_cases(test_relight relight twin twin_passes relighter into furnace orientation extreme negative)
# twin_passes is the CPU shape's alone (its tile walk's passes)
hl_test_cases_gpu_shape(test_relight relight twin relighter into furnace orientation extreme negative)
hl_test_exe(test_render ${CMAKE_CURRENT_LIST_DIR}/test_render.c)
hl_test_cases(test_render render constant_colour barycentric background explicit_camera bad_args exposure_auto)
# the GPU shape with groups of 8 (HL_TEST_GROUP_CAP), as a device that
# allows fewer work-items a group: more groups a range, each its own tally
add_test(NAME hl.relight.twin.gpu_shape_groups8 COMMAND test_relight twin)
set_tests_properties(hl.relight.twin.gpu_shape_groups8 PROPERTIES
  ENVIRONMENT "HL_DEVICE_SHAPE=gpu;HL_TEST_GROUP_CAP=8;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data;HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp"
  TIMEOUT 600)
