# Visibility rays (host/src/visibility): the origin offset against closed
# forms (reference backend only).
hl_test_exe(test_rays ${CMAKE_CURRENT_LIST_DIR}/test_rays.c)
hl_test_cases(test_rays rays offset step)
