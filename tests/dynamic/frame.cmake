# One frame of the dynamic method (host/src/dynamic/dyn_frame.c): the
# unshadowed sum against the map's irradiance, the shadow following a
# moved body, OpenCL against the reference backend, bad input, the
# public hl_dynamic API (a mesh and a glTF file of bodies) and
# `haarlight relight-dynamic`.
hl_test_exe(test_dyn_frame ${CMAKE_CURRENT_LIST_DIR}/test_dyn_frame.c)
hl_test_cases(test_dyn_frame dyn_frame unshadowed motion below twin device bad_input api cli file keep sharp contact enclosed sharp_rays)
hl_test_cases_gpu_shape(test_dyn_frame dyn_frame unshadowed twin device keep sharp sharp_rays)
