# Environments, images and tone mapping (tests/test_env.c).
# zlib (a dependency of libopenexr-dev already) deflates the ZIP chunks
# that hl.env.hostile_chunks writes byte by byte.
find_package(ZLIB REQUIRED)
hl_test_exe(test_env test_env.c)
target_link_libraries(test_env PRIVATE ZLIB::ZLIB)
hl_test_cases(test_env env convention solid_angle load_shared bad_files nan_repair sky image_io tonemap float_files hostile_headers hostile_chunks)
