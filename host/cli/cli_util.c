/* cli_util.c - option parsing and messages shared by the subcommands. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "haarlight_tools.h"

int usage_error(const char *usage, const char *fmt, const char *arg)
{
    fprintf(stderr, "haarlight: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\n\n%s", usage);
    return 2;
}

int parse_u32(const char *s, uint32_t *out)
{
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (errno || end == s || *end || v < 0 || v > 0xffffffffLL) return 0;
    *out = (uint32_t)v;
    return 1;
}

int parse_sharp(const char *s, uint32_t *out)
{
    static const char *const names[] = {"rays", "maps", "off"};
    static const uint32_t modes[] = {HL_DYNAMIC_SHARP_RAYS, HL_DYNAMIC_SHARP_MAPS, HL_DYNAMIC_SHARP_OFF};
    for (int i = 0; i < 3; i++)
        if (!strcmp(s, names[i])) { *out = modes[i]; return 1; }
    return 0;
}

int parse_float(const char *s, float *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !isfinite(v)) return 0;
    *out = (float)v;
    return 1;
}

int parse_device_memory(const char *s, hl_context_desc *cd)
{
    return hl_parse_bytes(s, &cd->device_memory);
}

int parse_device(const char *s, hl_context_desc *cd)
{
    if (strcmp(s, "ref") == 0) { cd->backend = HL_BACKEND_REFERENCE; return 1; }
    if (strcmp(s, "cl") == 0) { cd->backend = HL_BACKEND_OPENCL; return 1; }
    int p, d;
    char tail;
    if (sscanf(s, "cl:%d:%d%c", &p, &d, &tail) == 2 && p >= 0 && d >= 0) {
        cd->backend = HL_BACKEND_OPENCL;
        cd->cl_platform = p;
        cd->cl_device = d;
        return 1;
    }
    return 0;
}


int parse_layout(const char *s, hl_env_layout *out)
{
    static const char *const names[] = {"auto", "equirect", "angular", "cross-h", "cross-v"};
    for (int k = 0; k < 5; k++)
        if (!strcmp(s, names[k])) {
            *out = (hl_env_layout)k;
            return 1;
        }
    return 0;
}

int parse_select(const char *s, uint32_t *out)
{
    if (!strcmp(s, "transport")) *out = HL_SELECT_TRANSPORT;
    else if (!strcmp(s, "area")) *out = HL_SELECT_AREA;
    else if (!strcmp(s, "unweighted")) *out = HL_SELECT_UNWEIGHTED;
    else return 0;
    return 1;
}

const char *select_name(uint32_t scheme)
{
    return scheme == HL_SELECT_AREA ? "area" : scheme == HL_SELECT_UNWEIGHTED ? "unweighted" : "transport";
}

int parse_vec3(const char *s, float v[3])
{
    char tail;
    return sscanf(s, "%f,%f,%f%c", &v[0], &v[1], &v[2], &tail) == 3 && isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

int cli_fail(hl_context *ctx, hl_result r)
{
    fprintf(stderr, "haarlight: %s\n", ctx ? hl_context_last_error(ctx) : hl_result_string(r));
    return r == HL_ERR_INTERRUPTED ? 130 : 1;
}

hl_result cli_env_load(hl_context *ctx, const char *path, hl_env_layout layout, hl_env **out, int quiet)
{
    hl_env_stats es = {0, 0};
    hl_result r = hl_env_load_layout(ctx, path, layout, out, &es);
    if (r == HL_OK && !quiet && (es.nonfinite_pixels || es.negative_pixels))
        fprintf(stderr, "%s: %llu pixels with NaN or Inf set to 0, %llu pixels with negative values clamped to 0\n", path,
                (unsigned long long)es.nonfinite_pixels, (unsigned long long)es.negative_pixels);
    return r;
}

hl_context *cli_context(const hl_context_desc *cd)
{
    char err[4096];
    hl_context *ctx = NULL;
    if (hl_context_create(cd, &ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        return NULL;
    }
    cli_watch(ctx, NULL);
    return ctx;
}

int cli_context_pair(const hl_context_desc *cl_desc, hl_context **cl, hl_context **ref)
{
    char err[4096];
    hl_context_desc rdsc = {.backend = HL_BACKEND_REFERENCE, .quiet = 1};
    *cl = *ref = NULL;
    if (hl_context_create(cl_desc, cl, err, sizeof err) != HL_OK || hl_context_create(&rdsc, ref, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        hl_context_destroy(*cl);
        *cl = NULL;
        return 0;
    }
    return 1;
}

const char *cli_ext_of(const char *path)
{
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    return dot && (!slash || dot > slash) ? dot : "";
}

int cli_make_dir(const char *dir)
{
    if (mkdir(dir, 0777) == 0 || errno == EEXIST) return 1;
    fprintf(stderr, "haarlight: %s: cannot create the output folder: %s\n", dir, strerror(errno));
    return 0;
}

void cli_device_memory(const char *prefix, hl_relighter *rl, const char *scene, uint32_t V, int cols)
{
    hl_relighter_memory m;
    struct stat sb;
    char how[96] = "", col[64] = "";
    if (hl_relighter_memory_use(rl, &m) != HL_OK || !m.device_bytes || stat(scene, &sb) != 0 || sb.st_size <= 0 || !V)
        return;
    if (m.parts > 1)
        snprintf(how, sizeof how, m.resident ? ", in %u parts of their own buffers (no one buffer holds them)"
                                             : ", uploaded in %u parts from host memory",
                 m.parts);
    if (cols) snprintf(col, sizeof col, "; the columns %.1f MB", (double)m.column_bytes / 1e6);
    fprintf(stderr, "%sthe device holds %.1f MB for it: %.0f bytes a vertex, %.2f times the file%s%s\n", prefix,
            (double)m.device_bytes / 1e6, (double)m.device_bytes / V, (double)m.device_bytes / (double)sb.st_size, col,
            how);
}
