/* test_quantize.c - the 8-bit quantisation stage
 * (kernels/precompute/quantize.cl) against its plain-C twin
 * (host/src/precompute/twins/quantize.c), suite "quantize".
 *
 * quantize.twin    every scheme and three truncation rules: row parameters,
 *                  block counts and entries equal exactly.
 * quantize.dither  sqrt8's subtractive dither: within half a step, unbiased
 *                  and not following the value.
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

static void case_quantize(void)
{
    fixture f;
    if (!setup(&f, 64, 64, 128)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
    uint32_t rows;
    float *coef = make_coef(&f, &rows);
    const hl_geom *g = f.g;
    hl_trunc_result *tr = malloc(rows * sizeof *tr);
    hl_row_quant *rqa = malloc(rows * 8), *rqb = malloc(rows * 8);
    uint16_t *bca = malloc((size_t)rows * g->nblocks * 2), *bcb = malloc((size_t)rows * g->nblocks * 2);
    uint8_t *ea = calloc((size_t)rows * g->ncoef, 2), *eb = calloc((size_t)rows * g->ncoef, 2);
    uint32_t *na = malloc(rows * 4), *nb = malloc(rows * 4);
    hl_trunc_params tps[] = {{HL_TRUNC_ALL, 0, 0, 0}, {HL_TRUNC_ENERGY, 0, 105, 0}, {HL_TRUNC_TOPK, 7, 0, 0}};
    hl_ref_key *keys = malloc((size_t)g->ncoef * sizeof *keys);
    for (uint32_t scheme = HL_QUANT_LINEAR8; scheme <= HL_QUANT_MAX; scheme++)
        for (size_t c = 0; c < 3; c++) {
            for (uint32_t i = 0; i < rows; i++) tr[i] = hl_ref_truncate(g, coef + (size_t)i * g->ncoef, tps[c], keys);
            HL_CHECK(hl_cl_pipe_quantize(f.pipe, rows, 1000, coef, tr, scheme, rqb, bcb, eb, nb) == HL_OK, "%s",
                     hl_context_last_error(f.cl));
            uint32_t mism = 0;
            double qerr = 0.0, qscale = 0.0;
            for (uint32_t i = 0; i < rows; i++) {
                size_t eo = (size_t)i * g->ncoef * 2;
                na[i] = hl_ref_quantize(g, coef + (size_t)i * g->ncoef, tr[i], scheme, 1000 + i, &rqa[i],
                                        bca + (size_t)i * g->nblocks, ea + eo);
                int same = na[i] == nb[i] && na[i] == tr[i].count && rqa[i].a == rqb[i].a && rqa[i].b == rqb[i].b &&
                           !memcmp(bca + (size_t)i * g->nblocks, bcb + (size_t)i * g->nblocks, g->nblocks * 2) &&
                           !memcmp(ea + eo, eb + eo, 2 * (size_t)na[i]);
                mism += !same;
                /* quantisation error of the kept values, for the record */
                uint32_t e = 0;
                for (uint32_t b = 0; b < g->nblocks; b++)
                    for (uint32_t k = 0; k < bca[(size_t)i * g->nblocks + b]; k++, e++) {
                        uint32_t slot = b * 256 + ea[eo + 2 * e];
                        float v = coef[(size_t)i * g->ncoef + slot];
                        float d = hl_dequant(scheme, ea[eo + 2 * e + 1], rqa[i].a, rqa[i].b, hl_dither_key(1000 + i, slot));
                        qerr += ((double)v - d) * ((double)v - d);
                        qscale += (double)v * v;
                    }
            }
            printf("%s, rule %u: %u of %u rows differ; relative L2 quantisation error of kept values %.4f\n",
                   scheme == HL_QUANT_LOG8 ? "log8" : scheme == HL_QUANT_SQRT8 ? "sqrt8" : "linear8", tps[c].rule, mism, rows, qscale > 0 ? sqrt(qerr / qscale) : 0.0);
            HL_CHECK(mism == 0, "integer outputs and parameters must match exactly");
        }
    free(tr); free(rqa); free(rqb); free(bca); free(bcb); free(ea); free(eb); free(na); free(nb); free(coef); free(keys);
    teardown(&f);
}

/* sqrt8's subtractive dither on a smooth ramp of magnitudes (one per
 * vertex, as a coefficient varies over a surface): the error stays within
 * half a step in sqrt space, like plain rounding, but no longer follows
 * the value. Plain rounding's error is a sawtooth of the value itself
 * (correlation 1 with it); the dithered error must be nearly uncorrelated
 * with it, and unbiased. */
static void case_dither(void)
{
    const uint32_t n = 20000, slot = 77;
    const float b = 3.0f;
    double worst = 0.0, sum = 0.0, see = 0.0, srr = 0.0, ser = 0.0;
    for (uint32_t k = 0; k < n; k++) {
        const double s = (0.05 + 0.9 * k / (double)n); /* sqrt(|v| / b), smooth */
        const float v = (float)(b * s * s);
        const uint32_t key = hl_dither_key(k, slot), code = hl_quant_sqrt8(v, b, key);
        const double got = sqrt((double)hl_dequant_sqrt8(code, b, key) / b);
        const double err = got - sqrt((double)v / b), plain = nearbyint(127.0 * s) / 127.0 - s;
        worst = fmax(worst, fabs(err));
        sum += err;
        see += err * err;
        srr += plain * plain;
        ser += err * plain;
    }
    const double corr = ser / sqrt(see * srr), bias = sum / n;
    printf("dither: %u values: worst error %.3g of a step (tolerance 0.5 + 1e-4), bias %.3g of a step, correlation "
           "with plain rounding's error %.3f (tolerance 0.05)\n",
           n, 127.0 * worst, 127.0 * bias, corr);
    HL_CHECK(127.0 * worst <= 0.5 + 1e-4, "dithered error beyond half a step: %.4g", 127.0 * worst);
    HL_CHECK(fabs(corr) < 0.05, "the dithered error follows the value (correlation %.3f)", corr);
    HL_CHECK(fabs(127.0 * bias) < 0.02, "biased dither: %.3g of a step", 127.0 * bias);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"twin", case_quantize},
        {"dither", case_dither},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
