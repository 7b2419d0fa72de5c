# Numerical stability under stiff and extreme input: suns up to 1e7 x the
# sky, black, one-pixel, negative and subnormal maps, map sizes 2x1 to
# 8192x4096 (stiff_light); N and C from 8 to 256, K = 0, 1 and all,
# all-zero transport, long float accumulations (stiff_transport); meshes at
# 1e-6 and 1e6 and far from the origin, degenerate triangles and normals
# (stiff_mesh). Both backends (needs an OpenCL device: PoCL).
hl_test_exe(test_stiff_light ${CMAKE_CURRENT_LIST_DIR}/test_stiff_light.c)
hl_test_cases(test_stiff_light stiff_light sun_sky black single_pixel negative denormal env_sizes)
hl_test_exe(test_stiff_transport ${CMAKE_CURRENT_LIST_DIR}/test_stiff_transport.c)
hl_test_cases(test_stiff_transport stiff_transport resolution truncation zero_transport accumulation)
hl_test_exe(test_stiff_mesh ${CMAKE_CURRENT_LIST_DIR}/test_stiff_mesh.c)
hl_test_cases(test_stiff_mesh stiff_mesh scale shape)
