# Scenes with known answers, end to end (white furnace, occluding spherical
# cap). Reference backend only, so no OpenCL device is needed.
hl_test_exe(test_analytic ${CMAKE_CURRENT_LIST_DIR}/test_analytic.c)
hl_test_cases(test_analytic analytic furnace cap)
