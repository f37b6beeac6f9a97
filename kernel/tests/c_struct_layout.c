/* Every struct of mbdk.h against the kernel's own layout of its bind(C) type (mbdk_struct_info,
 * mbdk_struct_field): the same size, the same fields in the same order, each at the offset and of
 * the size the C compiler gives it. A field renamed, reordered, retyped or added on one side only
 * fails here. */
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include "mbdk.h"

struct field { const char *name; size_t offset, size; };

#define F(s, f) { #f, offsetof(s, f), sizeof(((s *)0)->f) }

static const struct field stats[] = {
    F(mbdk_stats, steps), F(mbdk_stats, nfev), F(mbdk_stats, njev), F(mbdk_stats, nlu),
    F(mbdk_stats, newton_iterations), F(mbdk_stats, startup_steps),
    F(mbdk_stats, rejected_steps), F(mbdk_stats, newton_failures), F(mbdk_stats, order1_steps),
    F(mbdk_stats, order2_steps), F(mbdk_stats, order3_steps), F(mbdk_stats, order4_steps),
    F(mbdk_stats, order5_steps), F(mbdk_stats, nlu_sparse),
    F(mbdk_stats, cpu_time),
    F(mbdk_stats, wall_time), F(mbdk_stats, t_reached), F(mbdk_stats, alloc_bytes)};
static const struct field options[] = {
    F(mbdk_options, h), F(mbdk_options, newton_rtol), F(mbdk_options, newton_atol),
    F(mbdk_options, rtol), F(mbdk_options, atol), F(mbdk_options, dt_out),
    F(mbdk_options, h_min), F(mbdk_options, h_max), F(mbdk_options, interrupt),
    F(mbdk_options, max_steps), F(mbdk_options, method), F(mbdk_options, every),
    F(mbdk_options, newton_max_iter), F(mbdk_options, fd_jacobian), F(mbdk_options, nq),
    F(mbdk_options, startup), F(mbdk_options, max_order), F(mbdk_options, progress)};
static const struct field index3[] = {
    F(mbdk_index3_options, h), F(mbdk_index3_options, newton_rtol),
    F(mbdk_index3_options, newton_atol), F(mbdk_index3_options, alpha),
    F(mbdk_index3_options, err_rtol), F(mbdk_index3_options, err_atol),
    F(mbdk_index3_options, dt_out), F(mbdk_index3_options, h_min), F(mbdk_index3_options, h_max),
    F(mbdk_index3_options, interrupt), F(mbdk_index3_options, formulation),
    F(mbdk_index3_options, every), F(mbdk_index3_options, newton_max_iter),
    F(mbdk_index3_options, adaptive), F(mbdk_index3_options, progress),
    F(mbdk_index3_options, beta), F(mbdk_index3_options, gamma),
    F(mbdk_index3_options, alpha_m), F(mbdk_index3_options, alpha_f)};
static const struct field model[] = {
    F(mbdk_model_options, baumgarte_alpha), F(mbdk_model_options, baumgarte_beta),
    F(mbdk_model_options, penalty_alpha), F(mbdk_model_options, penalty_omega),
    F(mbdk_model_options, penalty_mu), F(mbdk_model_options, projection_tol),
    F(mbdk_model_options, formulation), F(mbdk_model_options, solver),
    F(mbdk_model_options, small_dense), F(mbdk_model_options, projection_max_iter),
    F(mbdk_model_options, watch_position), F(mbdk_model_options, watch_velocity),
    F(mbdk_model_options, watch_energy), F(mbdk_model_options, watch_every),
    F(mbdk_model_options, locate_events), F(mbdk_model_options, watch_momentum)};

static const struct field spatial[] = {
    F(mbdk_spatial_options, baumgarte_alpha), F(mbdk_spatial_options, baumgarte_beta),
    F(mbdk_spatial_options, penalty_alpha), F(mbdk_spatial_options, penalty_omega),
    F(mbdk_spatial_options, penalty_mu), F(mbdk_spatial_options, lock_guard),
    F(mbdk_spatial_options, norm_gain), F(mbdk_spatial_options, projection_tol),
    F(mbdk_spatial_options, watch_position), F(mbdk_spatial_options, watch_velocity),
    F(mbdk_spatial_options, watch_energy), F(mbdk_spatial_options, watch_momentum),
    F(mbdk_spatial_options, watch_quaternion), F(mbdk_spatial_options, formulation),
    F(mbdk_spatial_options, rotation), F(mbdk_spatial_options, norm),
    F(mbdk_spatial_options, watch_every), F(mbdk_spatial_options, locate_events),
    F(mbdk_spatial_options, coordinates)};
static const struct field report[] = {
    F(mbdk_watch_report, value), F(mbdk_watch_report, tol), F(mbdk_watch_report, t),
    F(mbdk_watch_report, t_good), F(mbdk_watch_report, absolute), F(mbdk_watch_report, scale),
    F(mbdk_watch_report, quantity), F(mbdk_watch_report, row)};

struct table { const char *name; size_t size; const struct field *f; int n; };

static const size_t type_size[] = {0, sizeof(int), sizeof(int64_t), sizeof(double), sizeof(void *)};

int main(void)
{
    const struct table tables[] = {
        {"mbdk_stats", sizeof(mbdk_stats), stats, sizeof stats / sizeof *stats},
        {"mbdk_options", sizeof(mbdk_options), options, sizeof options / sizeof *options},
        {"mbdk_index3_options", sizeof(mbdk_index3_options), index3, sizeof index3 / sizeof *index3},
        {"mbdk_model_options", sizeof(mbdk_model_options), model, sizeof model / sizeof *model},
        {"mbdk_spatial_options", sizeof(mbdk_spatial_options), spatial,
         sizeof spatial / sizeof *spatial},
        {"mbdk_watch_report", sizeof(mbdk_watch_report), report, sizeof report / sizeof *report}};
    int ntab = sizeof tables / sizeof *tables, bad = 0, checked = 0;
    char name[64];
    int nbytes, nfields, offset, type;

    for (int id = 1; mbdk_struct_info(id, name, sizeof name, &nbytes, &nfields) == MBDK_SUCCESS; id++) {
        if (id > ntab) { printf("kernel struct %s has no C table here\n", name); bad++; continue; }
        const struct table *t = &tables[id - 1];
        if (strcmp(name, t->name) != 0 || (size_t)nbytes != t->size || nfields != t->n) {
            printf("%s: kernel says %s, %d bytes, %d fields; mbdk.h %zu bytes, %d fields\n",
                   t->name, name, nbytes, nfields, t->size, t->n);
            bad++;
        }
        for (int i = 1; mbdk_struct_field(id, i, name, sizeof name, &offset, &type) == MBDK_SUCCESS; i++) {
            checked++;
            if (i > t->n) { printf("%s: kernel field %s missing in mbdk.h\n", t->name, name); bad++; continue; }
            const struct field *f = &t->f[i - 1];
            if (strcmp(name, f->name) != 0 || (size_t)offset != f->offset || type < 1 || type > 4
                || type_size[type] != f->size) {
                printf("%s field %d: kernel %s at %d (type %d); mbdk.h %s at %zu (%zu bytes)\n",
                       t->name, i, name, offset, type, f->name, f->offset, f->size);
                bad++;
            }
        }
    }
    if (checked < 40) { printf("only %d fields checked\n", checked); bad++; }
    printf("%d fields checked, %d mismatches\n", checked, bad);
    return bad != 0;
}
