/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Calibration: depth of focus and object plane from a dotted target on an inclined plate
 * (paper, "Depth of focus"), and the imaging model's prediction of the same curve.
 * The reasoning behind each step is in docs/calib.md. */
#include "calib_impl.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_filter.h>
#include <gsl/gsl_fit.h>
#include <gsl/gsl_integration.h>
#include <gsl/gsl_multifit.h>
#include <gsl/gsl_vector.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

rpiv_calib_dof_params rpiv_calib_dof_params_default(void)
{
    return (rpiv_calib_dof_params){.geom = rpiv_calib_geom_default(),
                                   .dot_d_m = 62.5e-6,
                                   .pitch_m = 125e-6,
                                   .min_contrast = 0.03,
                                   .min_snr = 1,
                                   .smooth_px = 0.7,
                                   .lattice_tol = 0.25,
                                   .ref_cells = 2,
                                   .fit_columns = 4};
}

rpiv_status rpiv_calib_dof_params_check(const rpiv_calib_dof_params *p)
{
    rpiv_status st = rpiv_calib_geom_check(&p->geom);
    if (st)
        return st;
    if (!(p->dot_d_m > 0 && p->dot_d_m < 0.1))
        return rpiv_fail(RPIV_EINVAL, "calib dof: dot diameter %g m outside (0, 0.1)", p->dot_d_m);
    if (!(p->pitch_m > p->dot_d_m && p->pitch_m < 0.1))
        return rpiv_fail(RPIV_EINVAL,
                         "calib dof: dot pitch %g m must exceed the dot diameter %g m (and be "
                         "< 0.1 m)",
                         p->pitch_m, p->dot_d_m);
    if (!(p->min_contrast > 0 && p->min_contrast < 1))
        return rpiv_fail(RPIV_EINVAL, "calib dof: minimum contrast %g outside (0, 1)",
                         p->min_contrast);
    if (!(p->min_snr >= 0 && p->min_snr <= 100))
        return rpiv_fail(RPIV_EINVAL, "calib dof: minimum significance %g outside 0..100",
                         p->min_snr);
    if (!(p->smooth_px >= 0 && p->smooth_px <= 10))
        return rpiv_fail(RPIV_EINVAL, "calib dof: smoothing %g px outside 0..10", p->smooth_px);
    if (!(p->lattice_tol > 0 && p->lattice_tol <= 0.5))
        return rpiv_fail(RPIV_EINVAL, "calib dof: lattice tolerance %g outside (0, 0.5]",
                         p->lattice_tol);
    if (p->ref_cells < 1 || p->ref_cells > 20)
        return rpiv_fail(RPIV_EINVAL, "calib dof: reference cells %d outside 1..20", p->ref_cells);
    if (p->fit_columns < 0 || p->fit_columns > 50)
        return rpiv_fail(RPIV_EINVAL, "calib dof: fit half-window %d columns outside 0..50",
                         p->fit_columns);
    return RPIV_OK;
}

void rpiv_calib_dof_result_free(rpiv_calib_dof_result *r)
{
    if (!r)
        return;
    free(r->foot_px);
    free(r->angle_deg);
    free(r->dark);
    free(r->dot);
    rpiv_calib_focus_free(&r->curve);
    free(r);
}

/* ---- model ------------------------------------------------------------------------------- */

/* Nodes per axis of the average over the dot centre's position in its pixel. */
#define PHASE_NODES 4

static rpiv_status phase_nodes(double *node, double *wt)
{
    gsl_integration_glfixed_table *t = gsl_integration_glfixed_table_alloc(PHASE_NODES);
    if (!t)
        return rpiv_fail(RPIV_ENOMEM, "calib dof model: out of memory");
    for (size_t i = 0; i < PHASE_NODES; i++)
        gsl_integration_glfixed_point(-0.5, 0.5, i, &node[i], &wt[i], t);
    gsl_integration_glfixed_table_free(t);
    return RPIV_OK;
}

rpiv_status rpiv_calib_dof_model(const rpiv_calib_dof_params *p, const rpiv_camera *cam, double h_m,
                                 double reflectance, double zstep, rpiv_calib_focus *c)
{
    memset(c, 0, sizeof *c);
    rpiv_status st = rpiv_calib_dof_params_check(p);
    if (st || (st = rpiv_camera_check(cam)))
        return st;
    if (p->geom.angle_deg == 0)
        return rpiv_fail(RPIV_EINVAL, "calib dof model: the plate angle must be given");
    if (!(reflectance >= 0 && reflectance < 1))
        return rpiv_fail(RPIV_EINVAL, "calib dof model: dot reflectance %g outside 0..1",
                         reflectance);
    if (!(zstep >= 1e-4 && zstep <= 0.1))
        return rpiv_fail(RPIV_EINVAL, "calib dof model: z* step %g outside 1e-4..0.1", zstep);
    if (!(h_m > 0))
        return rpiv_fail(RPIV_EINVAL, "calib dof model: channel height %g m must be > 0", h_m);
    calib_gl gl;
    double node[PHASE_NODES], wt[PHASE_NODES];
    if ((st = calib_gl_init(&gl)) || (st = phase_nodes(node, wt)))
        return st;
    double scale = calib_scale(p->geom.scale_px_m, cam);
    double ca = fabs(cos(p->geom.angle_deg * M_PI / 180));
    double r = 0.5 * p->dot_d_m * scale, ax = r * ca, ay = r;
    double ppx = p->pitch_m * ca * scale, ppy = p->pitch_m * scale;
    double fill = M_PI * ax * ay / (ppx * ppy);
    size_t half = (size_t)lround(1 / zstep), n = 2 * half + 1;
    if ((st = calib_focus_alloc(c, n, 0)))
        return st;
    for (size_t i = 0; i < n; i++) {
        double z = cam->zop_star + ((double)i - (double)half) * zstep;
        double s = calib_blur_px(cam, h_m, scale, z);
        /* the measure reads the pixel nearest the dot centre, which falls anywhere in it */
        double dk = calib_lattice_pixel(&gl, ax, ay, ppx, ppy, s, node, wt, PHASE_NODES);
        c->z[i] = z;
        c->istar[i] = (1 - (1 - reflectance) * dk) / (1 - (1 - reflectance) * fill);
    }
    if ((st = calib_focus_analyse(c, 0, "calib dof model")))
        rpiv_calib_focus_free(c);
    return st;
}

rpiv_status rpiv_calib_dof_reflectance(const rpiv_calib_dof_params *p, const rpiv_camera *cam,
                                       double h_m, double inv_max, double *reflectance)
{
    rpiv_status st = rpiv_calib_dof_params_check(p);
    if (st || (st = rpiv_camera_check(cam)))
        return st;
    if (p->geom.angle_deg == 0)
        return rpiv_fail(RPIV_EINVAL, "calib dof model: the plate angle must be given");
    if (!(h_m > 0) || !(inv_max > 1))
        return rpiv_fail(RPIV_EINVAL, "calib dof model: need h > 0 and a peak 1/I* > 1 (%g)",
                         inv_max);
    calib_gl gl;
    double node[PHASE_NODES], wt[PHASE_NODES];
    if ((st = calib_gl_init(&gl)) || (st = phase_nodes(node, wt)))
        return st;
    double scale = calib_scale(p->geom.scale_px_m, cam);
    double ca = fabs(cos(p->geom.angle_deg * M_PI / 180));
    double r = 0.5 * p->dot_d_m * scale, ax = r * ca, ay = r;
    double ppx = p->pitch_m * ca * scale, ppy = p->pitch_m * scale;
    double fill = M_PI * ax * ay / (ppx * ppy);
    double s = calib_blur_px(cam, h_m, scale, cam->zop_star);
    double c0 = calib_lattice_pixel(&gl, ax, ay, ppx, ppy, s, node, wt, PHASE_NODES);
    /* I* = (1 - (1 - rho) c0) / (1 - (1 - rho) fill), solved for rho */
    double i = 1 / inv_max, q = (1 - i) / (c0 - i * fill), rho = 1 - q;
    if (!(c0 - i * fill > 0) || !(rho >= 0 && rho < 1))
        return rpiv_fail(RPIV_ENUMERIC,
                         "calib dof model: no dot reflectance in [0, 1) gives a peak 1/I* of %g "
                         "(a black dot gives %g)",
                         inv_max, (1 - fill) / (1 - c0));
    *reflectance = rho;
    return RPIV_OK;
}

/* ---- measurement ------------------------------------------------------------------------- */

/* Dark-subtracted copy of the image, and its lightly smoothed copy for detection. */
typedef struct dof_img {
    int w, h;
    double *d, *s;
} dof_img;

/* Width of the smoothing kernel: +- 4 sigma. */
static size_t kernel_size(double sigma)
{
    return 2 * (size_t)ceil(4 * sigma) + 1;
}

static rpiv_status gauss2d(double *img, int w, int h, double sigma, const char *what)
{
    if (!(sigma > 0))
        return RPIV_OK;
    size_t k = kernel_size(sigma), nmax = (size_t)(w > h ? w : h);
    gsl_filter_gaussian_workspace *ws = gsl_filter_gaussian_alloc(k);
    gsl_vector *in = gsl_vector_alloc(nmax), *out = gsl_vector_alloc(nmax);
    rpiv_status st = RPIV_OK;
    if (!ws || !in || !out) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
        goto out_free;
    }
    double alpha = (double)(k - 1) / (2 * sigma);
    for (int pass = 0; pass < 2 && !st; pass++) {
        int nline = pass ? w : h, len = pass ? h : w;
        gsl_vector_view vi = gsl_vector_subvector(in, 0, (size_t)len);
        gsl_vector_view vo = gsl_vector_subvector(out, 0, (size_t)len);
        for (int l = 0; l < nline; l++) {
            for (int i = 0; i < len; i++)
                gsl_vector_set(&vi.vector, (size_t)i,
                               pass ? img[(size_t)i * w + l] : img[(size_t)l * w + i]);
            if (len < (int)k) { /* too short to filter: leave the line */
                continue;
            }
            if (gsl_filter_gaussian(GSL_FILTER_END_PADVALUE, alpha, 0, &vi.vector, &vo.vector,
                                    ws)) {
                st = rpiv_fail(RPIV_ENUMERIC, "%s: smoothing failed", what);
                break;
            }
            for (int i = 0; i < len; i++) {
                double v = gsl_vector_get(&vo.vector, (size_t)i);
                if (pass)
                    img[(size_t)i * w + l] = v;
                else
                    img[(size_t)l * w + i] = v;
            }
        }
    }
out_free:
    gsl_vector_free(in);
    gsl_vector_free(out);
    gsl_filter_gaussian_free(ws);
    return st;
}

/* Length of [a, b] inside pixel i ([i - 1/2, i + 1/2]). */
static double overlap(int i, double a, double b)
{
    double lo = fmax(a, i - 0.5), hi = fmin(b, i + 0.5);
    return hi > lo ? hi - lo : 0;
}

/* Mean grey over the box of lx x ly px centred at (cx, cy), with fractional edge pixels, so that
 * it spans whole lattice cells exactly; shifted to stay inside rows [r0, r1) and the columns.
 * NAN if the image is too small. With sd, also the (weighted) standard deviation in the box. */
static double box_mean(const dof_img *im, int r0, int r1, double cx, double cy, double lx,
                       double ly, double *sd)
{
    double x0 = cx - lx / 2, y0 = cy - ly / 2;
    if (lx > im->w || ly > r1 - r0)
        return (double)NAN;
    x0 = fmin(fmax(x0, -0.5), im->w - 0.5 - lx);
    y0 = fmin(fmax(y0, r0 - 0.5), r1 - 0.5 - ly);
    int i0 = (int)floor(x0 + 0.5), i1 = (int)ceil(x0 + lx - 0.5);
    int j0 = (int)floor(y0 + 0.5), j1 = (int)ceil(y0 + ly - 0.5);
    double sum = 0, sum2 = 0;
    for (int j = j0; j <= j1; j++) {
        if (j < r0 || j >= r1)
            continue;
        double wy = overlap(j, y0, y0 + ly), row = 0, row2 = 0;
        if (wy <= 0)
            continue;
        for (int i = i0; i <= i1; i++)
            if (i >= 0 && i < im->w) {
                double v = im->d[(size_t)j * im->w + i], wx = overlap(i, x0, x0 + lx);
                row += wx * v;
                row2 += wx * v * v;
            }
        sum += wy * row;
        sum2 += wy * row2;
    }
    double mean = sum / (lx * ly);
    if (sd)
        *sd = sqrt(fmax(0, sum2 / (lx * ly) - mean * mean));
    return mean;
}

typedef struct cand {
    int x, y;
    double v;
} cand;

static int cand_cmp(const void *a, const void *b)
{
    const cand *p = a, *q = b;
    if (p->v != q->v)
        return p->v < q->v ? -1 : 1;
    if (p->y != q->y)
        return p->y < q->y ? -1 : 1;
    return (p->x > q->x) - (p->x < q->x);
}

/* Offset of the vertex of the parabola through (-1, a), (0, b), (1, c), b a minimum (0 if not,
 * or if the vertex is more than half a pixel away). */
static void vertex3(double a, double b, double c, double *off)
{
    double den = a - 2 * b + c;
    *off = 0;
    if (den > 0) {
        double o = 0.5 * (a - c) / den;
        if (fabs(o) <= 0.5)
            *off = o;
    }
}

/* Detect and measure the dots of one shot; appends to *dots (capacity *cap). */
static rpiv_status dof_shot(const rpiv_calib_dof_params *p, const rpiv_camera *cam,
                            const rpiv_channel *ch, const rpiv_calib_shot *shot, size_t ishot,
                            const rpiv_image *dark, rpiv_calib_dof_result *r, size_t *cap)
{
    char what[32];
    snprintf(what, sizeof what, "image %zu", ishot + 1);
    const rpiv_image *im = shot->image;
    calib_frame fr;
    calib_place pl;
    dof_img di = {im->w, im->h, NULL, NULL};
    cand *cs = NULL;
    long *head = NULL, *next = NULL;
    double *prof = NULL;
    rpiv_status st = calib_frame_init(&p->geom, im, dark, what, &fr);
    if (st)
        return st;
    size_t npx = (size_t)im->w * im->h;
    di.d = malloc(npx * sizeof *di.d);
    di.s = malloc(npx * sizeof *di.s);
    prof = malloc((size_t)im->w * sizeof *prof);
    if (!di.d || !di.s || !prof) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
        goto out_free;
    }
    double lo = HUGE_VAL, hi = -HUGE_VAL;
    for (int y = 0; y < im->h; y++)
        for (int x = 0; x < im->w; x++) {
            double v = calib_frame_at(&fr, x, y);
            di.d[(size_t)y * im->w + x] = v;
            lo = fmin(lo, v);
            hi = fmax(hi, v);
        }
    if (!(hi - lo > 1e-6 * fmax(1.0, fabs(hi)))) {
        st = rpiv_fail(RPIV_ENUMERIC, "%s: blank image (no signal)", what);
        goto out_free;
    }
    calib_frame_profile(&fr, prof);
    if ((st = calib_place_init(&p->geom, cam, ch, shot, prof, im->w, what, &pl)))
        goto out_free;
    r->foot_px[ishot] = pl.foot;
    r->angle_deg[ishot] = pl.angle_deg;
    r->dark[ishot] = fr.dark ? (double)NAN : fr.dark_level;
    double ca = fabs(cos(pl.angle_deg * M_PI / 180));
    double ppx = p->pitch_m * ca * pl.scale, ppy = p->pitch_m * pl.scale;
    if (ppx < 3 || ppy < 3) {
        st = rpiv_fail(RPIV_ENUMERIC,
                       "%s: the dot pitch is %.2f x %.2f px in the image: at least 3 px needed "
                       "to resolve the dots",
                       what, ppx, ppy);
        goto out_free;
    }
    memcpy(di.s, di.d, npx * sizeof *di.s);
    if ((st = gauss2d(di.s, im->w, im->h, p->smooth_px, what)))
        goto out_free;
    double hp = p->geom.plate_height_m > 0 ? p->geom.plate_height_m : ch->h_m;
    double zcap = fmin(1.0, hp / ch->h_m);
    double lx = p->ref_cells * ppx, ly = p->ref_cells * ppy;
    /* candidates: strict local minima (3x3) of the smoothed image, darker than the local mean */
    size_t nc = 0, ccap = 256;
    cs = malloc(ccap * sizeof *cs);
    if (!cs) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
        goto out_free;
    }
    int w = im->w;
    for (int y = fr.row0 + 1; y < fr.row1 - 1; y++)
        for (int x = 1; x < w - 1; x++) {
            double v = di.s[(size_t)y * w + x];
            int ismin = 1;
            for (int dy = -1; dy <= 1 && ismin; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    if (!dx && !dy)
                        continue;
                    double u = di.s[(size_t)(y + dy) * w + x + dx];
                    /* ties go to the first pixel in raster order */
                    if (u < v || (u == v && (dy < 0 || (dy == 0 && dx < 0)))) {
                        ismin = 0;
                        break;
                    }
                }
            if (!ismin)
                continue;
            double z = (x - pl.foot) * pl.k;
            if (z < 0 || z > zcap)
                continue;
            double sd, ref = box_mean(&di, fr.row0, fr.row1, x, y, lx, ly, &sd);
            if (!(ref > 0) || !(v < (1 - p->min_contrast) * ref) || !(ref - v > p->min_snr * sd))
                continue;
            if (nc == ccap) {
                cand *t = realloc(cs, 2 * ccap * sizeof *cs);
                if (!t) {
                    st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
                    goto out_free;
                }
                cs = t;
                ccap *= 2;
            }
            cs[nc++] = (cand){x, y, v};
        }
    /* one dot per lattice cell: darkest first, nothing else within half a pitch; the accepted
     * ones are indexed in a grid of cells one pitch wide, so each test looks at a few cells */
    qsort(cs, nc, sizeof *cs, cand_cmp);
    int gx = (int)(w / ppx) + 1, gy = (int)(im->h / ppy) + 1;
    head = malloc((size_t)gx * gy * sizeof *head);
    next = malloc((nc ? nc : 1) * sizeof *next);
    if (!head || !next) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
        goto out_free;
    }
    for (long c = 0; c < (long)gx * gy; c++)
        head[c] = -1;
    size_t na = 0;
    for (size_t i = 0; i < nc; i++) {
        int cx = (int)(cs[i].x / ppx), cy = (int)(cs[i].y / ppy), keep = 1;
        for (int by = cy - 1; by <= cy + 1 && keep; by++)
            for (int bx = cx - 1; bx <= cx + 1 && keep; bx++) {
                if (bx < 0 || by < 0 || bx >= gx || by >= gy)
                    continue;
                for (long j = head[(long)by * gx + bx]; j >= 0 && keep; j = next[j]) {
                    double dx = (cs[i].x - cs[j].x) / (0.5 * ppx),
                           dy = (cs[i].y - cs[j].y) / (0.5 * ppy);
                    if (dx * dx + dy * dy < 1)
                        keep = 0;
                }
            }
        if (!keep)
            continue;
        cs[na] = cs[i];
        next[na] = head[(long)cy * gx + cx];
        head[(long)cy * gx + cx] = (long)na;
        na++;
    }
    /* lattice check: a real dot has a neighbour one pitch away along x or y */
    size_t first = r->ndots;
    for (size_t i = 0; i < na; i++) {
        int nb = 0, bcx = (int)(cs[i].x / ppx), bcy = (int)(cs[i].y / ppy);
        for (int by = bcy - 2; by <= bcy + 2 && !nb; by++)
            for (int bx = bcx - 2; bx <= bcx + 2 && !nb; bx++) {
                if (bx < 0 || by < 0 || bx >= gx || by >= gy)
                    continue;
                for (long j = head[(long)by * gx + bx]; j >= 0 && !nb; j = next[j]) {
                    double dx = fabs((double)(cs[j].x - cs[i].x)),
                           dy = fabs((double)(cs[j].y - cs[i].y));
                    if ((fabs(dx - ppx) < p->lattice_tol * ppx && dy < p->lattice_tol * ppy) ||
                        (fabs(dy - ppy) < p->lattice_tol * ppy && dx < p->lattice_tol * ppx))
                        nb = 1;
                }
            }
        if (!nb)
            continue;
        /* the centre grey: the unsmoothed pixel at the minimum of the smoothed image, i.e.
         * the pixel nearest the dot centre (no selection of the darkest of several noisy pixels,
         * no extrapolation below a flat in-focus bottom, no smoothing in the measure); the
         * sub-pixel centre, for z*, from a parabola through the smoothed image */
        int x = cs[i].x, y = cs[i].y;
        const double *sm = di.s;
        double ox, oy, b = sm[(size_t)y * w + x];
        vertex3(sm[(size_t)y * w + x - 1], b, sm[(size_t)y * w + x + 1], &ox);
        vertex3(sm[(size_t)(y - 1) * w + x], b, sm[(size_t)(y + 1) * w + x], &oy);
        double grey = di.d[(size_t)y * w + x];
        double cx = x + ox, cy = y + oy;
        double ref = box_mean(&di, fr.row0, fr.row1, cx, cy, lx, ly, NULL);
        if (!(ref > 0) || !(grey > 0))
            continue;
        if (r->ndots == *cap) {
            size_t nc2 = *cap ? 2 * *cap : 512;
            rpiv_calib_dot *t = realloc(r->dot, nc2 * sizeof *t);
            if (!t) {
                st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
                goto out_free;
            }
            r->dot = t;
            *cap = nc2;
        }
        r->dot[r->ndots++] = (rpiv_calib_dot){.shot = ishot,
                                              .x = cx,
                                              .y = cy,
                                              .zstar = (cx - pl.foot) * pl.k,
                                              .grey = grey,
                                              .ref = ref,
                                              .istar = grey / ref};
    }
    if (r->ndots == first)
        st = rpiv_fail(RPIV_ENUMERIC,
                       "%s: no dots found (pitch %.2f x %.2f px, minimum contrast %g)", what, ppx,
                       ppy, p->min_contrast);
out_free:
    free(cs);
    free(head);
    free(next);
    free(prof);
    free(di.d);
    free(di.s);
    return st;
}

static int dot_cmp(const void *a, const void *b)
{
    const rpiv_calib_dot *p = a, *q = b;
    if (p->zstar != q->zstar)
        return p->zstar < q->zstar ? -1 : 1;
    if (p->shot != q->shot)
        return p->shot < q->shot ? -1 : 1;
    return (p->y > q->y) - (p->y < q->y);
}

/* Average the dots along the span: bins one dot column wide in z* (pitch sin(angle) / h),
 * placed by the mean phase of the dots so that a column falls in the middle of its bin. */
static rpiv_status dof_columns(const rpiv_calib_dof_params *p, const rpiv_channel *ch,
                               rpiv_calib_dof_result *r)
{
    size_t n = r->ndots;
    double dz = p->pitch_m * fabs(sin(r->angle_deg[0] * M_PI / 180)) / ch->h_m;
    qsort(r->dot, n, sizeof *r->dot, dot_cmp);
    double sc = 0, ss = 0;
    for (size_t i = 0; i < n; i++) {
        double ph = 2 * M_PI * r->dot[i].zstar / dz;
        sc += cos(ph);
        ss += sin(ph);
    }
    double z0 = atan2(ss, sc) / (2 * M_PI) * dz; /* a column centre */
    long b0 = lround((r->dot[0].zstar - z0) / dz), b1 = lround((r->dot[n - 1].zstar - z0) / dz);
    size_t nb = (size_t)(b1 - b0 + 1), m = 0;
    double *zs = calloc(nb, sizeof *zs), *is = calloc(nb, sizeof *is);
    size_t *cnt = calloc(nb, sizeof *cnt);
    rpiv_status st = RPIV_OK;
    if (!zs || !is || !cnt) {
        st = rpiv_fail(RPIV_ENOMEM, "calib dof: out of memory");
        goto out_free;
    }
    for (size_t i = 0; i < n; i++) {
        size_t b = (size_t)(lround((r->dot[i].zstar - z0) / dz) - b0);
        zs[b] += r->dot[i].zstar;
        is[b] += r->dot[i].istar;
        cnt[b]++;
    }
    for (size_t b = 0; b < nb; b++)
        m += cnt[b] > 0;
    if (m < 5) {
        st = rpiv_fail(RPIV_ENUMERIC,
                       "calib dof: only %zu columns of dots found (at least 5 needed)", m);
        goto out_free;
    }
    if ((st = calib_focus_alloc(&r->curve, m, 1)))
        goto out_free;
    m = 0;
    for (size_t b = 0; b < nb; b++)
        if (cnt[b]) {
            r->curve.z[m] = zs[b] / (double)cnt[b];
            r->curve.istar[m] = is[b] / (double)cnt[b];
            r->curve.count[m] = cnt[b];
            m++;
        }
    st = calib_focus_analyse(&r->curve, p->fit_columns, "calib dof");
out_free:
    free(zs);
    free(is);
    free(cnt);
    return st;
}

rpiv_status rpiv_calib_dof_run(const rpiv_calib_dof_params *p, const rpiv_camera *cam,
                               const rpiv_channel *ch, const rpiv_calib_shot *shots, size_t nshots,
                               const rpiv_image *dark, rpiv_calib_dof_result **out)
{
    *out = NULL;
    rpiv_status st = rpiv_calib_dof_params_check(p);
    if (st || (st = rpiv_camera_check(cam)) || (st = rpiv_channel_check(ch)))
        return st;
    if (nshots == 0)
        return rpiv_fail(RPIV_EINVAL, "calib dof: no image given");
    rpiv_calib_dof_result *r = calloc(1, sizeof *r);
    if (!r)
        return rpiv_fail(RPIV_ENOMEM, "calib dof: out of memory");
    r->nshots = nshots;
    r->foot_px = calloc(nshots, sizeof *r->foot_px);
    r->angle_deg = calloc(nshots, sizeof *r->angle_deg);
    r->dark = calloc(nshots, sizeof *r->dark);
    if (!r->foot_px || !r->angle_deg || !r->dark) {
        st = rpiv_fail(RPIV_ENOMEM, "calib dof: out of memory");
        goto out_fail;
    }
    size_t cap = 0;
    for (size_t i = 0; i < nshots; i++)
        if ((st = dof_shot(p, cam, ch, &shots[i], i, dark, r, &cap)))
            goto out_fail;
    if ((st = dof_columns(p, ch, r)))
        goto out_fail;
    *out = r;
    return RPIV_OK;
out_fail:
    rpiv_calib_dof_result_free(r);
    return st;
}

rpiv_status rpiv_calib_dof_write_dots(const rpiv_calib_dof_result *r, FILE *fp)
{
    fprintf(fp, "# rpiv calib dof: detected dots (grey and ref above dark)\n"
                "# image x_px y_px zstar grey ref Istar\n");
    for (size_t i = 0; i < r->ndots; i++) {
        const rpiv_calib_dot *d = &r->dot[i];
        fprintf(fp, "%zu %.3f %.3f %.6f %.4f %.4f %.6f\n", d->shot + 1, d->x, d->y, d->zstar,
                d->grey, d->ref, d->istar);
    }
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "calib dof: write error");
    return RPIV_OK;
}
