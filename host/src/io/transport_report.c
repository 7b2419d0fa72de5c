/* transport_report.c - the human report of a loaded transport for
 * `haarlight info` (hl_transport_describe): parameters, counts, per-vertex
 * statistics, ray counters and sizes.
 *
 * Depends on: transport_file.h (its declaration), transport_layout.h
 * (slot_total), POSIX stat.
 */
#include <inttypes.h>
#include <stdio.h>
#include <sys/stat.h>

#include "transport_file.h"
#include "transport_layout.h"

static const char *rule_name(uint32_t rule)
{
    switch (rule) {
    case HL_TRUNC_ALL: return "all non-zeros";
    case HL_TRUNC_TOPK: return "top-K";
    case HL_TRUNC_ENERGY: return "energy";
    default: return "unknown";
    }
}

static const char *quant_name(uint32_t quant)
{
    switch (quant) {
    case HL_QUANT_LINEAR8: return "linear8 (8-bit linear between the row's min and max)";
    case HL_QUANT_LOG8: return "log8 (sign + 7-bit log magnitude)";
    case HL_QUANT_SQRT8: return "sqrt8 (sign + 7-bit square-root magnitude)";
    default: return "unknown";
    }
}

void hl_transport_describe(const hl_transport *t, const char *path, FILE *f)
{
    if (!t || !f) return;
    const hl_transport_info *i = &t->info;
    uint32_t V = i->vertex_count, B = i->block_count;
    uint64_t min_nnz = UINT64_MAX, max_nnz = 0, nonempty = 0;
    const uint32_t R = hl_transport_rows(i);
    for (uint32_t v = 0; v < R; v++) {
        uint64_t n = t->row_offset[v + 1] - t->row_offset[v];
        if (n < min_nnz) min_nnz = n;
        if (n > max_nnz) max_nnz = n;
        for (uint32_t b = 0; b < B; b++) nonempty += t->block_counts[(size_t)v * B + b] != 0;
    }
    if (V == 0) min_nnz = 0;
    double dv = V ? (double)V : 1.0, dr = R ? (double)R : 1.0;
    /* with a row a channel the row statistics are per row */
    const char *per = i->channels == 3 ? "row" : "vertex";
    uint64_t entry_bytes = 2 * i->coefficients_kept;
    uint64_t directions = i->rays_cast + i->rays_culled;

    if (path) {
        struct stat st;
        if (stat(path, &st) == 0)
            fprintf(f, "file               %s (%" PRIu64 " bytes)\n", path, (uint64_t)st.st_size);
        else
            fprintf(f, "file               %s\n", path);
    }
    fprintf(f, "format version     %u\n", i->version);
    fprintf(f, "paraboloid N       %u (2 x %u^2 = %u coefficient slots)\n", i->N, i->N, slot_total(i->N));
    if (i->basis == HL_TRANSPORT_BASIS_SH)
        fprintf(f, "basis              spherical harmonics, order %u (%u coefficients in slots 0..%u)\n", i->sh_order,
                i->sh_order * i->sh_order, i->sh_order * i->sh_order - 1);
    else if (i->basis == HL_TRANSPORT_BASIS_CUBE)
        fprintf(f, "basis              cube-face Haar wavelets, faces of side %u (%u coefficients in slots 0..%u)\n",
                i->sh_order, 6 * i->sh_order * i->sh_order, 6 * i->sh_order * i->sh_order - 1);
    else
        fprintf(f, "basis              paraboloid Haar wavelets\n");
    fprintf(f, "cubemap C          %u, supersample %u x %u\n", i->C, i->supersample, i->supersample);
    if (i->bounces)
        fprintf(f, "light              direct and %u bounce%s of diffuse interreflection, baked with the mesh's albedo "
                   "%s\n", i->bounces, i->bounces == 1 ? "" : "s",
                i->channels == 3 ? "(a row a colour channel: coloured bounces)" : "(grey: one row a vertex)");
    else
        fprintf(f, "light              direct only\n");
    fprintf(f, "truncation         %s", rule_name(i->rule));
    if (i->rule == HL_TRUNC_TOPK || i->rule == HL_TRUNC_ENERGY) {
        if (i->K)
            fprintf(f, ", K %u", i->K);
        else
            fprintf(f, ", K none");
    }
    if (i->rule == HL_TRUNC_ENERGY) fprintf(f, ", eps %g", (double)i->eps);
    fprintf(f, "\n");
    fprintf(f, "quantisation       %s\n", quant_name(i->quant));
    if (i->ray_offset > 0.0f) fprintf(f, "ray offset         %g x bounding-box diagonal\n", (double)i->ray_offset);
    else fprintf(f, "ray offset         robust (2^-16 of the vertex's largest coordinate or longest edge)\n");
    fprintf(f, "vertices           %u (object %u, ground %u)\n", V, i->object_vertex_count,
            V - i->object_vertex_count);
    fprintf(f, "triangles          %u\n", i->triangle_count);
    if (i->channels == 3) fprintf(f, "rows               %u: a red, a green and a blue row a vertex\n", R);
    fprintf(f, "blocks per %-6s  %u of %u slots\n", per, B, HL_BLOCK);
    fprintf(f, "coefficients kept  %" PRIu64 " (per %s: mean %.1f, min %" PRIu64 ", max %" PRIu64 ")\n",
            i->coefficients_kept, per, (double)i->coefficients_kept / dr, min_nnz, max_nnz);
    fprintf(f, "non-empty blocks   %.2f per %s (of %u)\n", (double)nonempty / dr, per, B);
    fprintf(f, "rays cast          %" PRIu64 " (%.0f per vertex)\n", i->rays_cast, (double)i->rays_cast / dv);
    fprintf(f, "rays culled        %" PRIu64 " (%.1f%% of all directions)\n", i->rays_culled,
            directions ? 100.0 * (double)i->rays_culled / (double)directions : 0.0);
    fprintf(f, "entry section      %" PRIu64 " bytes (%.1f per vertex)\n", entry_bytes, (double)entry_bytes / dv);
}
