# The dynamic method's per-vertex irradiance (host/src/dynamic/irradiance.c,
# kernels/dynamic/dyn_irradiance.cl): the kernel against its plain-C twin,
# the twin against area_lights.c's double-checked host functions, and bad
# input. The lights come from the shared maps (skipped where missing).
hl_test_exe(test_dyn_irradiance ${CMAKE_CURRENT_LIST_DIR}/test_dyn_irradiance.c)
hl_test_cases(test_dyn_irradiance dyn_irradiance twin exact bad_input)
hl_test_cases_gpu_shape(test_dyn_irradiance dyn_irradiance twin)
