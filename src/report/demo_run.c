/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/report/demo_run.c - the demo's run: the output folders, the steps in order (demo_optics.c,
 * demo_series.c, demo_compare.c, demo_report.c), timed. */
#include "demo_impl.h"

#include "rpiv/field.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include <omp.h>

/* ---- the run ------------------------------------------------------------------------------ */

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static rpiv_status mkdir_one(const char *path)
{
    if (mkdir(path, 0777) == 0 || errno == EEXIST) {
        struct stat sb;
        if (stat(path, &sb) == 0 && S_ISDIR(sb.st_mode))
            return RPIV_OK;
        return rpiv_fail(RPIV_EIO, "%s: exists and is not a folder", path);
    }
    return rpiv_fail(RPIV_EIO, "%s: cannot make folder: %s", path, strerror(errno));
}

/* dir and its parents, then dir/data and dir/images. */
static rpiv_status make_dirs(demo_ctx *c)
{
    char buf[RPIV_PATH_MAX];
    size_t n = strlen(c->dir);
    rpiv_status st;
    for (size_t k = 1; k <= n; k++) {
        if (k < n && c->dir[k] != '/')
            continue;
        memcpy(buf, c->dir, k);
        buf[k] = '\0';
        if ((st = mkdir_one(buf)))
            return st;
    }
    if ((st = demo_path(c, "data", buf, sizeof buf)) || (st = mkdir_one(buf)))
        return st;
    if (c->p.save_images &&
        ((st = demo_path(c, "images", buf, sizeof buf)) || (st = mkdir_one(buf))))
        return st;
    return RPIV_OK;
}

static void ctx_free(demo_ctx *c)
{
    rpiv_optics_result_free(c->trace);
    rpiv_optics_selfsim_free(c->fit);
    rpiv_sheet_free(c->sheet);
    rpiv_image_free(c->mask);
    rpiv_image_free(c->sample);
    rpiv_field_free(c->ppiv_mid);
    rpiv_field_free(c->rfield);
    rpiv_field_free(c->bfield);
    for (size_t k = 0; k < RPIV_DEMO_MAX_SNAP; k++)
        rpiv_field_free(c->snapf[k]);
    void *arrays[] = {c->mzinf,  c->mzmax,  c->mzsup,  c->me,        c->sweep_prof, c->xs,
                      c->ys,     c->fluid,  c->zk,     c->uvol,      c->plane_e1,   c->col_ok,
                      c->czinf,  c->czmax,  c->czsup,  c->e1inf,     c->e1max,      c->e1sup,
                      c->ur_mid, c->up_mid, c->umodel, c->usnap_mid, c->inv_z,      c->inv_zm};
    for (size_t k = 0; k < sizeof arrays / sizeof arrays[0]; k++)
        free(arrays[k]);
}

/* The steps in their order; the image band is set up first and counted with step 2 (flow,
 * mask, grid). */
typedef rpiv_status (*step_fn)(demo_ctx *);
static const step_fn steps[] = {demo_geometry, demo_optics,  demo_flow,  demo_ppiv,
                                demo_rpiv,     demo_compare, demo_report};
static const int step_of[] = {1, 0, 1, 2, 3, 4, 5};

/* The snapshots: p->snap below N, then N itself. */
static void snapshots(demo_ctx *c)
{
    c->nsnap = 0;
    for (size_t k = 0; k < c->p.nsnap && c->nsnap < RPIV_DEMO_MAX_SNAP - 1; k++)
        if (c->p.snap[k] < c->p.rpiv_pairs)
            c->snap[c->nsnap++] = c->p.snap[k];
    c->snap[c->nsnap++] = c->p.rpiv_pairs;
}

rpiv_status rpiv_demo_run(const rpiv_experiment *e, const rpiv_demo_params *p, const char *dir,
                          const rpiv_progress *prog, const rpiv_demo_log *log,
                          rpiv_demo_result *out)
{
    rpiv_status st;
    if ((st = rpiv_demo_params_check(p)) || (st = rpiv_experiment_check(e)))
        return st;
    if (!dir || !dir[0])
        return rpiv_fail(RPIV_EINVAL, "demo: no output folder");
    demo_ctx *c = calloc(1, sizeof *c);
    rpiv_demo_result *res = calloc(1, sizeof *res);
    if (!c || !res) {
        free(c);
        free(res);
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    }
    c->e = *e;
    c->p = *p;
    c->prog = prog;
    c->log = log;
    c->res = res;
    if (snprintf(c->dir, sizeof c->dir, "%s", dir) >= (int)sizeof c->dir) {
        st = rpiv_fail(RPIV_EINVAL, "demo: output folder name too long: %s", dir);
        goto out_free;
    }
    while (strlen(c->dir) > 1 && c->dir[strlen(c->dir) - 1] == '/')
        c->dir[strlen(c->dir) - 1] = '\0';
    snapshots(c);
    res->threads = p->threads > 0 ? p->threads : omp_get_max_threads();
    c->e.piv.threads = p->threads;
    if ((st = make_dirs(c)))
        goto out_free;

    double t0 = now_s(), t;
    for (size_t k = 0; k < sizeof steps / sizeof steps[0]; k++) {
        t = now_s();
        if ((st = steps[k](c)))
            goto out_free;
        double dt = now_s() - t;
        res->step_seconds[step_of[k]] += dt;
        res->seconds = now_s() - t0;
        if (k != 0) /* the band set-up is part of step 2 */
            demo_note(c, "  (step %d: %.1f s)", step_of[k] + 1, res->step_seconds[step_of[k]]);
    }
    res->seconds = now_s() - t0;
    c->total = c->done;
    if ((st = demo_tick(c, 0)))
        goto out_free;
    demo_note(c, "done in %.1f s: %s/report.md, %s/report.html", res->seconds, c->dir, c->dir);
    if (out)
        *out = *res;
out_free:
    ctx_free(c);
    free(c);
    free(res);
    return st;
}
