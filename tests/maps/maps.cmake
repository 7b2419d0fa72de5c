# The direction maps (host/src/maps, kernels/maps): each kernel against its
# plain-C twin and its closed forms, suite named after the kernel, and the
# maps' geometry (geom.c) against closed forms.
hl_test_exe(test_cube2para ${CMAKE_CURRENT_LIST_DIR}/test_cube2para.c)
hl_test_cases(test_cube2para cube2para twin)
hl_test_exe(test_env2para ${CMAKE_CURRENT_LIST_DIR}/test_env2para.c)
hl_test_cases(test_env2para env2para twin energy)
hl_test_exe(test_haar ${CMAKE_CURRENT_LIST_DIR}/test_haar.c)
hl_test_cases(test_haar haar twin roundtrip parseval slots)
hl_test_cases_gpu_shape(test_cube2para cube2para twin)
hl_test_cases_gpu_shape(test_env2para env2para twin)
hl_test_cases_gpu_shape(test_haar haar twin)
hl_test_exe(test_geom ${CMAKE_CURRENT_LIST_DIR}/test_geom.c)
hl_test_cases(test_geom geom solid_angle mapping table)
