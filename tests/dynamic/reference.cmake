# The exact reference of the dynamic method (host/src/dynamic/dyn_reference.c):
# a furnace, the unoccluded sums against the frame's, and a shadow under a
# floating quad; the traced method (dyn_traced.c) against the K-lights
# reference. `test_dyn_reference accuracy` (minutes) is run by hand.
hl_test_exe(test_dyn_reference ${CMAKE_CURRENT_LIST_DIR}/test_dyn_reference.c)
hl_test_cases(test_dyn_reference dyn_reference furnace unoccluded occluded traced)
