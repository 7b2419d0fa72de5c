# Real spherical harmonics and their integrals over the paraboloid
# texels (host/src/sh): values, addition theorem, orthonormality on the
# sphere and over the texel footprints, convergence in the quadrature,
# constant map, turns about +Y, bad arguments.
hl_test_exe(test_sh ${CMAKE_CURRENT_LIST_DIR}/test_sh.c)
hl_test_cases(test_sh sh values addition orthonormal footprint convergence constant rotation bad tool)
# `haarlight bench-basis` end to end, tiny, and its bad options
# (test_bench_basis.sh).
foreach(c basis cube_side bad_options)
  add_test(NAME hl.bench_basis.${c} COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/test_bench_basis.sh ${c})
  set_tests_properties(hl.bench_basis.${c} PROPERTIES
    ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data"
    TIMEOUT 600)
endforeach()
# Haar wavelets over the six cube faces (host/src/cube) and bench-basis's
# cube bases: the transform's inverse and Parseval, the environment taps,
# the own-footprint rows, a constant map, half-space lights, bad cube sides
# (test_cube.c).
hl_test_exe(test_cube ${CMAKE_CURRENT_LIST_DIR}/test_cube.c)
hl_test_cases(test_cube cube transform taps rows constant halfspace bad)
# Spherical harmonics through the real pipeline (precompute --basis sh, the
# relighter's lighting projected alike): the projection kernel against its
# twin and the double projection, a constant map, OpenCL against the
# reference, relight against bench-basis's SH colours, bad options
# (test_sh_pipeline.c).
hl_test_exe(test_sh_pipeline ${CMAKE_CURRENT_LIST_DIR}/test_sh_pipeline.c)
hl_test_cases(test_sh_pipeline sh_pipeline kernel constant cl_ref bench bad)
hl_test_cases_gpu_shape(test_sh_pipeline sh_pipeline cl_ref)
