/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The numerical parameters, the model's inputs (defaults, check, the callbacks), Eq. "CCM_gen"
 * and Eq. "CCM_simp", and the helpers the module's files share (ccm_impl.h). */
#include "ccm_impl.h"
#include "rpiv/peak.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_math.h>

/* ---- parameters ----------------------------------------------------------------------- */

rpiv_ccm_params rpiv_ccm_params_default(void)
{
    return (rpiv_ccm_params){.epsrel = 1e-9,
                             .limit = 1000,
                             .gl_points = 20,
                             .max_width = 1.0 / 64,
                             .scan = 4001,
                             .xtol_px = 1e-7,
                             .max_iter = 500,
                             .max_range_px = 4096,
                             .subpixel = RPIV_SUBPIXEL_AUTO,
                             .utab = 4097};
}

rpiv_status rpiv_ccm_params_check(const rpiv_ccm_params *p)
{
    if (!(p->epsrel >= 1e-14 && p->epsrel <= 0.1))
        return rpiv_fail(RPIV_EINVAL, "ccm.epsrel: %g outside 1e-14..0.1", p->epsrel);
    if (p->limit < 10 || p->limit > 1000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.limit: %zu outside 10..1e6", p->limit);
    if (p->gl_points < 2 || p->gl_points > 100)
        return rpiv_fail(RPIV_EINVAL, "ccm.gl_points: %zu outside 2..100", p->gl_points);
    if (!(p->max_width > 1e-6 && p->max_width <= 10))
        return rpiv_fail(RPIV_EINVAL, "ccm.max_width: %g outside (1e-6, 10]", p->max_width);
    if (p->scan < 3 || p->scan > 10000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.scan: %zu outside 3..1e7", p->scan);
    if (!(p->xtol_px > 0 && p->xtol_px < 1))
        return rpiv_fail(RPIV_EINVAL, "ccm.xtol_px: %g outside (0, 1)", p->xtol_px);
    if (p->max_iter < 1 || p->max_iter > 1000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.max_iter: %d outside 1..1e6", p->max_iter);
    if (p->max_range_px < 3 || p->max_range_px > 1000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.max_range_px: %d outside 3..1e6", p->max_range_px);
    if ((p->utab > 0 && p->utab < 5) || p->utab > 10000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.utab: %zu nodes: 0 or 5..1e7", p->utab);
    if (p->subpixel < RPIV_SUBPIXEL_GAUSS || p->subpixel > RPIV_SUBPIXEL_AUTO)
        return rpiv_fail(RPIV_EINVAL, "ccm.subpixel: unknown estimator %d", (int)p->subpixel);
    return RPIV_OK;
}

void ccm_file_header(FILE *fp, const char *hdr)
{
    const char *s = hdr;
    while (s && *s) {
        size_t len = strcspn(s, "\n");
        fprintf(fp, "# %.*s\n", (int)len, s);
        s += len;
        if (*s == '\n')
            s++;
    }
}

unsigned long ccm_seed(unsigned long seed, unsigned long index)
{
    unsigned long long z = (unsigned long long)seed * 0x9E3779B97F4A7C15ULL + index + 1;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    return (unsigned long)(z & 0xFFFFFFFFUL);
}

/* ---- the model's inputs --------------------------------------------------------------- */

rpiv_ccm_model rpiv_ccm_model_default(void)
{
    static const double one = 1.0;
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_ccm_model m;
    memset(&m, 0, sizeof m);
    m.camera = cam;
    m.h_m = ch.h_m;
    m.dp_m = rpiv_particles_default().dp_m;
    m.scale_px = rpiv_ccm_scale_px(&cam, &ch, 1e-3);
    m.illum = (rpiv_ccm_func){rpiv_ccm_const_fn, &one};
    m.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, NULL};
    m.zlo = 0;
    m.zhi = 1;
    m.pixel_box = 1;
    return m;
}

rpiv_status rpiv_ccm_model_check(const rpiv_ccm_model *m)
{
    rpiv_status st = rpiv_camera_check(&m->camera);
    if (st)
        return st;
    if (!(m->h_m > 0 && m->h_m < 10))
        return rpiv_fail(RPIV_EINVAL, "ccm: channel height %g m outside (0, 10)", m->h_m);
    if (!(m->dp_m > 0 && m->dp_m < 1e-2))
        return rpiv_fail(RPIV_EINVAL, "ccm: particle diameter %g m outside (0, 1e-2)", m->dp_m);
    if (!isfinite(m->scale_px) || fabs(m->scale_px) > 1e6)
        return rpiv_fail(RPIV_EINVAL, "ccm: displacement scale %g px outside -1e6..1e6",
                         m->scale_px);
    if (!m->illum.fn || !m->u.fn)
        return rpiv_fail(RPIV_EINVAL, "ccm: the illumination and the velocity profile are "
                                      "required");
    if (!(m->zlo < m->zhi) || !isfinite(m->zlo) || !isfinite(m->zhi))
        return rpiv_fail(RPIV_EINVAL, "ccm: particle heights [%g, %g] are not an interval", m->zlo,
                         m->zhi);
    if (!(m->pixel_box >= 0 && m->pixel_box <= 4))
        return rpiv_fail(RPIV_EINVAL, "ccm: pixel_box %g px outside 0..4", m->pixel_box);
    if (!(m->window_w == 0 && m->window_h == 0) &&
        !(m->window_w >= 4 && m->window_h >= 4 && m->window_w <= 4096 && m->window_h <= 4096))
        return rpiv_fail(RPIV_EINVAL, "ccm: window %d x %d px outside 4..4096 px (0 x 0: infinite)",
                         m->window_w, m->window_h);
    if (!(m->window_pairs >= 0 && m->window_pairs <= 1e9))
        return rpiv_fail(RPIV_EINVAL, "ccm: window_pairs %g outside 0..1e9", m->window_pairs);
    if (m->nbreaks > RPIV_CCM_MAX_BREAKS)
        return rpiv_fail(RPIV_EINVAL, "ccm: %zu breakpoints, at most %d", m->nbreaks,
                         RPIV_CCM_MAX_BREAKS);
    return RPIV_OK;
}

double rpiv_ccm_scale_px(const rpiv_camera *cam, const rpiv_channel *ch, double dt_s)
{
    return rpiv_channel_bulk_ms(ch) * dt_s * cam->magnification / rpiv_camera_pixel_m(cam);
}

double rpiv_ccm_duct_fn(const void *user, double zstar)
{
    double y = user ? *(const double *)user : 0.5;
    return rpiv_duct_u(y, zstar);
}

double rpiv_ccm_const_fn(const void *user, double zstar)
{
    (void)zstar;
    return *(const double *)user;
}

double rpiv_ccm_sheet_fn(const void *user, double zstar)
{
    const rpiv_ccm_sheet_at *s = user;
    return rpiv_sheet_eval(s->sheet, s->xstar, zstar);
}

/* ---- Eq. "CCM_gen" and Eq. "CCM_simp" ------------------------------------------------- */

/* Peak and variance (px^2) of the continuous image of Eq. "int" of a particle at z with
 * intensity i. */
static void image_of(const ccm_frame *f, double z, double i, double dp, double *peak, double *var)
{
    const rpiv_camera *cam = &f->m->camera;
    double zd = rpiv_imaging_defocus_m(cam, f->m->h_m, z);
    double de = rpiv_imaging_de_m(cam, dp, zd);
    double s = rpiv_imaging_sigma_m(cam, de) / f->pixel_m;
    *var = s * s;
    *peak = rpiv_imaging_peak(cam, i * dp * dp, de, zd);
}

/* A pixel integrates the image over a square of side b = pixel_box: the recorded image is the
 * Gaussian convolved with that box, sampled at the pixel centres. Averaged over the particles'
 * sub-pixel positions, the correlation of two such images is the continuous one convolved with
 * the box's autocorrelation, per axis the triangle (b - |t|)/b^2: every term carries .box = b
 * and is evaluated exactly (ccm_axis; docs/ccm.md, "Pixel integration"). */
void ccm_frame_init(ccm_frame *f, const rpiv_ccm_model *m)
{
    f->m = m;
    f->pixel_m = rpiv_camera_pixel_m(&m->camera);
    double pk, var, fa, d1, d2;
    /* the reference particle: in focus (z = z*_OP), I0 = 1, d_p of the model; its term's
     * peak value, the pixels' triangle included */
    image_of(f, m->camera.zop_star, 1.0, m->dp_m, &pk, &var);
    ccm_axis(0, 1 / (4 * var), m->pixel_box, &fa, &d1, &d2);
    f->ref = pk * pk * M_PI * var * fa * fa;
    f->pnorm = 1;
}

/* The correlation of two Gaussian images P1 exp(-r^2/(2 s1^2)) and P2 exp(-|r-D|^2/(2 s2^2)):
 * P1 P2 2 pi s1^2 s2^2 / (s1^2 + s2^2) exp(-|D - d|^2 / (2 (s1^2 + s2^2))). */
rpiv_ccm_gauss ccm_term(const ccm_frame *f, double z1, double z2, double i1, double i2, double dp1,
                        double dp2, double ddx, double ddy)
{
    double p1, v1, p2, v2;
    image_of(f, z1, i1, dp1, &p1, &v1);
    image_of(f, z2, i2, dp2, &p2, &v2);
    double vs = v1 + v2;
    return (rpiv_ccm_gauss){.amp = p1 * p2 * 2 * M_PI * v1 * v2 / vs / f->ref,
                            .c = 1 / (2 * vs),
                            .dx = ddx,
                            .dy = ddy,
                            .box = f->m->pixel_box};
}

rpiv_ccm_gauss ccm_amp_term(const ccm_frame *f, double z)
{
    const rpiv_ccm_model *m = f->m;
    double i0 = m->illum.fn(m->illum.user, z);
    double p, v;
    image_of(f, z, i0 > 0 ? i0 : 0, m->dp_m, &p, &v);
    return (rpiv_ccm_gauss){
        .amp = p * p * M_PI * v / f->ref, .c = 1 / (4 * v), .dx = 0, .dy = 0, .box = m->pixel_box};
}

rpiv_ccm_gauss ccm_simp_term(const ccm_frame *f, double z)
{
    const rpiv_ccm_model *m = f->m;
    rpiv_ccm_gauss g = ccm_amp_term(f, z);
    g.dx = m->u.fn(m->u.user, z) * m->scale_px;
    g.dy = m->v.fn ? m->v.fn(m->v.user, z) * m->scale_px : 0;
    return g;
}

double ccm_presence(const rpiv_ccm_model *m, double z)
{
    return m->presence.fn ? m->presence.fn(m->presence.user, z) : 1.0;
}

rpiv_status rpiv_ccm_gen(const rpiv_ccm_model *m, const rpiv_ccm_particle *pt, size_t n,
                         rpiv_ccm_corr *out)
{
    rpiv_status st = rpiv_camera_check(&m->camera);
    if (st)
        return st;
    if (!(m->h_m > 0) || !(m->dp_m > 0))
        return rpiv_fail(RPIV_EINVAL, "ccm: channel height and particle diameter must be > 0");
    ccm_frame f;
    ccm_frame_init(&f, m);
    for (size_t i = 0; i < n; i++) {
        const rpiv_ccm_particle *q = &pt[i];
        if (!(q->i1 >= 0 && q->i2 >= 0) || !(q->dp_m > 0) || !isfinite(q->z1) || !isfinite(q->z2) ||
            !isfinite(q->dx) || !isfinite(q->dy))
            return rpiv_fail(RPIV_EINVAL,
                             "ccm: particle %zu: intensities must be >= 0, the diameter > 0 "
                             "and positions finite",
                             i);
        st = rpiv_ccm_corr_add(
            out, ccm_term(&f, q->z1, q->z2, q->i1, q->i2, q->dp_m, q->dp_m, q->dx, q->dy));
        if (st)
            return st;
    }
    return RPIV_OK;
}

rpiv_status rpiv_ccm_simp(const rpiv_ccm_model *m, const double *z, size_t n, double weight,
                          rpiv_ccm_corr *out)
{
    rpiv_status st = rpiv_ccm_model_check(m);
    if (st)
        return st;
    ccm_frame f;
    ccm_frame_init(&f, m);
    for (size_t i = 0; i < n; i++) {
        rpiv_ccm_gauss g = ccm_simp_term(&f, z[i]);
        g.amp *= weight;
        if ((st = rpiv_ccm_corr_add(out, g)))
            return st;
    }
    return RPIV_OK;
}
