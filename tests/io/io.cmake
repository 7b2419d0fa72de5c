# Input and output (host/src/io): environments (EXR and Radiance .hdr), EXR files written byte by
# byte, images and tone mapping, transport files, meshes, PLY output.
# zlib (a dependency of libopenexr-dev already) deflates the ZIP chunks
# that hl.exr_chunks.hostile writes byte by byte.
find_package(ZLIB REQUIRED)
hl_test_exe(test_env ${CMAKE_CURRENT_LIST_DIR}/test_env.c)
hl_test_cases(test_env env convention solid_angle load_shared bad_files nan_repair sky float_files)
hl_test_exe(test_hdr ${CMAKE_CURRENT_LIST_DIR}/test_hdr.c)
hl_test_cases(test_hdr hdr read exposure same_as_exr bad)
hl_test_exe(test_env_layout ${CMAKE_CURRENT_LIST_DIR}/test_env_layout.c)
hl_test_cases(test_env_layout env_layout orientation energy explicit relight)
hl_test_exe(test_exr_headers ${CMAKE_CURRENT_LIST_DIR}/test_exr_headers.c)
hl_test_cases(test_exr_headers exr_headers hostile)
hl_test_exe(test_exr_chunks ${CMAKE_CURRENT_LIST_DIR}/test_exr_chunks.c)
target_link_libraries(test_exr_chunks PRIVATE ZLIB::ZLIB)
hl_test_cases(test_exr_chunks exr_chunks hostile)
hl_test_exe(test_image ${CMAKE_CURRENT_LIST_DIR}/test_image.c)
hl_test_cases(test_image image io tonemap)
hl_test_exe(test_transport_file ${CMAKE_CURRENT_LIST_DIR}/test_transport_file.c)
hl_test_cases(test_transport_file transport_file roundtrip atomic truncated)
hl_test_exe(test_transport_hostile ${CMAKE_CURRENT_LIST_DIR}/test_transport_hostile.c)
hl_test_cases(test_transport_hostile transport_hostile corrupt badappend basis cube_basis pieces)
# Mesh module: loading (native OBJ and assimp), welding, clean-up,
# orientation, normals, ground plane and bad input; mesh_shared reads the
# optional shared meshes and skips without them.
hl_test_exe(test_mesh ${CMAKE_CURRENT_LIST_DIR}/test_mesh.c)
hl_test_cases(test_mesh mesh ground ply create obj_features obj_vs_ply teapot_lowres)
hl_test_exe(test_mesh_shared ${CMAKE_CURRENT_LIST_DIR}/test_mesh_shared.c)
hl_test_cases(test_mesh_shared mesh_shared bunny teapot horse_up_z horse_keep_winding normals ground)
hl_test_exe(test_mesh_bad ${CMAKE_CURRENT_LIST_DIR}/test_mesh_bad.c)
hl_test_cases(test_mesh_bad mesh_bad
  nan index no_faces not_mesh counts missing empty args no_placed_mesh placed_overflow import_memory)
hl_test_exe(test_gltf_out ${CMAKE_CURRENT_LIST_DIR}/test_gltf_out.c)
hl_test_cases(test_gltf_out gltf_out roundtrip bad blender)
hl_test_exe(test_ply_out ${CMAKE_CURRENT_LIST_DIR}/test_ply_out.c)
hl_test_cases(test_ply_out ply_out roundtrip atomic)
# Albedo from a file's materials (host/src/io/material.c): base-colour
# factors, vertex colours, textures averaged per vertex, the dynamic
# scenes, and bad textures and factors.
hl_test_exe(test_material ${CMAKE_CURRENT_LIST_DIR}/test_material.c)
hl_test_cases(test_material material factor colors texture render glb dynamic dynamic_surface bad)
