# The lighting stages: OpenCL against the plain-C twins, and their properties.
hl_test_exe(test_light test_light.c)
hl_test_cases(test_light light env2para energy stages relighter furnace into extreme orientation negative)
