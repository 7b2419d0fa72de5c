# The viewer (`haarlight view`): real windows under Xvfb, captures compared
# with `haarlight relight`'s pictures (tests/test_viewer.sh, the comparison
# in tests/test_viewer.c) and `haarlight relight-dynamic`'s, an animated
# scene written by tests/viewer/viewer_scene.c, lighting captured from
# data/surroundings/lamp_orbit.gltf, and bad input. Cases that need a window skip
# (exit 77) where the viewer is not built or no X server can start.
hl_test_exe(test_viewer test_viewer.c)
hl_test_exe(viewer_scene viewer/viewer_scene.c)
foreach(c capture_sky capture_bounced capture_env drop bad_input dynamic_rest dynamic_moved dynamic_moments dynamic_drag dynamic_anim dynamic_bad
          surroundings_capture surroundings_drag surroundings_unchanged surroundings_bad textured)
  add_test(NAME hl.viewer.${c} COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_viewer.sh ${c})
  set_tests_properties(hl.viewer.${c} PROPERTIES
    ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_COMPARE=$<TARGET_FILE:test_viewer>;HL_SCENE_GEN=$<TARGET_FILE:viewer_scene>;HL_TMP=${CMAKE_CURRENT_BINARY_DIR}/tmp;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data;HL_VIEWER_BUILT=${HL_VIEWER_BUILT}"
    SKIP_RETURN_CODE 77
    TIMEOUT 120)
endforeach()
