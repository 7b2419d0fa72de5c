/* bench_capture.c - `haarlight bench --surroundings`: the speed of
 * lighting captured from surroundings. With the relighter lit by them over
 * the first environment: lighting changes per second at M = 200 where
 * every change is a new capture (every body turned a further half degree
 * about +Y), the cost of a run in which nothing changed, and rounds of the
 * capture alone against the dot products alone, each pair a moment apart.
 *
 * Depends on: the public API and haarlight_tools.h (the device probes),
 * cli.h (bench_speed, bench_median).
 */
#include <math.h>
#include <stdlib.h>

#include "cli.h"
#include "haarlight_tools.h"

/* Each timed change turns the surroundings by this much more (degrees):
 * enough that every triangle's corners change in float. */
#define CAPTURE_TURN_DEG 0.5
/* Launches a round's capture and dot-product means are taken over. */
#define CAPTURE_ROUND_REPS 20

/* Every body turned by deg about +Y through the origin. */
static hl_result turn_all(hl_surroundings *sur, double deg)
{
    const double a = deg * 3.14159265358979323846 / 180.0;
    const float c = (float)cos(a), s = (float)sin(a);
    const float xf[12] = {c, 0, s, 0, 0, 1, 0, 0, -s, 0, c, 0};
    hl_result r = HL_OK;
    for (uint32_t b = 0; b < hl_surroundings_body_count(sur) && r == HL_OK; b++)
        r = hl_surroundings_set_transform(sur, b, xf);
    return r;
}

hl_result bench_capture(hl_relighter *rc, hl_surroundings *sur, uint32_t probes, uint32_t reps, float *B,
                        bench_speed *sp)
{
    double *t = malloc((size_t)(reps + 1) * sizeof *t);
    if (!t) return HL_ERR_OUT_OF_MEMORY;
    hl_relight_desc d = {.terms = 200, .select = HL_SELECT_DEFAULT};
    hl_relight_stats st;
    hl_result r = hl_relighter_set_surroundings(rc, sur);
    if (r == HL_OK) r = hl_relighter_set_probes(rc, probes ? probes : 1, 0.0);
    if (r == HL_OK) r = turn_all(sur, 0.0);
    if (r == HL_OK) r = hl_relighter_run(rc, &d, B, &st); /* first capture: the kernel's build */
    for (uint32_t k = 0; k < reps && r == HL_OK; k++) {
        r = turn_all(sur, CAPTURE_TURN_DEG * (k + 1));
        if (r == HL_OK) r = hl_relighter_run(rc, &d, B, &st);
        if (r == HL_OK && st.reused) r = HL_ERR_INVALID_ARGUMENT; /* a turn must be a new capture */
        t[k] = st.seconds;
    }
    if (r == HL_OK) sp->cap_rate = 1.0 / bench_median(t, (int)reps);
    if (r == HL_OK) sp->cap_probes = st.probes;
    /* nothing changed: the last colours again */
    for (uint32_t k = 0; k < reps && r == HL_OK; k++) {
        r = hl_relighter_run(rc, &d, B, &st);
        t[k] = st.seconds;
    }
    if (r == HL_OK) sp->cap_same = bench_median(t, (int)reps);
    double cap[BENCH_ROUNDS], dot[BENCH_ROUNDS], ratio[BENCH_ROUNDS];
    for (int k = 0; k < BENCH_ROUNDS && r == HL_OK; k++) {
        r = hl_bench_time_capture(rc, CAPTURE_ROUND_REPS, &cap[k]);
        if (r == HL_OK) r = hl_bench_time_dots(rc, CAPTURE_ROUND_REPS, &dot[k]);
        ratio[k] = r == HL_OK && dot[k] > 0 ? cap[k] / dot[k] : 0.0;
    }
    if (r == HL_OK) {
        sp->cap_ms = 1e3 * bench_median(cap, BENCH_ROUNDS);
        sp->cap_dot_ms = 1e3 * bench_median(dot, BENCH_ROUNDS);
        sp->cap_ratio = bench_median(ratio, BENCH_ROUNDS);
        sp->cap_triangles = hl_surroundings_triangle_count(sur);
    }
    free(t);
    hl_result r2 = turn_all(sur, 0.0);
    hl_result r3 = hl_relighter_set_surroundings(rc, NULL);
    if (r3 == HL_OK) r3 = hl_relighter_set_probes(rc, 1, 0.0);
    return r != HL_OK ? r : r2 != HL_OK ? r2 : r3;
}
