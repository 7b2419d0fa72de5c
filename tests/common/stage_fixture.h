/* stage_fixture.h - the fixture of the precompute stages' twin tests
 * (tests/maps, tests/precompute): an OpenCL and a reference context,
 * data/bunny_lowres.obj with a ground, rows of real Embree visibility
 * spread over it, the stages' pipe, the reference T and coefficients of
 * all rows (plus synthetic all-zero, all-equal and one-value rows), and a
 * relative difference.
 * Depends on: hl_test.h, cl_backend.h, geom.h, rays.h, twins.h, HL_REPO_DATA.
 */
#ifndef HL_TEST_STAGE_FIXTURE_H
#define HL_TEST_STAGE_FIXTURE_H

typedef struct fixture {
    hl_context *cl, *ref;
    hl_mesh *mesh;
    hl_geom *g;
    hl_cl_pipe *pipe;
    uint32_t rows;
    uint8_t *vis;
    float *n4;
} fixture;

static inline hl_mesh *make_mesh(hl_context *ctx)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    hl_mesh *m = NULL;
    if (hl_mesh_load(ctx, path, NULL, &m, NULL) != HL_OK) {
        fprintf(stderr, "%s\n", hl_context_last_error(ctx));
        return NULL;
    }
    hl_ground_desc gd = {.resolution = 24};
    if (hl_mesh_add_ground(ctx, m, &gd) != HL_OK) {
        hl_mesh_destroy(m);
        return NULL;
    }
    return m;
}

/* rows vertices spread over the mesh, object and ground alike */
static inline int setup(fixture *f, uint32_t N, uint32_t C, uint32_t rows)
{
    memset(f, 0, sizeof *f);
    char err[4096];
    hl_context_desc dc = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1}, dr = {.backend = HL_BACKEND_REFERENCE};
    if (hl_context_create(&dc, &f->cl, err, sizeof err) != HL_OK) {
        fprintf(stderr, "OpenCL context: %s\n", err);
        return 0;
    }
    if (hl_context_create(&dr, &f->ref, err, sizeof err) != HL_OK) return 0;
    f->mesh = make_mesh(f->ref);
    if (!f->mesh) return 0;
    if (hl_geom_create(f->ref, N, C, &f->g) != HL_OK) return 0;
    if (hl_cl_pipe_create(f->cl, f->g, rows, &f->pipe) != HL_OK) {
        fprintf(stderr, "%s\n", hl_context_last_error(f->cl));
        return 0;
    }
    f->rows = rows;
    f->vis = malloc((size_t)rows * f->g->ncube);
    f->n4 = malloc((size_t)rows * 16);
    hl_rt *rt = NULL;
    if (hl_rt_create(f->ref, f->mesh, &rt) != HL_OK) return 0;
    float off = 1e-3f * hl_mesh_query_diagonal(f->mesh);
    for (uint32_t i = 0; i < rows; i++) {
        uint32_t v = (uint32_t)((uint64_t)i * f->mesh->vertex_count / rows);
        hl_rt_visibility(rt, f->g, f->mesh, v, 1, 1, off, f->vis + (size_t)i * f->g->ncube, NULL);
        memcpy(f->n4 + 4 * i, f->mesh->normals + 3 * (size_t)v, 12);
        f->n4[4 * i + 3] = 0.0f;
    }
    hl_rt_destroy(rt);
    return 1;
}

static inline void teardown(fixture *f)
{
    hl_cl_pipe_destroy(f->pipe);
    hl_geom_destroy(f->g);
    hl_mesh_destroy(f->mesh);
    hl_context_destroy(f->cl);
    hl_context_destroy(f->ref);
    free(f->vis);
    free(f->n4);
}

static const float VIS_SCALE = (float)(1.0 / 3.14159265358979323846);

/* Reference T and coefficients for all rows. */
static inline void ref_T(const fixture *f, float *T)
{
    for (uint32_t i = 0; i < f->rows; i++)
        hl_ref_cube2para(f->g, f->vis + (size_t)i * f->g->ncube, VIS_SCALE, f->n4 + 4 * i, T + (size_t)i * f->g->ncoef);
}

/* Coefficients of all rows plus synthetic rows: all zero, all equal
 * (every key tied), and one non-zero. */
static inline float *make_coef(fixture *f, uint32_t *rows_out)
{
    uint32_t rows = f->rows;
    size_t nc = f->g->ncoef;
    float *T = malloc((size_t)rows * nc * 4), *coef = malloc((size_t)rows * nc * 4);
    ref_T(f, T);
    for (uint32_t i = 0; i < rows; i++) hl_ref_haar(f->g, T + i * nc, coef + i * nc);
    memset(coef, 0, nc * 4);
    for (size_t j = 0; j < nc; j++) coef[nc + j] = (j & 1) ? -0.25f : 0.25f;
    memset(coef + 2 * nc, 0, nc * 4);
    coef[2 * nc + 77] = -3.0f;
    free(T);
    *rows_out = rows;
    return coef;
}

#endif
