# make_terrain: a displaced terrain of any size for the scale measurements
# (docs/SCALE.md); a small one is precomputed and relit here, so that the
# generator and the path it feeds stay working.
add_executable(make_terrain ${CMAKE_CURRENT_LIST_DIR}/make_terrain.c)
target_link_libraries(make_terrain PRIVATE m)
add_test(NAME hl.terrain.small
         COMMAND sh -c "set -e; d=\"$3\"; mkdir -p \"$d\"; \"$1\" \"$d/t.ply\" 64; \"$2\" precompute \"$d/t.ply\" -C 16 -N 16 -q -o \"$d/t.hlt\"; \"$2\" info \"$d/t.hlt\" | grep -q 'vertices *4096 '; \"$2\" relight \"$d/t.hlt\" --sky -q -o \"$d/t.ply.out.ply\"; rm -rf \"$d\"; echo passed" sh
                 $<TARGET_FILE:make_terrain> $<TARGET_FILE:haarlight> ${CMAKE_CURRENT_BINARY_DIR}/tmp/terrain_small)
set_tests_properties(hl.terrain.small PROPERTIES TIMEOUT 120)
