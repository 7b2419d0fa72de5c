# Precompute (host/src/precompute, kernels/precompute): truncation and
# quantisation against their plain-C twins (needs an OpenCL device: PoCL),
# and the whole chunk path.
hl_test_exe(test_truncate ${CMAKE_CURRENT_LIST_DIR}/test_truncate.c)
hl_test_cases(test_truncate truncate twin)
hl_test_exe(test_quantize ${CMAKE_CURRENT_LIST_DIR}/test_quantize.c)
hl_test_cases(test_quantize quantize twin dither)
hl_test_exe(test_precompute ${CMAKE_CURRENT_LIST_DIR}/test_precompute.c)
hl_test_cases(test_precompute precompute pipeline)
hl_test_cases_gpu_shape(test_truncate truncate twin)
hl_test_cases_gpu_shape(test_quantize quantize twin)
hl_test_cases_gpu_shape(test_precompute precompute pipeline)
# Address-space limits cannot work under AddressSanitizer's shadow memory.
if(NOT HL_SANITIZE)
  hl_test_cases(test_precompute precompute ref_oom)
endif()
# Interreflection (precompute --bounces): a spherical cavity against its
# exact series, the white furnace, the gather kernel against its twin.
hl_test_exe(test_bounce ${CMAKE_CURRENT_LIST_DIR}/test_bounce.c)
target_link_libraries(test_bounce PRIVATE ZLIB::ZLIB) # bounce.floats rewrites a values file's checksum
hl_test_cases(test_bounce bounce cavity furnace twin colour shards floats half bad)
hl_test_cases_gpu_shape(test_bounce bounce twin colour)
