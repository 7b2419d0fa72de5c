# Real spherical harmonics and their integrals over the paraboloid
# texels (host/src/sh): values, addition theorem, orthonormality on the
# sphere and over the texel footprints, convergence in the quadrature,
# constant map, turns about +Y, bad arguments.
hl_test_exe(test_sh ${CMAKE_CURRENT_LIST_DIR}/test_sh.c)
hl_test_cases(test_sh sh values addition orthonormal footprint convergence constant rotation bad)
