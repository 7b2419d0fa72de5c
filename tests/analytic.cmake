# The maths of docs/CONVENTIONS.md against closed forms (tests/test_analytic.c):
# the Haar transform, the direction maps and their tables, and two scenes with
# known answers (white furnace, occluding spherical cap). Reference backend
# only, so no OpenCL device is needed.
hl_test_exe(test_analytic test_analytic.c)
hl_test_cases(test_analytic haar roundtrip parseval slots)
hl_test_cases(test_analytic geom solid_angle mapping table)
hl_test_cases(test_analytic analytic furnace cap ray_offset)
