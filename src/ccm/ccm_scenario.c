/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The paper's scenarios (section "Analysis of the illumination methods with the CCM"): P-PIV
 * scanned with the object plane on the sheet or fixed, and R-PIV along the inclined sheet. */
#include "ccm_impl.h"

#include "base/atomic.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

rpiv_ccm_scenario rpiv_ccm_scenario_default(rpiv_ccm_kind kind)
{
    rpiv_ccm_scenario s = {.kind = kind,
                           .e_star = 0.05,
                           .zop_star = 0.5,
                           .z0 = 0.0625,
                           .z1 = 0.9375,
                           .n = 15,
                           .symmetric = 1,
                           .xlo = 0.01,
                           .xhi = 100};
    if (kind == RPIV_CCM_RPIV) {
        s.z0 = 0.03125;
        s.z1 = 0.5;
        s.n = 16;
    }
    return s;
}

rpiv_status rpiv_ccm_scenario_check(const rpiv_ccm_scenario *s)
{
    if (s->kind < RPIV_CCM_PPIV_SCAN || s->kind > RPIV_CCM_RPIV)
        return rpiv_fail(RPIV_EINVAL, "ccm: unknown scenario kind %d", (int)s->kind);
    if (s->kind != RPIV_CCM_RPIV && !(s->e_star > 0 && s->e_star < 100))
        return rpiv_fail(RPIV_EINVAL, "ccm: sheet thickness %g outside (0, 100)", s->e_star);
    if (!isfinite(s->zop_star))
        return rpiv_fail(RPIV_EINVAL, "ccm: object plane must be finite");
    if (s->n < 2 || s->n > 100000)
        return rpiv_fail(RPIV_EINVAL, "ccm: %zu positions outside 2..1e5", s->n);
    if (!(s->z0 < s->z1) || !(s->z0 > 0) || !(s->z1 < 1))
        return rpiv_fail(RPIV_EINVAL, "ccm: positions [%g, %g] must be increasing inside (0, 1)",
                         s->z0, s->z1);
    if (s->kind == RPIV_CCM_RPIV && !(s->xlo < s->xhi))
        return rpiv_fail(RPIV_EINVAL, "ccm: x* search bracket [%g, %g] is empty", s->xlo, s->xhi);
    return RPIV_OK;
}

void rpiv_ccm_table_free(rpiv_ccm_table *t)
{
    if (!t)
        return;
    free(t->row);
    free(t);
}

/* One position of a scenario. */
static rpiv_status position(const rpiv_ccm_scenario *s, const rpiv_ccm_model *base,
                            const rpiv_ccm_func *uref, const rpiv_sheet *sheet, rpiv_ccm_work *w,
                            size_t i, rpiv_ccm_row *row)
{
    rpiv_status st;
    double zt = s->z0 + (s->z1 - s->z0) * (double)i / (double)(s->n - 1);
    rpiv_ccm_model m = *base;
    rpiv_sheet *own = NULL;
    rpiv_ccm_sheet_at at = {sheet, 0};
    memset(row, 0, sizeof *row);
    if (s->kind == RPIV_CCM_RPIV) {
        if (!sheet)
            return rpiv_fail(RPIV_EINVAL, "ccm: the R-PIV scenario needs a sheet");
        if ((st = rpiv_ccm_sheet_x_of_zmax(sheet, zt, s->xlo, s->xhi, &w->p, &at.xstar)) ||
            (st = rpiv_ccm_sheet_zmax(sheet, at.xstar, &w->p, &row->zstar)))
            return st;
        m.camera.zop_star = s->zop_star;
        row->xstar = at.xstar;
    } else {
        rpiv_sheet_params sp = rpiv_sheet_params_default();
        sp.kind = RPIV_SHEET_GAUSS;
        sp.zb_star = zt;
        sp.e_star = s->e_star;
        if ((st = rpiv_sheet_new(&sp, &own)))
            return st;
        at.sheet = own;
        m.camera.zop_star = s->kind == RPIV_CCM_PPIV_SCAN ? zt : s->zop_star;
        if (m.nbreaks < RPIV_CCM_MAX_BREAKS)
            m.breaks[m.nbreaks++] = zt; /* the sheet's centre */
        row->zstar = zt;
    }
    m.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
    rpiv_ccm_peak pk;
    st = rpiv_ccm_predict(&m, w, &pk);
    rpiv_sheet_free(own);
    if (st)
        return st;
    row->uref = uref->fn(uref->user, row->zstar);
    row->umodel = pk.dx / m.scale_px;
    row->usub = pk.dx_sub / m.scale_px;
    row->err = (row->umodel - row->uref) / row->uref;
    row->err_sub = (row->usub - row->uref) / row->uref;
    return RPIV_OK;
}

static int cmp_row(const void *a, const void *b)
{
    double x = ((const rpiv_ccm_row *)a)->zstar, y = ((const rpiv_ccm_row *)b)->zstar;
    return (x > y) - (x < y);
}

static rpiv_status table_stats(rpiv_ccm_table *t)
{
    size_t n = t->n;
    double *z = malloc(n * sizeof *z), *r = malloc(n * sizeof *r), *a = malloc(n * sizeof *a),
           *b = malloc(n * sizeof *b);
    rpiv_status st = RPIV_OK;
    if (!z || !r || !a || !b) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
        goto out_free;
    }
    t->maxerr = t->maxerr_sub = 0;
    for (size_t i = 0; i < n; i++) {
        z[i] = t->row[i].zstar;
        r[i] = t->row[i].uref;
        a[i] = t->row[i].umodel;
        b[i] = t->row[i].usub;
        t->maxerr = fmax(t->maxerr, fabs(t->row[i].err));
        t->maxerr_sub = fmax(t->maxerr_sub, fabs(t->row[i].err_sub));
    }
    if ((st = rpiv_e1(z, r, a, n, &t->e1)))
        goto out_free;
    st = rpiv_e1(z, r, b, n, &t->e1_sub);
out_free:
    free(z);
    free(r);
    free(a);
    free(b);
    return st;
}

rpiv_status rpiv_ccm_scenario_run(const rpiv_ccm_scenario *s, const rpiv_ccm_model *base,
                                  const rpiv_sheet *sheet, const rpiv_ccm_params *p, int threads,
                                  const rpiv_progress *progress, rpiv_ccm_table **out)
{
    *out = NULL;
    rpiv_status st;
    if ((st = rpiv_ccm_scenario_check(s)) || (st = rpiv_ccm_model_check(base)) ||
        (st = rpiv_ccm_params_check(p)))
        return st;
    if (threads < 0 || threads > 1024)
        return rpiv_fail(RPIV_EINVAL, "ccm: %d threads outside 0..1024", threads);
    if (s->kind == RPIV_CCM_RPIV && !sheet)
        return rpiv_fail(RPIV_EINVAL, "ccm: the R-PIV scenario needs a sheet");
    size_t n = s->n;
    int nth = threads > 0 ? threads : omp_get_max_threads();
    ccm_utab tab;
    rpiv_ccm_model tb;
    if ((st = ccm_utab_init(&tab, base, p, &tb)))
        return st;
    rpiv_ccm_table *t = calloc(1, sizeof *t);
    rpiv_ccm_row *rows = calloc(2 * n, sizeof *rows);
    rpiv_ccm_work **w = calloc((size_t)nth, sizeof *w);
    rpiv_status *sts = calloc(n, sizeof *sts);
    char(*msg)[256] = calloc(n, sizeof *msg);
    if (!t || !rows || !w || !sts || !msg) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
        goto out_free;
    }
    for (int k = 0; k < nth; k++)
        if ((st = rpiv_ccm_work_new(p, &w[k])))
            goto out_free;
    /* batches so that progress is reported from the calling thread */
    size_t batch = 4 * (size_t)nth;
    for (size_t b = 0; b < n && !st; b += batch) {
        size_t e = b + batch < n ? b + batch : n;
#pragma omp parallel for num_threads(nth) schedule(dynamic, 1)
        for (long i = (long)b; i < (long)e; i++) {
            sts[i] =
                position(s, &tb, &base->u, sheet, w[omp_get_thread_num()], (size_t)i, &rows[i]);
            if (sts[i])
                snprintf(msg[i], sizeof msg[i], "%s", rpiv_errmsg());
        }
        for (size_t i = b; i < e; i++)
            if (sts[i]) {
                st = rpiv_fail(sts[i], "%s", msg[i]);
                break;
            }
        if (!st && rpiv_progress_report(progress, e, n))
            st =
                rpiv_fail(RPIV_EINTR, "ccm: scenario interrupted after %zu of %zu positions", e, n);
    }
    if (st)
        goto out_free;
    size_t nr = n;
    if (s->kind == RPIV_CCM_RPIV && s->symmetric) {
        /* the paper's extension: the profile mirrored about the mid-plane z* = 0.5 */
        for (size_t i = 0; i < n; i++) {
            if (rows[i].zstar >= 0.5 - 1e-9)
                continue;
            rpiv_ccm_row r = rows[i];
            r.zstar = 1 - rows[i].zstar;
            r.uref = base->u.fn(base->u.user, r.zstar);
            r.err = (r.umodel - r.uref) / r.uref;
            r.err_sub = (r.usub - r.uref) / r.uref;
            r.mirrored = 1;
            rows[nr++] = r;
        }
    }
    qsort(rows, nr, sizeof *rows, cmp_row);
    t->row = rows;
    t->n = nr;
    rows = NULL;
    if ((st = table_stats(t)))
        goto out_free;
    *out = t;
    t = NULL;
out_free:
    ccm_utab_free(&tab);
    if (w)
        for (int k = 0; k < nth; k++)
            rpiv_ccm_work_free(w[k]);
    free(w);
    free(sts);
    free(msg);
    free(rows);
    rpiv_ccm_table_free(t);
    return st;
}

rpiv_status rpiv_ccm_table_save(const rpiv_ccm_table *t, const char *hdr, const char *path)
{
    atomic_file af; /* unique temporary name, fsync, rename, fsync of the folder */
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    FILE *fp = af.fp;
    fprintf(fp, "# rpiv-ccm 1\n");
    ccm_file_header(fp, hdr);
    fprintf(fp, "# E1 = %.6g (continuous peak), %.6g (sub-pixel estimator)\n", t->e1, t->e1_sub);
    fprintf(fp, "# max |relative error| = %.6g (continuous peak), %.6g (sub-pixel estimator)\n",
            t->maxerr, t->maxerr_sub);
    fprintf(fp, "# columns: x* z* U*_ref U*_model U*_subpixel err err_subpixel mirrored\n");
    for (size_t i = 0; i < t->n; i++) {
        const rpiv_ccm_row *r = &t->row[i];
        fprintf(fp, "%.8g %.8g %.10g %.10g %.10g %.6e %.6e %d\n", r->xstar, r->zstar, r->uref,
                r->umodel, r->usub, r->err, r->err_sub, r->mirrored);
    }
    return atomic_commit(&af);
}

size_t rpiv_ccm_table_worst(const rpiv_ccm_table *t)
{
    size_t worst = 0;
    for (size_t i = 0; i < t->n; i++)
        if (fabs(t->row[i].err) > fabs(t->row[worst].err) + 1e-12)
            worst = i;
    return worst;
}
