# The bounced exact reference of `haarlight bench` (hl_bench_ref_bounced):
# a spherical cavity against its closed form, and a wrong bounce count
# detected (test_bench_ref.c).
hl_test_exe(test_bench_ref ${CMAKE_CURRENT_LIST_DIR}/test_bench_ref.c)
hl_test_cases(test_bench_ref bench_ref cavity mismatch)
