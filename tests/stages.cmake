# OpenCL stages against their plain-C twins (needs an OpenCL device: PoCL).
hl_test_exe(test_stages test_stages.c)
hl_test_cases(test_stages stages cube2para haar truncate quantize pipeline dither)
# Address-space limits cannot work under AddressSanitizer's shadow memory.
if(NOT HL_SANITIZE)
  hl_test_cases(test_stages stages ref_oom)
endif()
