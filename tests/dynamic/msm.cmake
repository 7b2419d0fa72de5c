# Moment shadow maps (host/src/dynamic/csm.c with HL_SHADOW_REP_MOMENTS,
# kernels/dynamic/msm_*.cl): each kernel against its plain-C twin, the
# 4MSM bound on known distributions, the tables' precision against the
# moment bias, a receiver plane under a blocker, bad input.
hl_test_exe(test_msm ${CMAKE_CURRENT_LIST_DIR}/test_msm.c)
hl_test_cases(test_msm msm twin bound precision plane bad_input)
hl_test_cases_gpu_shape(test_msm msm twin)
