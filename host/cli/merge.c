/* merge.c - `haarlight merge`: the shard files of a precompute spread over
 * machines (precompute --shard I/N) joined into one transport file,
 * through hl_transport_merge (host/src/precompute/merge.c). Usage errors
 * exit 2, refused shards and other failures 1, naming the file.
 *
 * Depends on: cli.h (usage_error, cli_fail, cli_watch), haarlight.h,
 * haarlight_tools.h (hl_transport_merge).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "haarlight.h"
#include "haarlight_tools.h"

/* Declared here and in main.c, the command table (cli.h belongs to the
 * commands' shared helpers). */
int cmd_merge(int argc, char **argv);

static const char *const usage_merge =
    "usage: haarlight merge -o SCENE.hlt SHARD... [options]\n"
    "\n"
    "Joins the shard files of a precompute spread over machines (one run of\n"
    "`haarlight precompute MESH --shard I/N -o SHARD` for each I from 0 to N-1, with\n"
    "the same mesh and options) into SCENE.hlt: byte for byte the file one run\n"
    "without --shard writes. The shards may come in any order and are left as\n"
    "they are; SCENE.hlt is written atomically (SCENE.hlt.partial, renamed when\n"
    "complete). It streams: a few MiB of memory whatever the size of the shards.\n"
    "Where every shard has its direct rows' floats (SHARD.values, precompute\n"
    "--keep-floats) they are joined into SCENE.hlt.values, for a later precompute\n"
    "--bounces B --direct-rows SCENE.hlt; where only some have, a warning and none.\n"
    "\n"
    "Refused, naming the file (exit 1): a file that is not a shard (a whole\n"
    "transport file, an unfinished .partial, anything else); shards of different\n"
    "meshes, options or shard counts; a missing or repeated shard; a truncated or\n"
    "corrupt shard (every checksum and row is checked); an output that is one of\n"
    "the shards.\n"
    "\n"
    "options:\n"
    "  -o, --output SCENE.hlt  the transport file to write (required)\n"
    "  -q, --quiet             no summary on stderr\n";

int cmd_merge(int argc, char **argv)
{
    const char *out = NULL;
    int quiet = 0;
    const char **shards = calloc((size_t)argc + 1, sizeof *shards);
    if (!shards) {
        fprintf(stderr, "haarlight: merge: out of memory\n");
        return 1;
    }
    uint32_t n = 0;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            fputs(usage_merge, stdout);
            free(shards);
            return 0;
        } else if (!strcmp(a, "-o") || !strcmp(a, "--output")) {
            if (i + 1 >= argc) {
                free(shards);
                return usage_error(usage_merge, "option %s needs a value", a);
            }
            out = argv[++i];
        } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) quiet = 1;
        else if (a[0] == '-' && a[1]) {
            free(shards);
            return usage_error(usage_merge, "unknown option %s", a);
        } else shards[n++] = a;
    }
    if (!out) {
        free(shards);
        return usage_error(usage_merge, "%s", "no output given (-o SCENE.hlt)");
    }
    if (n == 0) {
        free(shards);
        return usage_error(usage_merge, "%s", "no SHARD files given");
    }
    /* No device: merging is file work. */
    hl_context_desc cd = {.backend = HL_BACKEND_REFERENCE, .quiet = quiet};
    hl_context *ctx = cli_context(&cd);
    if (!ctx) {
        free(shards);
        return 1;
    }
    hl_merge_stats st;
    hl_result r = hl_transport_merge(ctx, out, shards, n, &st);
    int rc = 0;
    if (r != HL_OK) rc = cli_fail(ctx, r);
    else if (!quiet)
        fprintf(stderr, "wrote %s: %u shards, %u vertices, %.1f coefficients kept per vertex; %.1f MB read, %.1f MB "
                        "written in %.2f s\n",
                out, st.shards, st.vertices, (double)st.coefficients_kept / st.vertices, (double)st.bytes_read * 1e-6,
                (double)st.bytes_written * 1e-6, st.seconds);
    if (r == HL_OK && !quiet && st.values) fprintf(stderr, "wrote %s.values: the shards' direct rows' floats\n", out);
    cli_unwatch();
    hl_context_destroy(ctx);
    free(shards);
    return rc;
}
