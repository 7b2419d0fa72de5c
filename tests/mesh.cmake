# Mesh module: loading (native OBJ and assimp), welding, clean-up,
# orientation, normals, ground plane and bad input.
hl_test_exe(test_mesh test_mesh.c)
hl_test_cases(test_mesh mesh
  bunny teapot horse_up_z horse_keep_winding normals ground ply create
  obj_features obj_vs_ply
  bad_nan bad_index bad_no_faces bad_not_mesh bad_counts bad_missing bad_empty bad_args)
