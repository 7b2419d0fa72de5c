# `haarlight bench-dynamic` end to end, tiny (a 16^2-cube transport of the
# bunny on a coarse ground, the sky, one dynamic setting, two traced S):
# the files are written, the rows are there, every error is finite and
# in [0, 1), and bad options exit 2 (test_bench_dynamic.sh).
foreach(c run bad_options)
  add_test(NAME hl.bench_dynamic.${c} COMMAND bash ${CMAKE_CURRENT_LIST_DIR}/test_bench_dynamic.sh ${c})
  set_tests_properties(hl.bench_dynamic.${c} PROPERTIES
    ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data"
    TIMEOUT 600)
endforeach()
