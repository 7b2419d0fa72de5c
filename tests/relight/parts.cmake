# The relight in parts (host/src/relight/cl_parts.c): a device memory
# limit too small for all the transport columns (needs an OpenCL device:
# PoCL).
hl_test_exe(test_parts ${CMAKE_CURRENT_LIST_DIR}/test_parts.c)
hl_test_cases(test_parts parts quarter refused)
