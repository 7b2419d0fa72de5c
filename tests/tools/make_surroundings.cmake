# The generator of data/surroundings/lamp_orbit.gltf (make_surroundings.c
# says how to re-make it), and a check that the committed file is what it
# writes today.
add_executable(make_surroundings ${CMAKE_CURRENT_LIST_DIR}/make_surroundings.c)
target_include_directories(make_surroundings PRIVATE ${CMAKE_CURRENT_LIST_DIR}/../capture)
target_link_libraries(make_surroundings PRIVATE m)
add_test(NAME hl.surroundings.example_file
         COMMAND sh -c "$<TARGET_FILE:make_surroundings> \"$1\" && cmp \"$1\" \"$2\"" sh
                 ${CMAKE_CURRENT_BINARY_DIR}/tmp/lamp_orbit_remade.gltf ${CMAKE_SOURCE_DIR}/data/surroundings/lamp_orbit.gltf)
set_tests_properties(hl.surroundings.example_file PROPERTIES TIMEOUT 60)
