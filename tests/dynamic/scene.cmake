# Dynamic scenes of rigid bodies (host/src/dynamic/scene.c, scene_anim.c):
# loading glTF written by scene_gen.h, sampling its node animation against
# an independent reference, rigidity, the built-in bunny-and-ground scene
# and bad input. Plain C on the host, so no twin case.
hl_test_exe(test_scene ${CMAKE_CURRENT_LIST_DIR}/test_scene.c)
hl_test_cases(test_scene scene load anim rigid builtin bad ground posed)
