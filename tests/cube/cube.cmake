# Haar over the six cube faces through the real pipeline (precompute
# --basis cube-haar, the relighter's lighting on the same faces): the
# kernels against their twins, a constant map, OpenCL against the
# reference, rotation, relight against bench-basis's cube colours, bad
# options (test_cube_pipeline.c).
hl_test_exe(test_cube_pipeline ${CMAKE_CURRENT_LIST_DIR}/test_cube_pipeline.c)
hl_test_cases(test_cube_pipeline cube_pipeline kernel constant cl_ref bench bad)
hl_test_cases_gpu_shape(test_cube_pipeline cube_pipeline cl_ref)
