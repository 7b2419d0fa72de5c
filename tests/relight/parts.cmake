# The relight in parts (host/src/relight/cl_parts.c): a device memory
# limit too small for all the transport columns (needs an OpenCL device:
# PoCL); a relighter that reads the rows again from the file instead of
# holding them (hl_relighter_create_from_file).
hl_test_exe(test_parts ${CMAKE_CURRENT_LIST_DIR}/test_parts.c)
hl_test_cases(test_parts parts quarter refused from_file resident rows both)
hl_test_cases_gpu_shape(test_parts parts quarter refused from_file resident rows both)
