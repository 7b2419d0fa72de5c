# The environment split into area lights (host/src/dynamic/area_lights.c):
# energy, cover, the sun, irradiance, rotation and bad input. Plain C on
# the host, so no twin case.
hl_test_exe(test_area_lights ${CMAKE_CURRENT_LIST_DIR}/test_area_lights.c)
hl_test_cases(test_area_lights area_lights energy energy_shared cover sun irradiance rotation bad_input)
