# Rendering (Embree primary rays, camera, background) and PLY output
# (tests/test_render.c).
hl_test_exe(test_render test_render.c)
hl_test_cases(test_render render
  constant_colour barycentric background explicit_camera bad_args ply_roundtrip ply_atomic)
