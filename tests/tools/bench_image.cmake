# `haarlight bench --image` (image-space errors, popping under a turning
# map) and `bench --surroundings` (captured lighting's speed) end to end,
# tiny, and their bad options; a bounced file's reference (test_bench_image.sh).
foreach(c image capture bad_options bounced)
  add_test(NAME hl.bench_image.${c} COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/test_bench_image.sh ${c})
  set_tests_properties(hl.bench_image.${c} PROPERTIES
    ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data"
    TIMEOUT 600)
endforeach()
# bench in the GPU shape (HL_DEVICE_SHAPE=gpu): its probe and dot products
add_test(NAME hl.bench_image.image.gpu_shape COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/test_bench_image.sh image)
set_tests_properties(hl.bench_image.image.gpu_shape PROPERTIES
  ENVIRONMENT "HL_DEVICE_SHAPE=gpu;HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data"
  TIMEOUT 600)
