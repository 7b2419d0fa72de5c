# Lighting captured from the surroundings (host/src/capture,
# kernels/capture): the kernel against its twin, the hierarchy on 20,000
# triangles against testing every triangle, the energy of a square
# light against its solid angle, a cross-check through the environment
# path, and bad input.
hl_test_exe(test_capture ${CMAKE_CURRENT_LIST_DIR}/test_capture.c)
hl_test_cases(test_capture capture twin hierarchy energy crosscheck bad)
hl_test_cases_gpu_shape(test_capture capture twin hierarchy crosscheck)
