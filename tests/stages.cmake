# OpenCL stages against their plain-C twins (needs an OpenCL device: PoCL).
hl_test_exe(test_stages test_stages.c)
hl_test_cases(test_stages stages cube2para haar truncate quantize pipeline dither)
