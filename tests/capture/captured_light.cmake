# The relighter lit by surroundings (hl_relighter_set_surroundings): OpenCL
# against the reference, reuse of unchanged frames, a cross-check against
# the same surroundings rendered into an EXR, and the shadow of a lamp
# carried around the bunny, and the near-field references (relight
# --reference) against Lambert's formula and each other, and more than one
# capture point (hl_relighter_set_probes).
hl_test_exe(test_captured_light ${CMAKE_CURRENT_LIST_DIR}/test_captured_light.c)
hl_test_cases(test_captured_light captured_light twin reuse crosscheck motion bad reference probes)
hl_test_cases_gpu_shape(test_captured_light captured_light twin crosscheck probes)
