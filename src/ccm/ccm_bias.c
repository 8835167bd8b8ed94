/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The refracted sheet's bias for every vector of a field (docs/bias.md): at each vector's
 * section x* the displacement Eq. "statform" predicts through the sheet there, for the
 * velocity's variation across the depth (the duct, a profile, or the measured field's
 * gradient along x* mapped onto z* by the sheet's inclination), against the displacement at a
 * named depth (z*_max or z*_OP). The uncertainty is the bias's sensitivity to the sheet's
 * thickness and position. */
#include "ccm_impl.h"
#include "rpiv/flow.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *const rpiv_ccm_depth_names[] = {"zmax", "zop", NULL};
const char *const rpiv_ccm_vary_names[] = {"duct", "profile", "field", NULL};

rpiv_ccm_bias_params rpiv_ccm_bias_params_default(void)
{
    rpiv_ccm_bias_params bp;
    memset(&bp, 0, sizeof bp);
    bp.depth = RPIV_CCM_DEPTH_ZMAX;
    bp.vary = RPIV_CCM_VARY_DUCT;
    bp.rel_thickness = 0.1;
    bp.dz = 0.01;
    bp.pixel_box = 1;
    bp.window_model = 1;
    bp.window_interp = 1;
    bp.measured = 1; /* session 11: better than the continuous peak in every band measured */
    bp.measured_step = 8;
    bp.threads = 0;
    return bp;
}

rpiv_status rpiv_ccm_bias_params_check(const rpiv_ccm_bias_params *bp)
{
    if (bp->depth != RPIV_CCM_DEPTH_ZMAX && bp->depth != RPIV_CCM_DEPTH_ZOP)
        return rpiv_fail(RPIV_EINVAL, "bias: depth %d is neither zmax (0) nor zop (1)", bp->depth);
    if (bp->vary < RPIV_CCM_VARY_DUCT || bp->vary > RPIV_CCM_VARY_FIELD)
        return rpiv_fail(RPIV_EINVAL, "bias: variation %d is not duct, profile or field", bp->vary);
    if (bp->vary == RPIV_CCM_VARY_PROFILE && !bp->profile[0])
        return rpiv_fail(RPIV_EINVAL, "bias: the profile variation needs a profile file");
    if (memchr(bp->profile, 0, sizeof bp->profile) == NULL)
        return rpiv_fail(RPIV_EINVAL, "bias: profile path not terminated");
    if (!(bp->rel_thickness >= 0 && bp->rel_thickness <= 0.9))
        return rpiv_fail(RPIV_EINVAL, "bias: rel_thickness %g outside 0..0.9", bp->rel_thickness);
    if (!(bp->dz >= 0 && bp->dz <= 0.5))
        return rpiv_fail(RPIV_EINVAL, "bias: dz %g outside 0..0.5", bp->dz);
    if (!(bp->pixel_box >= 0 && bp->pixel_box <= 4))
        return rpiv_fail(RPIV_EINVAL, "bias: pixel_box %g px outside 0..4", bp->pixel_box);
    if (bp->window_model != 0 && bp->window_model != 1)
        return rpiv_fail(RPIV_EINVAL, "bias: window_model %d is neither 0 nor 1", bp->window_model);
    if (bp->measured != 0 && bp->measured != 1)
        return rpiv_fail(RPIV_EINVAL, "bias: measured %d is neither 0 nor 1", bp->measured);
    if (bp->measured_step < 1 || bp->measured_step > 64)
        return rpiv_fail(RPIV_EINVAL, "bias: measured_step %d outside 1..64", bp->measured_step);
    if (bp->threads < 0 || bp->threads > 1024)
        return rpiv_fail(RPIV_EINVAL, "bias: %d threads outside 0..1024", bp->threads);
    return RPIV_OK;
}

/* The sheet at one section, stretched by `stretch` about zc and shifted by `shift`. */
typedef struct pert_sheet {
    const rpiv_sheet *s;
    double xstar, zc, stretch, shift;
} pert_sheet;

static double pert_fn(const void *user, double z)
{
    const pert_sheet *p = user;
    return rpiv_sheet_eval(p->s, p->xstar, p->zc + (z - p->shift - p->zc) / p->stretch);
}

/* A linear profile c + a (z - z0). */
typedef struct lin_profile {
    double c, a, z0;
} lin_profile;

static double lin_fn(const void *user, double z)
{
    const lin_profile *l = user;
    return l->c + l->a * (z - l->z0);
}

/* The bias of one vector through one variant of the sheet: the predicted measurement (the
 * continuous peak, or with `measured` the engine's estimate on its window's plane) minus the
 * displacement at the reference depth (dref_u, dref_v), px. */
static rpiv_status bias_one(const rpiv_ccm_model *m0, rpiv_ccm_work *w, pert_sheet *ps,
                            int measured, double stretch, double shift, double dref_u,
                            double dref_v, double *bu, double *bv)
{
    rpiv_ccm_model m = *m0;
    ps->stretch = stretch;
    ps->shift = shift;
    m.illum = (rpiv_ccm_func){pert_fn, ps};
    if (!measured) /* the continuous peak does not depend on the window: skip its estimate */
        m.window_w = m.window_h = 0;
    if (m.nbreaks < RPIV_CCM_MAX_BREAKS && ps->zc + shift > m.zlo && ps->zc + shift < m.zhi)
        m.breaks[m.nbreaks++] = ps->zc + shift; /* the sheet's peak */
    rpiv_ccm_peak pk;
    rpiv_status st = rpiv_ccm_predict(&m, w, &pk);
    if (st)
        return st;
    *bu = (measured ? pk.dx_sub : pk.dx) - dref_u;
    *bv = (measured ? pk.dy_sub : pk.dy) - dref_v;
    return RPIV_OK;
}

/* The quantities written, in this order. */
enum { Q_BU, Q_BV, Q_UC, Q_VC, Q_SU, Q_SV, Q_Z, NQ };
static const char *const qname[NQ] = {"bias_u",     "bias_v",     "u_corrected", "v_corrected",
                                      "bias_u_std", "bias_v_std", "z_ref"};
static const int qunit[NQ] = {RPIV_UNIT_PX_PER_DT, RPIV_UNIT_PX_PER_DT | RPIV_UNIT_ODD_Y,
                              RPIV_UNIT_PX_PER_DT, RPIV_UNIT_PX_PER_DT | RPIV_UNIT_ODD_Y,
                              RPIV_UNIT_PX_PER_DT, RPIV_UNIT_PX_PER_DT,
                              RPIV_UNIT_ONE};

/* The derivative of a along x at (i, j) of f, px per px: central over unmasked neighbours,
 * else one-sided, else 0. */
static double ddx(const rpiv_field *f, const float *a, int i, int j)
{
    size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
    int l = i > 0 && f->flag[k - 1] != RPIV_FLAG_MASKED;
    int r = i + 1 < f->nx && f->flag[k + 1] != RPIV_FLAG_MASKED;
    if (l && r)
        return ((double)a[k + 1] - (double)a[k - 1]) / (2 * f->dx);
    if (r)
        return ((double)a[k + 1] - (double)a[k]) / f->dx;
    if (l)
        return ((double)a[k] - (double)a[k - 1]) / f->dx;
    return 0;
}

/* Everything one row shares. */
typedef struct bias_job {
    rpiv_field *f;
    const rpiv_ccm_model *base;
    const rpiv_sheet *sheet;
    const rpiv_ccm_geometry *g;
    const rpiv_ccm_bias_params *bp;
    const rpiv_ccm_params *p;
    const rpiv_ccm_curve *profile;
    float *q[NQ];
} bias_job;

/* The quantities of vector k: bias (bu, bv), squared std (su, sv), reference depth. */
static void store(const bias_job *jb, size_t k, double bu, double bv, double su, double sv,
                  double zref)
{
    const rpiv_field *f = jb->f;
    jb->q[Q_BU][k] = (float)bu;
    jb->q[Q_BV][k] = (float)bv;
    jb->q[Q_UC][k] = (float)((double)f->u[k] - bu);
    jb->q[Q_VC][k] = (float)((double)f->v[k] - bv);
    jb->q[Q_SU][k] = (float)sqrt(su);
    jb->q[Q_SV][k] = (float)sqrt(sv);
    jb->q[Q_Z][k] = (float)zref;
}

/* One vector (i, j); m has the row's velocity (DUCT, PROFILE) and uref its untabulated U*. */
static rpiv_status vector(const bias_job *jb, rpiv_ccm_work *w, const rpiv_ccm_model *mrow,
                          const rpiv_ccm_func *uref, int i, int j)
{
    const rpiv_field *f = jb->f;
    const rpiv_ccm_bias_params *bp = jb->bp;
    size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
    double xstar = jb->g->x0_star + (f->x0 + i * f->dx + 0.5) * jb->g->star_per_px, zmax;
    rpiv_status st = rpiv_ccm_sheet_zmax(jb->sheet, xstar, jb->p, &zmax);
    if (st)
        return st;
    double zref = bp->depth == RPIV_CCM_DEPTH_ZMAX ? zmax : mrow->camera.zop_star;
    rpiv_ccm_model m = *mrow;
    double dref_u = 0, dref_v = 0;
    lin_profile lu = {0, 0, zref}, lv = {0, 0, zref};
    if (bp->vary == RPIV_CCM_VARY_FIELD) {
        /* the sheet's peak moves along x*: the field's gradient along x* is one across z* */
        double hx = f->dx * jb->g->star_per_px, z1, z0;
        if ((st = rpiv_ccm_sheet_zmax(jb->sheet, xstar + hx, jb->p, &z1)) ||
            (st = rpiv_ccm_sheet_zmax(jb->sheet, xstar - hx, jb->p, &z0)))
            return st;
        double dzdx = (z1 - z0) / (2 * hx);
        if (!(fabs(dzdx) > 1e-9))
            return rpiv_fail(RPIV_EINVAL,
                             "bias: the sheet's peak does not move along x* at x* = %g: the "
                             "measured field says nothing of the velocity across the depth",
                             xstar);
        double per_xstar = 1.0 / (jb->g->star_per_px * m.scale_px); /* px/px -> U* per x* */
        lu.a = ddx(f, f->u, i, j) * per_xstar / dzdx;
        lv.a = ddx(f, f->v, i, j) * per_xstar / dzdx;
        if (bp->measured) {
            /* the engine's estimate moves with a uniform displacement only on a deformed
             * plane; on whole-pixel offsets it depends on the displacement's fraction of a
             * pixel: anchor the profile at the measured displacement */
            dref_u = (double)f->u[k];
            dref_v = (double)f->v[k];
            lu.c = dref_u / m.scale_px;
            lv.c = dref_v / m.scale_px;
        }
        m.u = (rpiv_ccm_func){lin_fn, &lu};
        m.v = lv.a != 0 || lv.c != 0 ? (rpiv_ccm_func){lin_fn, &lv} : (rpiv_ccm_func){NULL, NULL};
    } else {
        dref_u = m.scale_px * uref->fn(uref->user, zref);
    }
    pert_sheet ps = {jb->sheet, xstar, zmax, 1, 0};
    double bu, bv;
    if ((st = bias_one(&m, w, &ps, bp->measured, 1, 0, dref_u, dref_v, &bu, &bv)))
        return st;
    double su = 0, sv = 0;
    if (bp->rel_thickness > 0) {
        double pu, pv, nu, nv;
        if ((st = bias_one(&m, w, &ps, bp->measured, 1 + bp->rel_thickness, 0, dref_u, dref_v, &pu,
                           &pv)) ||
            (st = bias_one(&m, w, &ps, bp->measured, 1 - bp->rel_thickness, 0, dref_u, dref_v, &nu,
                           &nv)))
            return st;
        su += 0.25 * (pu - nu) * (pu - nu);
        sv += 0.25 * (pv - nv) * (pv - nv);
    }
    if (bp->dz > 0) {
        double pu, pv, nu, nv;
        if ((st = bias_one(&m, w, &ps, bp->measured, 1, bp->dz, dref_u, dref_v, &pu, &pv)) ||
            (st = bias_one(&m, w, &ps, bp->measured, 1, -bp->dz, dref_u, dref_v, &nu, &nv)))
            return st;
        su += 0.25 * (pu - nu) * (pu - nu);
        sv += 0.25 * (pv - nv) * (pv - nv);
    }
    store(jb, k, bu, bv, su, sv, zref);
    return RPIV_OK;
}

/* ---- measured = 1 at measured_step > 1: the window's estimate at nodes, interpolated -------
 * Along a row (duct, profile) the model of a vector depends only on its section x*, and the
 * window's estimate less the continuous peak, dx_sub - dx, is a smooth function of x* except
 * where the estimator's path on the sampled plane changes: the sampled maximum moves to the
 * next pixel, a sample its logarithms read turns non-positive (the 7 x 7 spline falls to
 * 5 x 5, then to the 3-point Gaussian, which is off by up to 0.08 px on a broad skewed peak),
 * or the window's passes cycle instead of converging. Those are its signature (ccm_wsig). The
 * estimate is computed exactly every measured_step-th unmasked vector of the row; between two
 * exact vectors whose signatures differ, or that did not converge, exactly at the middle one,
 * recursively; the offset of every other vector is interpolated between two exact vectors of
 * the same signature (cubic with the next exact vectors on both sides when they share it, else
 * quadratic or linear). The continuous peak is computed once at every vector. With an infinite
 * window (window_model 0) the rows are exact at every vector (its estimate's signature is not
 * kept). */

enum { MAXVAR = 5 };

/* One vector through one variant of the sheet. */
typedef struct npt {
    double dx, dy; /* the continuous peak, px */
    double sx, sy; /* the window's estimate (exact), px */
    ccm_wsig sig;
    int exact;
} npt;

typedef struct nrow {
    const bias_job *jb;
    rpiv_ccm_work *w;
    const rpiv_ccm_model *m; /* the row's model (its velocity) */
    int n, nvar;
    double stretch[MAXVAR], shift[MAXVAR];
    double *xstar, *zmax; /* [n] */
    npt *pt;              /* [t nvar + v] */
} nrow;

/* Vector t through variant v: the continuous peak; with window, the estimate and signature. */
static rpiv_status npredict(nrow *r, int t, int v, int window)
{
    rpiv_ccm_model m = *r->m;
    pert_sheet ps = {r->jb->sheet, r->xstar[t], r->zmax[t], r->stretch[v], r->shift[v]};
    npt *q = &r->pt[(size_t)t * (size_t)r->nvar + (size_t)v];
    m.illum = (rpiv_ccm_func){pert_fn, &ps};
    if (!window)
        m.window_w = m.window_h = 0;
    if (m.nbreaks < RPIV_CCM_MAX_BREAKS && ps.zc + ps.shift > m.zlo && ps.zc + ps.shift < m.zhi)
        m.breaks[m.nbreaks++] = ps.zc + ps.shift; /* the sheet's peak, as bias_one */
    rpiv_ccm_peak pk;
    rpiv_status st = ccm_predict_sig(&m, r->w, &pk, window ? &q->sig : NULL);
    if (st)
        return st;
    q->dx = pk.dx;
    q->dy = pk.dy;
    if (window) {
        q->sx = pk.dx_sub;
        q->sy = pk.dy_sub;
        q->exact = 1;
    }
    return RPIV_OK;
}

static int sig_same(const ccm_wsig *a, const ccm_wsig *b)
{
    return a->conv && b->conv && a->mx == b->mx && a->my == b->my && a->sig == b->sig;
}

#define NPT(r, t, v) (&(r)->pt[(size_t)(t) * (size_t)(r)->nvar + (size_t)(v)])

/* Exact vectors between a and b (both exact) until every gap lies between two of the same
 * signature. */
static rpiv_status refine(nrow *r, int v, int a, int b)
{
    while (b - a > 1 && !sig_same(&NPT(r, a, v)->sig, &NPT(r, b, v)->sig)) {
        int mid = a + (b - a) / 2;
        rpiv_status st = npredict(r, mid, v, 1);
        if (st || (st = refine(r, v, a, mid)))
            return st;
        a = mid;
    }
    return RPIV_OK;
}

/* The offset (estimate less continuous peak) of vector t of variant v between the exact
 * vectors l < t < h of the same signature; ll, hh: the exact ones beyond them (-1: none). */
static void interp(nrow *r, int v, int t, int ll, int l, int h, int hh, double *ox, double *oy)
{
    int idx[4], k = 0;
    const ccm_wsig *sg = &NPT(r, l, v)->sig;
    if (ll >= 0 && sig_same(&NPT(r, ll, v)->sig, sg))
        idx[k++] = ll;
    idx[k++] = l;
    idx[k++] = h;
    if (hh >= 0 && sig_same(&NPT(r, hh, v)->sig, sg))
        idx[k++] = hh;
    double x = r->xstar[t];
    *ox = *oy = 0;
    for (int a = 0; a < k; a++) { /* Lagrange through the k exact vectors */
        double wgt = 1;
        for (int b = 0; b < k; b++)
            if (b != a)
                wgt *= (x - r->xstar[idx[b]]) / (r->xstar[idx[a]] - r->xstar[idx[b]]);
        const npt *q = NPT(r, idx[a], v);
        *ox += wgt * (q->sx - q->dx);
        *oy += wgt * (q->sy - q->dy);
    }
}

/* With the deformation's interpolation the paths' weights blend the estimates continuously
 * (ccm_window.c), and the offset can bend within one signature where they change: between two
 * exact vectors of the same signature whose weights differ by more than NODE_DW, the one in
 * the middle is computed exactly, and where the interpolation missed it by more than NODE_TOL
 * px both halves are refined again. */
#define NODE_TOL 5e-5
#define NODE_DW  (1.0 / 256)

static rpiv_status refine_smooth(nrow *r, int v, int a, int b)
{
    const ccm_wsig *sa = &NPT(r, a, v)->sig, *sb = &NPT(r, b, v)->sig;
    if (b - a < 2 || !sig_same(sa, sb) ||
        !(fabs(sa->w7 - sb->w7) > NODE_DW || fabs(sa->w3 - sb->w3) > NODE_DW))
        return RPIV_OK;
    int mid = a + (b - a) / 2, ll, hh;
    for (ll = a - 1; ll >= 0 && !NPT(r, ll, v)->exact; ll--)
        ;
    for (hh = b + 1; hh < r->n && !NPT(r, hh, v)->exact; hh++)
        ;
    double ox, oy;
    interp(r, v, mid, ll, a, b, hh < r->n ? hh : -1, &ox, &oy);
    rpiv_status st = npredict(r, mid, v, 1);
    if (st)
        return st;
    const npt *q = NPT(r, mid, v);
    if (!(fabs(q->sx - q->dx - ox) > NODE_TOL || fabs(q->sy - q->dy - oy) > NODE_TOL))
        return RPIV_OK;
    if ((st = refine(r, v, a, mid)) || (st = refine(r, v, mid, b)))
        return st;
    for (int t = a + 1, l = a; t <= b && !st; t++)
        if (NPT(r, t, v)->exact) {
            st = refine_smooth(r, v, l, t);
            l = t;
        }
    return st;
}

/* Row j by nodes (measured, duct or profile): m the row's model, uref its untabulated U*. */
static rpiv_status row_nodes(const bias_job *jb, rpiv_ccm_work *w, const rpiv_ccm_model *m,
                             const rpiv_ccm_func *uref, int j)
{
    const rpiv_field *f = jb->f;
    const rpiv_ccm_bias_params *bp = jb->bp;
    nrow r = {jb, w, m, 0, 1, {1}, {0}, NULL, NULL, NULL};
    if (bp->rel_thickness > 0) {
        r.stretch[r.nvar] = 1 + bp->rel_thickness;
        r.stretch[r.nvar + 1] = 1 - bp->rel_thickness;
        r.nvar += 2;
    }
    if (bp->dz > 0) {
        r.stretch[r.nvar] = r.stretch[r.nvar + 1] = 1;
        r.shift[r.nvar] = bp->dz;
        r.shift[r.nvar + 1] = -bp->dz;
        r.nvar += 2;
    }
    int *col = malloc((size_t)f->nx * sizeof *col);
    double *buf = malloc(3 * (size_t)f->nx * sizeof *buf);
    r.pt = calloc((size_t)f->nx * (size_t)r.nvar, sizeof *r.pt);
    rpiv_status st = RPIV_OK;
    if (!col || !buf || !r.pt) {
        st = rpiv_fail(RPIV_ENOMEM, "bias: out of memory for a row of %d vectors", f->nx);
        goto out_free;
    }
    r.xstar = buf;
    r.zmax = buf + f->nx;
    double *zref = buf + 2 * (size_t)f->nx;
    for (int i = 0; i < f->nx; i++) {
        size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
        if (f->flag[k] == RPIV_FLAG_MASKED) {
            for (int q = 0; q < NQ; q++)
                jb->q[q][k] = 0;
            continue;
        }
        col[r.n++] = i;
    }
    const int step = bp->measured_step;
    for (int t = 0; t < r.n && !st; t++) {
        r.xstar[t] = jb->g->x0_star + (f->x0 + col[t] * f->dx + 0.5) * jb->g->star_per_px;
        if ((st = rpiv_ccm_sheet_zmax(jb->sheet, r.xstar[t], jb->p, &r.zmax[t])))
            break;
        zref[t] = bp->depth == RPIV_CCM_DEPTH_ZMAX ? r.zmax[t] : m->camera.zop_star;
        for (int v = 0; v < r.nvar && !st && (t % step == 0 || t == r.n - 1); v++)
            st = npredict(&r, t, v, 1); /* the nodes */
    }
    for (int v = 0; v < r.nvar && !st; v++) {
        int a = 0;
        for (int t = 1; t < r.n && !st; t++)
            if (NPT(&r, t, v)->exact) {
                st = refine(&r, v, a, t);
                a = t;
            }
        a = 0;
        for (int t = 1; t < r.n && !st && m->window_deform == 2; t++)
            if (NPT(&r, t, v)->exact) {
                st = refine_smooth(&r, v, a, t);
                a = t;
            }
    }
    for (int t = 0; t < r.n && !st; t++) /* the continuous peak of the others */
        for (int v = 0; v < r.nvar && !st; v++)
            if (!NPT(&r, t, v)->exact)
                st = npredict(&r, t, v, 0);
    for (int t = 0; t < r.n && !st; t++) {
        double d[MAXVAR][2];
        for (int v = 0; v < r.nvar; v++) {
            const npt *q = NPT(&r, t, v);
            if (q->exact) {
                d[v][0] = q->sx;
                d[v][1] = q->sy;
                continue;
            }
            int l = t - 1, h = t + 1, ll, hh;
            while (!NPT(&r, l, v)->exact)
                l--;
            while (!NPT(&r, h, v)->exact)
                h++;
            for (ll = l - 1; ll >= 0 && !NPT(&r, ll, v)->exact; ll--)
                ;
            for (hh = h + 1; hh < r.n && !NPT(&r, hh, v)->exact; hh++)
                ;
            double ox, oy;
            interp(&r, v, t, ll, l, h, hh < r.n ? hh : -1, &ox, &oy);
            d[v][0] = q->dx + ox;
            d[v][1] = q->dy + oy;
        }
        double dref_u = m->scale_px * uref->fn(uref->user, zref[t]), su = 0, sv = 0;
        for (int v = 1; v + 1 < r.nvar; v += 2) {
            double pu = d[v][0] - d[v + 1][0], pv = d[v][1] - d[v + 1][1];
            su += 0.25 * pu * pu;
            sv += 0.25 * pv * pv;
        }
        store(jb, (size_t)j * (size_t)f->nx + (size_t)col[t], d[0][0] - dref_u, d[0][1], su, sv,
              zref[t]);
    }
out_free:
    free(col);
    free(buf);
    free(r.pt);
    return st;
}

/* One row j of the field. */
static rpiv_status row(const bias_job *jb, rpiv_ccm_work *w, int j)
{
    const rpiv_field *f = jb->f;
    double ystar = jb->g->y0_star + (f->y0 + j * f->dy + 0.5) * jb->g->star_per_px;
    rpiv_ccm_model m = *jb->base, tm;
    m.v = (rpiv_ccm_func){NULL, NULL};
    ccm_utab tab = {0};
    if (jb->bp->vary == RPIV_CCM_VARY_DUCT)
        m.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &ystar};
    else if (jb->bp->vary == RPIV_CCM_VARY_PROFILE)
        m.u = (rpiv_ccm_func){rpiv_ccm_curve_fn, jb->profile};
    else
        m.u = (rpiv_ccm_func){rpiv_ccm_const_fn, &ystar}; /* replaced per vector */
    rpiv_status st = RPIV_OK;
    tm = m;
    if (jb->bp->vary == RPIV_CCM_VARY_DUCT && (st = ccm_utab_init(&tab, &m, jb->p, &tm)))
        return st;
    if (jb->bp->measured && jb->bp->measured_step > 1 && jb->bp->vary != RPIV_CCM_VARY_FIELD &&
        m.window_w > 0) { /* (an infinite window's estimate: exact at every vector) */
        st = row_nodes(jb, w, &tm, &m.u, j);
        ccm_utab_free(&tab);
        return st;
    }
    for (int i = 0; i < f->nx && !st; i++) {
        size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
        if (f->flag[k] == RPIV_FLAG_MASKED) {
            for (int q = 0; q < NQ; q++)
                jb->q[q][k] = 0;
            continue;
        }
        st = vector(jb, w, &tm, &m.u, i, j);
    }
    ccm_utab_free(&tab);
    return st;
}

/* The quantity `name` of f: the existing one (overwritten) or a new one. */
static rpiv_status quantity(rpiv_field *f, const char *name, int unit, float **data)
{
    const rpiv_quantity *q = rpiv_field_quantity(f, name);
    if (q) {
        *data = q->data;
        return RPIV_OK;
    }
    return rpiv_field_add_quantity(f, name, unit, data);
}

rpiv_status rpiv_ccm_bias_field(rpiv_field *f, const rpiv_ccm_model *base, const rpiv_sheet *sheet,
                                const rpiv_ccm_geometry *g, const rpiv_ccm_bias_params *bp,
                                const rpiv_ccm_params *p, const rpiv_progress *progress)
{
    rpiv_status st;
    if (!f || !base || !sheet || !g || !bp || !p)
        return rpiv_fail(RPIV_EINVAL, "bias: a required argument is NULL");
    if ((st = rpiv_ccm_bias_params_check(bp)) || (st = rpiv_ccm_params_check(p)) ||
        (st = rpiv_ccm_model_check(base)))
        return st;
    if (f->y_up)
        return rpiv_fail(RPIV_EINVAL, "bias: the field is turned y-up; give it in image "
                                      "coordinates (the bias is computed before turning)");
    if (!(g->star_per_px > 0) || !isfinite(g->x0_star) || !isfinite(g->y0_star))
        return rpiv_fail(RPIV_EINVAL, "bias: the geometry needs star_per_px > 0 and finite edges");
    bias_job jb = {f, base, sheet, g, bp, p, NULL, {0}};
    rpiv_ccm_curve *profile = NULL;
    if (bp->vary == RPIV_CCM_VARY_PROFILE) {
        if ((st = rpiv_ccm_curve_load(bp->profile, &profile)))
            return st;
        jb.profile = profile;
    }
    for (int q = 0; q < NQ; q++)
        if ((st = quantity(f, qname[q], qunit[q], &jb.q[q]))) {
            rpiv_ccm_curve_free(profile);
            return st;
        }
    const int ny = f->ny;
    int nth = bp->threads > 0 ? bp->threads : omp_get_max_threads();
    if (nth > ny)
        nth = ny;
    rpiv_ccm_work **w = calloc((size_t)nth, sizeof *w);
    rpiv_status *sts = calloc((size_t)ny, sizeof *sts);
    char(*msg)[256] = calloc((size_t)ny, sizeof *msg);
    if (!w || !sts || !msg) {
        st = rpiv_fail(RPIV_ENOMEM, "bias: out of memory for %d rows", ny);
        goto out_free;
    }
    for (int t = 0; t < nth; t++)
        if ((st = rpiv_ccm_work_new(p, &w[t])))
            goto out_free;
    /* batches of rows, so that progress is reported from the calling thread; every vector
     * depends only on its own inputs: the same result for any thread count */
    int batch = 2 * nth;
    for (int b = 0; b < ny && !st; b += batch) {
        int e = b + batch < ny ? b + batch : ny;
#pragma omp parallel for num_threads(nth) schedule(dynamic, 1)
        for (int j = b; j < e; j++) {
            sts[j] = row(&jb, w[omp_get_thread_num()], j);
            if (sts[j])
                snprintf(msg[j], sizeof msg[j], "%s", rpiv_errmsg());
        }
        for (int j = b; j < e; j++)
            if (sts[j]) {
                st = rpiv_fail(sts[j], "%s", msg[j]);
                break;
            }
        if (!st && rpiv_progress_report(progress, (size_t)e, (size_t)ny))
            st = rpiv_fail(RPIV_EINTR, "bias: interrupted after %d of %d rows", e, ny);
    }
out_free:
    if (w)
        for (int t = 0; t < nth; t++)
            rpiv_ccm_work_free(w[t]);
    free(w);
    free(sts);
    free(msg);
    rpiv_ccm_curve_free(profile);
    return st;
}
