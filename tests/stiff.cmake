# Numerical stability under stiff and extreme input (tests/test_stiff.c):
# suns up to 1e7 x the sky, black, one-pixel, negative and subnormal maps,
# map sizes 2x1 to 8192x4096, N and C from 8 to 256, K = 0, 1 and all,
# all-zero transport, meshes at 1e-6 and 1e6 and far from the origin,
# degenerate triangles and normals, long float accumulations. Both
# backends (needs an OpenCL device: PoCL).
hl_test_exe(test_stiff test_stiff.c)
hl_test_cases(test_stiff stiff
  sun_sky black single_pixel negative denormal env_sizes resolution
  truncation zero_transport scale shape accumulation)
