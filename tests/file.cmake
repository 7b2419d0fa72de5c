# Transport file writer and reader (tests/test_file.c).
hl_test_exe(test_file test_file.c)
hl_test_cases(test_file file roundtrip atomic truncated corrupt badappend)
