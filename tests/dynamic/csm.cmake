# Convolution shadow maps (host/src/dynamic/csm.c, kernels/dynamic/csm_*.cl):
# each kernel against its plain-C twin, the series against the step
# function, the tables' precision, and the visibility on synthetic scenes.
hl_test_exe(test_csm_basis ${CMAKE_CURRENT_LIST_DIR}/test_csm_basis.c)
hl_test_cases(test_csm_basis csm_basis twin shapes series)
hl_test_exe(test_csm_sat ${CMAKE_CURRENT_LIST_DIR}/test_csm_sat.c)
hl_test_cases(test_csm_sat csm_sat twin precision)
hl_test_exe(test_csm_eval ${CMAKE_CURRENT_LIST_DIR}/test_csm_eval.c)
hl_test_cases(test_csm_eval csm_eval twin plane edge contact batch bad_input)
hl_test_cases_gpu_shape(test_csm_basis csm_basis twin)
hl_test_cases_gpu_shape(test_csm_sat csm_sat twin)
hl_test_cases_gpu_shape(test_csm_eval csm_eval twin batch)
