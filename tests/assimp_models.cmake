# Every model of Debian's assimp-testmodels package through `precompute`
# (-C 8 -N 8, --device ref), two at a time, each under a memory and a time
# limit: each loads or is refused with a message (test_assimp_models.sh).
# Skipped (77) without /usr/share/assimp/models. HL_SANITIZE tells the
# script to limit memory through ASan's allocator instead of ulimit -v.
if(HL_SANITIZE)
  set(HL_MODELS_SANITIZE 1)
else()
  set(HL_MODELS_SANITIZE 0)
endif()
add_test(NAME hl.assimp_models.testmodels COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_assimp_models.sh)
set_tests_properties(hl.assimp_models.testmodels PROPERTIES
  ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_SANITIZE=${HL_MODELS_SANITIZE}"
  SKIP_RETURN_CODE 77 TIMEOUT 1500)
