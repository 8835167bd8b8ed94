/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/report/demo.c - the demo: its parameters and the helpers its steps share (notes,
 * progress, paths, the P-PIV volume). The run is demo_run.c; docs/demo.md describes the study. */
#include "demo_impl.h"

#include "rpiv/field.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_spline.h>
#include <omp.h>

rpiv_demo_params rpiv_demo_params_default(void)
{
    rpiv_demo_params p = {.width_px = 0,
                          .margin_px = 32,
                          .rpiv_pairs = 100,
                          .ppiv_pairs = 12,
                          .ppiv_e_star = 0.05,
                          .ppiv_z0 = 0.0625,
                          .ppiv_dz = 0.0625,
                          .ppiv_planes = 15,
                          .ppiv_slab = 1.5,
                          .optics_x0 = 0.5,
                          .optics_x1 = 9.0,
                          .optics_dx = 0.25,
                          .profile_x = 5.0,
                          .wall_z = 0.12,
                          .core_z = 0.2,
                          .nsnap = 9,
                          .snap = {1, 2, 5, 10, 20, 50, 100, 200, 500},
                          .save_images = 1,
                          .cache_mb = 1024,
                          .threads = 0};
    return p;
}

rpiv_demo_params rpiv_demo_params_quick(void)
{
    rpiv_demo_params p = rpiv_demo_params_default();
    p.width_px = 512;
    p.ppiv_pairs = 3;
    p.rpiv_pairs = 16;
    return p;
}

rpiv_status rpiv_demo_params_check(const rpiv_demo_params *p)
{
    if (p->width_px < 0 || p->width_px > 1 << 16)
        return rpiv_fail(RPIV_EINVAL, "demo: width_px = %d outside [0, 65536]", p->width_px);
    if (p->margin_px < 0 || p->margin_px > 4096)
        return rpiv_fail(RPIV_EINVAL, "demo: margin_px = %d outside [0, 4096]", p->margin_px);
    if (p->rpiv_pairs < 1 || p->rpiv_pairs > 1000000)
        return rpiv_fail(RPIV_EINVAL, "demo: rpiv_pairs = %d outside [1, 1000000]", p->rpiv_pairs);
    if (p->ppiv_pairs < 1 || p->ppiv_pairs > 1000000)
        return rpiv_fail(RPIV_EINVAL, "demo: ppiv_pairs = %d outside [1, 1000000]", p->ppiv_pairs);
    if (!(p->ppiv_e_star > 0 && p->ppiv_e_star <= 1))
        return rpiv_fail(RPIV_EINVAL, "demo: ppiv_e_star = %g outside (0, 1]", p->ppiv_e_star);
    if (p->ppiv_planes < 2 || p->ppiv_planes > 256)
        return rpiv_fail(RPIV_EINVAL, "demo: ppiv_planes = %d outside [2, 256]", p->ppiv_planes);
    if (!(p->ppiv_dz > 0))
        return rpiv_fail(RPIV_EINVAL, "demo: ppiv_dz = %g must be > 0", p->ppiv_dz);
    double zl = p->ppiv_z0 + (p->ppiv_planes - 1) * p->ppiv_dz;
    if (!(p->ppiv_z0 > 0 && zl < 1))
        return rpiv_fail(RPIV_EINVAL,
                         "demo: P-PIV planes %g ... %g must lie strictly inside (0, 1)", p->ppiv_z0,
                         zl);
    if (!(p->ppiv_slab > 0 && p->ppiv_slab <= 100))
        return rpiv_fail(RPIV_EINVAL, "demo: ppiv_slab = %g outside (0, 100]", p->ppiv_slab);
    if (!(isfinite(p->optics_x0) && isfinite(p->optics_x1) && p->optics_x1 > p->optics_x0 &&
          p->optics_dx > 0 && (p->optics_x1 - p->optics_x0) / p->optics_dx <= 10000))
        return rpiv_fail(RPIV_EINVAL,
                         "demo: optics stations %g : %g : %g (need x1 > x0, 0 < dx, at most "
                         "10000 stations)",
                         p->optics_x0, p->optics_dx, p->optics_x1);
    if (!isfinite(p->profile_x))
        return rpiv_fail(RPIV_EINVAL, "demo: profile_x must be finite");
    if (!(p->wall_z > 0 && p->wall_z < 1 && p->core_z > 0 && p->core_z < 1))
        return rpiv_fail(RPIV_EINVAL, "demo: wall_z = %g and core_z = %g must be in (0, 1)",
                         p->wall_z, p->core_z);
    if (p->nsnap > RPIV_DEMO_MAX_SNAP)
        return rpiv_fail(RPIV_EINVAL, "demo: nsnap = %zu above %d", p->nsnap, RPIV_DEMO_MAX_SNAP);
    for (size_t k = 0; k < p->nsnap; k++)
        if (p->snap[k] < 1 || (k && p->snap[k] <= p->snap[k - 1]))
            return rpiv_fail(RPIV_EINVAL,
                             "demo: snap[%zu] = %d: snapshots must be >= 1 and "
                             "increasing",
                             k, p->snap[k]);
    if (!(p->cache_mb >= 0 && p->cache_mb <= 1e6))
        return rpiv_fail(RPIV_EINVAL, "demo: cache_mb = %g outside [0, 1e6]", p->cache_mb);
    if (p->threads < 0 || p->threads > 1024)
        return rpiv_fail(RPIV_EINVAL, "demo: threads = %d outside [0, 1024]", p->threads);
    return RPIV_OK;
}

/* ---- helpers ------------------------------------------------------------------------------ */

void demo_note(demo_ctx *c, const char *fmt, ...)
{
    if (!c->log || !c->log->fn)
        return;
    char line[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    c->log->fn(c->log->user, line);
}

rpiv_status demo_tick(demo_ctx *c, size_t n)
{
    c->done += n;
    if (c->done > c->total)
        c->total = c->done;
    if (rpiv_progress_report(c->prog, c->done, c->total))
        return rpiv_fail(RPIV_EINTR, "demo: interrupted");
    return RPIV_OK;
}

rpiv_status demo_path(const demo_ctx *c, const char *name, char *buf, size_t size)
{
    int n = snprintf(buf, size, "%s/%s", c->dir, name);
    if (n < 0 || (size_t)n >= size)
        return rpiv_fail(RPIV_EINVAL, "demo: path too long: %s/%s", c->dir, name);
    return RPIV_OK;
}

void demo_add_plot(demo_ctx *c, const char *name)
{
    rpiv_demo_result *r = c->res;
    if (r->nplots >= RPIV_DEMO_MAX_PLOTS)
        return;
    snprintf(r->plots[r->nplots], sizeof r->plots[0], "%s", name);
    r->nplots++;
}

double demo_vol_eval(const demo_ctx *c, int i, int j, double z)
{
    size_t idx = (size_t)j * (size_t)c->nx + (size_t)i;
    if (!c->fluid[idx] || !(z >= 0 && z <= 1))
        return (double)NAN;
    size_t nk = c->nz + 2, plane = (size_t)c->nx * (size_t)c->ny;
    double u[258];
    for (size_t k = 0; k < nk; k++)
        u[k] = c->uvol[k * plane + idx];
    /* a natural cubic spline through the planes and the wall zeros (the paper's "cubic
     * spline" reconstruction); made per call: 17 knots cost less than caching 5000 splines */
    gsl_spline *sp = gsl_spline_alloc(gsl_interp_cspline, nk);
    if (!sp)
        return (double)NAN;
    double v = (double)NAN;
    if (gsl_spline_init(sp, c->zk, u, nk) == GSL_SUCCESS)
        v = gsl_spline_eval(sp, z, NULL);
    gsl_spline_free(sp);
    return v;
}

double demo_field_at_y(const demo_ctx *c, const rpiv_field *f, int i, double ystar)
{
    /* row coordinate of ystar on the grid */
    double t = (ystar - c->ys[0]) / (c->ys[1] - c->ys[0]);
    if (!(t >= 0 && t <= c->ny - 1))
        return (double)NAN;
    int j0 = (int)floor(t);
    if (j0 >= c->ny - 1)
        j0 = c->ny - 2;
    double a = t - j0;
    size_t k0 = (size_t)j0 * (size_t)c->nx + (size_t)i, k1 = k0 + (size_t)c->nx;
    if (!c->fluid[k0] || !c->fluid[k1])
        return (double)NAN;
    return ((1 - a) * (double)f->u[k0] + a * (double)f->u[k1]) / c->bulk_px;
}
