# The surroundings the capture renders (host/src/capture/surroundings*.c
# on the dynamic scene's loader): emission per triangle from emissive
# materials and glTF's emissive strength, dark occluders, node animation,
# program transforms, and bad input.
hl_test_exe(test_surroundings ${CMAKE_CURRENT_LIST_DIR}/test_surroundings.c)
hl_test_cases(test_surroundings surroundings emissive dark animation transform bad example)
