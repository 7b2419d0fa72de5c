/* test_truncate.c - the truncation stage (kernels/precompute/truncate.cl)
 * against its plain-C twin (host/src/precompute/twins/truncate.c), suite
 * "truncate".
 *
 * truncate.twin  every rule (all, top-K, energy) over rows of real
 *                visibility plus synthetic ones: thresholds, ties and
 *                counts equal exactly; the counts the rules fix.
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL),
 * tests/common/stage_fixture.h.
 */
#include <stdint.h>

#include "cl_backend.h"
#include "geom.h"
#include "hl_test.h"
#include "precompute.h"
#include "rays.h"
#include "twins.h"
#include "stage_fixture.h"


static const hl_trunc_params trunc_cases[] = {
    {HL_TRUNC_ALL, 0, 0, 0},         {HL_TRUNC_TOPK, 1, 0, 0},         {HL_TRUNC_TOPK, 100, 0, 0},
    {HL_TRUNC_TOPK, 8192, 0, 0},     {HL_TRUNC_TOPK, 100000, 0, 0},    {HL_TRUNC_TOPK, 0, 0, 0},
    {HL_TRUNC_ENERGY, 0, 10486, 0},  {HL_TRUNC_ENERGY, 0, 105, 0},     {HL_TRUNC_ENERGY, 50, 105, 0},
    {HL_TRUNC_ENERGY, 0, 0, 0},      {HL_TRUNC_ENERGY, 0, 1048575, 0},
};

static void case_truncate(void)
{
    fixture f;
    if (!setup(&f, 64, 64, 128)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
    uint32_t rows;
    float *coef = make_coef(&f, &rows);
    hl_trunc_result *a = malloc(rows * sizeof *a), *b = malloc(rows * sizeof *b);
    hl_ref_key *keys = malloc((size_t)f.g->ncoef * sizeof *keys);
    for (size_t c = 0; c < sizeof trunc_cases / sizeof *trunc_cases; c++) {
        hl_trunc_params p = trunc_cases[c];
        if (c == 0) hl_cl_pipe_truncate(f.pipe, rows, coef, p, b); /* warm-up: PoCL compiles lazily */
        double t0 = hl_now();
        HL_CHECK(hl_cl_pipe_truncate(f.pipe, rows, coef, p, b) == HL_OK, "%s", hl_context_last_error(f.cl));
        double t1 = hl_now();
        uint32_t mism = 0;
        uint64_t kept = 0;
        for (uint32_t i = 0; i < rows; i++) {
            a[i] = hl_ref_truncate(f.g, coef + (size_t)i * f.g->ncoef, p, keys);
            kept += a[i].count;
            if (a[i].thresh != b[i].thresh || a[i].ties != b[i].ties || a[i].count != b[i].count) {
                if (mism++ < 3)
                    fprintf(stderr, "row %u: C (%x %u %u) vs OpenCL (%x %u %u)\n", i, a[i].thresh, a[i].ties, a[i].count,
                            b[i].thresh, b[i].ties, b[i].count);
            }
        }
        printf("rule %u K %u eps_q20 %u: %.1f kept per row, %.2f ms OpenCL, %u of %u rows differ\n", p.rule, p.K,
               p.eps_q20, (double)kept / rows, 1e3 * (t1 - t0), mism, rows);
        HL_CHECK(mism == 0, "integer outputs must match exactly");
        /* rules that fix the count exactly */
        if (p.rule == HL_TRUNC_TOPK) HL_CHECK(a[3].count == (p.K < 8192 ? p.K : a[3].count), "top-K count");
        HL_CHECK(a[0].count == 0 && a[2].count == (p.rule == HL_TRUNC_TOPK && p.K == 0 ? 0u : 1u), "synthetic rows");
    }
    free(a); free(b); free(coef); free(keys);
    teardown(&f);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"twin", case_truncate},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
