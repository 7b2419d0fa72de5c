# The dynamic method's shadow maps (host/src/dynamic/shadow_map.c,
# kernels/dynamic/shadow_raster.cl and its twin, visibility/instances.c):
# kernel against twin, closed forms, rasteriser against Embree, motion,
# frame fitting and bad input.
hl_test_exe(test_shadow_raster ${CMAKE_CURRENT_LIST_DIR}/test_shadow_raster.c)
hl_test_cases(test_shadow_raster shadow_raster twin analytic embree motion frame bad_input)
hl_test_cases_gpu_shape(test_shadow_raster shadow_raster twin)
hl_test_exe(test_shadow_skip ${CMAKE_CURRENT_LIST_DIR}/test_shadow_skip.c)
hl_test_cases(test_shadow_skip shadow_skip planes)
