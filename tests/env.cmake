# Environments, images and tone mapping (tests/test_env.c).
hl_test_exe(test_env test_env.c)
hl_test_cases(test_env env convention solid_angle load_shared bad_files nan_repair sky image_io tonemap float_files hostile_headers hostile_chunks)
