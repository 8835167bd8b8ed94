/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Calibration: the light-sheet profile from a fluorescent inclined plate (paper, "Measurement
 * of the laser sheet intensity after the refraction"). The reasoning behind each step is in
 * docs/calib.md. */
#include "calib_impl.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_filter.h>
#include <gsl/gsl_fit.h>
#include <gsl/gsl_integration.h>
#include <gsl/gsl_interp.h>
#include <gsl/gsl_sort_double.h>
#include <gsl/gsl_statistics_double.h>
#include <gsl/gsl_vector.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ---- sheet ---------------------------------------------------------------------------------- */

rpiv_calib_sheet_params rpiv_calib_sheet_params_default(void)
{
    return (rpiv_calib_sheet_params){.geom = rpiv_calib_geom_default(),
                                     .smooth_px = 0,
                                     .subtract_floor = 1,
                                     .margin = 0.03,
                                     .min_signal = 0.1,
                                     .zplus_step = 0.01,
                                     .zplus_max = 3};
}

rpiv_status rpiv_calib_sheet_params_check(const rpiv_calib_sheet_params *p)
{
    rpiv_status st = rpiv_calib_geom_check(&p->geom);
    if (st)
        return st;
    if (!(p->smooth_px >= 0 && p->smooth_px <= 100))
        return rpiv_fail(RPIV_EINVAL, "calib sheet: smoothing %g px outside 0..100", p->smooth_px);
    if (!(p->min_signal >= 0 && p->min_signal < 1e6))
        return rpiv_fail(RPIV_EINVAL, "calib sheet: minimum signal %g must be >= 0", p->min_signal);
    if (!(p->margin >= 0 && p->margin < 0.4))
        return rpiv_fail(RPIV_EINVAL, "calib sheet: margin %g outside 0..0.4", p->margin);
    if (!(p->zplus_step >= 1e-4 && p->zplus_step <= 0.5))
        return rpiv_fail(RPIV_EINVAL, "calib sheet: z+ step %g outside 1e-4..0.5", p->zplus_step);
    if (!(p->zplus_max >= 0.5 && p->zplus_max <= 100 && p->zplus_max / p->zplus_step < 1e6))
        return rpiv_fail(RPIV_EINVAL,
                         "calib sheet: z+ range %g outside 0.5..100 (or too many "
                         "rows for the step)",
                         p->zplus_max);
    return RPIV_OK;
}

void rpiv_calib_sheet_result_free(rpiv_calib_sheet_result *r)
{
    if (!r)
        return;
    for (size_t i = 0; i < r->nplates; i++) {
        free(r->plate[i].z);
        free(r->plate[i].x);
        free(r->plate[i].inten);
    }
    free(r->plate);
    free(r->zplus);
    free(r->shape);
    free(r);
}

/* Gaussian smoothing with GSL; sigma in samples. */
static rpiv_status smooth(double *p, int n, double sigma, const char *what)
{
    size_t k = 2 * (size_t)ceil(4 * sigma) + 1;
    if (k > (size_t)n)
        k = (size_t)n | 1;
    gsl_filter_gaussian_workspace *ws = gsl_filter_gaussian_alloc(k);
    gsl_vector *in = gsl_vector_alloc((size_t)n), *out = gsl_vector_alloc((size_t)n);
    rpiv_status st = RPIV_OK;
    if (!ws || !in || !out) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
        goto out_free;
    }
    for (int i = 0; i < n; i++)
        gsl_vector_set(in, (size_t)i, p[i]);
    /* GSL's kernel is exp(-(alpha k / ((K-1)/2))^2 / 2): sigma = (K-1) / (2 alpha) */
    if (gsl_filter_gaussian(GSL_FILTER_END_PADVALUE, (double)(k - 1) / (2 * sigma), 0, in, out,
                            ws)) {
        st = rpiv_fail(RPIV_ENUMERIC, "%s: smoothing failed", what);
        goto out_free;
    }
    for (int i = 0; i < n; i++)
        p[i] = gsl_vector_get(out, (size_t)i);
out_free:
    gsl_vector_free(in);
    gsl_vector_free(out);
    gsl_filter_gaussian_free(ws);
    return st;
}

/* Is the image flat (no signal)? */
static int image_blank(const rpiv_image *im)
{
    float lo = im->px[0], hi = im->px[0];
    size_t n = (size_t)im->w * im->h;
    for (size_t i = 1; i < n; i++) {
        lo = fminf(lo, im->px[i]);
        hi = fmaxf(hi, im->px[i]);
    }
    return !((double)hi - (double)lo > 1e-6 * fmax(1.0, fabs((double)hi)));
}

/* One plate: profile, mapping to z*, normalisation, raw metrics. */
static rpiv_status sheet_plate(const rpiv_calib_sheet_params *p, const rpiv_camera *cam,
                               const rpiv_channel *ch, const rpiv_calib_shot *shot,
                               const rpiv_image *dark, const char *what, rpiv_calib_sheet_plate *pl)
{
    const rpiv_image *im = shot->image;
    calib_frame fr;
    calib_place place;
    rpiv_status st = calib_frame_init(&p->geom, im, dark, what, &fr);
    if (st)
        return st;
    if (image_blank(im))
        return rpiv_fail(RPIV_ENUMERIC, "%s: blank image (no signal)", what);
    double *prof = malloc((size_t)im->w * sizeof *prof);
    if (!prof)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
    calib_frame_profile(&fr, prof);
    double noise;
    if ((st = calib_frame_noise(&fr, &noise)))
        goto out_free;
    if (p->smooth_px > 0 && (st = smooth(prof, im->w, p->smooth_px, what)))
        goto out_free;
    if ((st = calib_place_init(&p->geom, cam, ch, shot, prof, im->w, what, &place)))
        goto out_free;
    pl->foot_px = place.foot;
    pl->angle_deg = place.angle_deg;
    pl->x_foot = place.x_foot;
    pl->dark = fr.dark ? (double)NAN : fr.dark_level;
    double hp = p->geom.plate_height_m > 0 ? p->geom.plate_height_m : ch->h_m;
    double zcap = fmin(1.0, hp / ch->h_m), tana = tan(place.angle_deg * M_PI / 180);
    /* samples in z* order: columns X with 0 <= z* <= zcap */
    size_t n = 0;
    pl->z = malloc((size_t)im->w * sizeof *pl->z);
    pl->x = malloc((size_t)im->w * sizeof *pl->x);
    pl->inten = malloc((size_t)im->w * sizeof *pl->inten);
    if (!pl->z || !pl->x || !pl->inten) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
        goto out_free;
    }
    for (int i = 0; i < im->w; i++) {
        int X = place.k > 0 ? i : im->w - 1 - i;
        double z = (X - place.foot) * place.k;
        if (z < p->margin || z > zcap - p->margin)
            continue;
        pl->z[n] = z;
        pl->x[n] = place.x_foot + z / tana;
        pl->inten[n] = prof[X];
        n++;
    }
    pl->n = n;
    if (n < 8) {
        st = rpiv_fail(RPIV_ENUMERIC,
                       "%s: the plate covers %zu columns inside the channel (foot %.1f px, "
                       "angle %g deg): at least 8 needed",
                       what, n, place.foot, place.angle_deg);
        goto out_free;
    }
    pl->floor = 0;
    if (p->subtract_floor) {
        double fl = HUGE_VAL;
        for (size_t i = 0; i < n; i++)
            fl = fmin(fl, pl->inten[i]);
        pl->floor = isfinite(fl) ? fl : 0;
    }
    double peak = -HUGE_VAL;
    for (size_t i = 0; i < n; i++) {
        pl->inten[i] -= pl->floor;
        peak = fmax(peak, pl->inten[i]);
    }
    pl->peak = peak;
    if (!(peak > p->min_signal * fabs(pl->floor) && peak > 10 * noise && peak > 1e-9)) {
        st = rpiv_fail(RPIV_ENUMERIC,
                       "%s: no sheet on the plate (peak %.3g above the floor %.3g, noise %.3g of "
                       "the span average)",
                       what, peak, pl->floor, noise);
        goto out_free;
    }
    for (size_t i = 0; i < n; i++)
        pl->inten[i] /= peak;
    if ((st = rpiv_sheet_metrics_of(pl->z, pl->inten, n, &pl->raw))) {
        char msg[256];
        snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
        st = rpiv_fail(st, "%s: %s inside the channel (is the sheet on the plate?)", what, msg);
        goto out_free;
    }
    pl->x_max = place.x_foot + pl->raw.zmax / tana;
    pl->x_inf = place.x_foot + pl->raw.zinf / tana;
    pl->x_sup = place.x_foot + pl->raw.zsup / tana;
out_free:
    free(prof);
    return st;
}

/* Least-squares line z = c0 + c1 x through n points; slope 0 if the x do not spread. */
static void fit_line(const double *x, const double *z, size_t n, double *c0, double *c1)
{
    double lo = x[0], hi = x[0], mean = 0;
    for (size_t i = 0; i < n; i++) {
        lo = fmin(lo, x[i]);
        hi = fmax(hi, x[i]);
        mean += z[i];
    }
    double cov00, cov01, cov11, ss;
    if (n < 2 || hi - lo < 1e-9 ||
        gsl_fit_linear(x, 1, z, 1, n, c0, c1, &cov00, &cov01, &cov11, &ss) != GSL_SUCCESS) {
        *c0 = mean / (double)n;
        *c1 = 0;
    }
}

/* A plate's profile I(z+) as a table, interpolated linearly (GSL) between its samples and
 * without a value outside them; built once per plate for all its lookups. */
typedef struct shape_table {
    const double *z, *inten;
    size_t n;
    gsl_interp *in;
    gsl_interp_accel *acc;
} shape_table;

static void shape_table_free(shape_table *t)
{
    if (t->in)
        gsl_interp_free(t->in);
    if (t->acc)
        gsl_interp_accel_free(t->acc);
}

/* The table (z, inten, n) of one plate; n < 2 gives an empty table (no value anywhere). */
static rpiv_status shape_table_init(shape_table *t, const double *z, const double *inten, size_t n)
{
    *t = (shape_table){z, inten, n, NULL, NULL};
    if (n < 2)
        return RPIV_OK;
    t->in = gsl_interp_alloc(gsl_interp_linear, n);
    t->acc = gsl_interp_accel_alloc();
    if (!t->in || !t->acc) {
        shape_table_free(t);
        return rpiv_fail(RPIV_ENOMEM, "calib sheet: out of memory");
    }
    int gs = gsl_interp_init(t->in, z, inten, n);
    if (gs) {
        shape_table_free(t);
        return rpiv_fail(RPIV_ENUMERIC, "calib sheet: a plate's profile: %s", gsl_strerror(gs));
    }
    return RPIV_OK;
}

/* 1 and *y if x is inside the table, 0 outside. */
static int shape_at(const shape_table *t, double x, double *y)
{
    if (t->n < 2 || x < t->z[0] || x > t->z[t->n - 1])
        return 0;
    return gsl_interp_eval_e(t->in, t->z, t->inten, x, t->acc, y) == GSL_SUCCESS;
}

/* Lines through the (x*, z*) points where the plates meet z*_max, z*_inf, z*_sup. Each point
 * lies on the true line whatever the plate's angle (the quarter level along the plate is the
 * quarter level of the sheet because the plate crosses the sheet's maximum), so the fit undoes
 * the oblique cut; the per-plate thickness read directly on one plate does not. */
static rpiv_status sheet_model(rpiv_calib_sheet_result *r)
{
    size_t n = r->nplates;
    double *buf = malloc(6 * n * sizeof *buf);
    if (!buf)
        return rpiv_fail(RPIV_ENOMEM, "calib sheet: out of memory");
    double *xm = buf, *zm = buf + n, *xi = buf + 2 * n, *zi = buf + 3 * n, *xs = buf + 4 * n,
           *zs = buf + 5 * n;
    for (size_t i = 0; i < n; i++) {
        const rpiv_calib_sheet_plate *pl = &r->plate[i];
        xm[i] = pl->x_max;
        zm[i] = pl->raw.zmax;
        xi[i] = pl->x_inf;
        zi[i] = pl->raw.zinf;
        xs[i] = pl->x_sup;
        zs[i] = pl->raw.zsup;
    }
    fit_line(xm, zm, n, &r->zm0, &r->zm1);
    fit_line(xi, zi, n, &r->inf0, &r->inf1);
    fit_line(xs, zs, n, &r->sup0, &r->sup1);
    free(buf);
    r->e0 = r->sup0 - r->inf0;
    r->e1 = r->sup1 - r->inf1;
    for (size_t i = 0; i < n; i++) {
        rpiv_calib_sheet_plate *pl = &r->plate[i];
        double x = pl->x_max;
        pl->at.zmax = r->zm0 + r->zm1 * x;
        pl->at.zinf = r->inf0 + r->inf1 * x;
        pl->at.zsup = r->sup0 + r->sup1 * x;
        pl->at.e = pl->at.zsup - pl->at.zinf;
        pl->at.imax = 1;
        if (!(pl->at.e > 0))
            return rpiv_fail(RPIV_ENUMERIC,
                             "calib sheet: fitted thickness e* = %g <= 0 at plate %zu (x* = %g)",
                             pl->at.e, i + 1, x);
    }
    return RPIV_OK;
}

/* Mean shape S(z+) over all plates on a regular z+ grid, and each plate's deviation from it. */
static rpiv_status sheet_shape(const rpiv_calib_sheet_params *p, rpiv_calib_sheet_result *r)
{
    size_t half = (size_t)lround(p->zplus_max / p->zplus_step), ng = 2 * half + 1;
    size_t n = r->nplates, nmax = 0;
    for (size_t i = 0; i < n; i++)
        nmax = r->plate[i].n > nmax ? r->plate[i].n : nmax;
    double *zp = malloc(n * nmax * sizeof *zp), *sum = calloc(ng, sizeof *sum);
    size_t *cnt = calloc(ng, sizeof *cnt);
    r->zplus = malloc(ng * sizeof *r->zplus);
    r->shape = malloc(ng * sizeof *r->shape);
    rpiv_status st = RPIV_OK;
    if (!zp || !sum || !cnt || !r->zplus || !r->shape) {
        st = rpiv_fail(RPIV_ENOMEM, "calib sheet: out of memory");
        goto out_free;
    }
    for (size_t i = 0; i < n; i++) {
        const rpiv_calib_sheet_plate *pl = &r->plate[i];
        double *z = zp + i * nmax;
        for (size_t j = 0; j < pl->n; j++) {
            double x = pl->x[j];
            z[j] = rpiv_sheet_zplus(pl->z[j], r->zm0 + r->zm1 * x, r->e0 + r->e1 * x);
            if (j && !(z[j] > z[j - 1])) {
                st = rpiv_fail(RPIV_ENUMERIC,
                               "calib sheet: z+ does not increase along plate %zu (the fitted "
                               "sheet is steeper than the plate)",
                               i + 1);
                goto out_free;
            }
        }
        shape_table t;
        if ((st = shape_table_init(&t, z, pl->inten, pl->n)))
            goto out_free;
        for (size_t g = 0; g < ng; g++) {
            double v, zg = ((double)g - (double)half) * p->zplus_step;
            if (shape_at(&t, zg, &v)) {
                sum[g] += v;
                cnt[g]++;
            }
        }
        shape_table_free(&t);
    }
    size_t m = 0;
    double smax = 0;
    for (size_t g = 0; g < ng; g++)
        if (cnt[g]) {
            r->zplus[m] = ((double)g - (double)half) * p->zplus_step;
            r->shape[m] = sum[g] / (double)cnt[g];
            smax = fmax(smax, r->shape[m]);
            m++;
        }
    r->nshape = m;
    if (m < 3 || !(smax > 0)) {
        st = rpiv_fail(RPIV_ENUMERIC, "calib sheet: the mean shape has fewer than 3 rows");
        goto out_free;
    }
    for (size_t j = 0; j < m; j++)
        r->shape[j] = fmin(1.0, fmax(0.0, r->shape[j] / smax));
    for (size_t i = 0; i < n; i++) {
        rpiv_calib_sheet_plate *pl = &r->plate[i];
        double ss = 0, v;
        size_t k = 0;
        shape_table t;
        if ((st = shape_table_init(&t, zp + i * nmax, pl->inten, pl->n)))
            goto out_free;
        for (size_t j = 0; j < m; j++)
            if (shape_at(&t, r->zplus[j], &v)) {
                ss += (v - r->shape[j]) * (v - r->shape[j]);
                k++;
            }
        shape_table_free(&t);
        pl->shape_rms = k ? sqrt(ss / (double)k) : (double)NAN;
    }
out_free:
    free(zp);
    free(sum);
    free(cnt);
    return st;
}

rpiv_status rpiv_calib_sheet_run(const rpiv_calib_sheet_params *p, const rpiv_camera *cam,
                                 const rpiv_channel *ch, const rpiv_calib_shot *shots,
                                 size_t nshots, const rpiv_image *dark,
                                 rpiv_calib_sheet_result **out)
{
    *out = NULL;
    rpiv_status st = rpiv_calib_sheet_params_check(p);
    if (st)
        return st;
    if ((st = rpiv_camera_check(cam)) || (st = rpiv_channel_check(ch)))
        return st;
    if (nshots == 0)
        return rpiv_fail(RPIV_EINVAL, "calib sheet: no image given");
    rpiv_calib_sheet_result *r = calloc(1, sizeof *r);
    if (!r)
        return rpiv_fail(RPIV_ENOMEM, "calib sheet: out of memory");
    r->plate = calloc(nshots, sizeof *r->plate);
    if (!r->plate) {
        free(r);
        return rpiv_fail(RPIV_ENOMEM, "calib sheet: out of memory");
    }
    r->nplates = nshots;
    for (size_t i = 0; i < nshots; i++) {
        char what[32];
        snprintf(what, sizeof what, "image %zu", i + 1);
        if ((st = sheet_plate(p, cam, ch, &shots[i], dark, what, &r->plate[i])))
            goto out_fail;
    }
    if ((st = sheet_model(r)) || (st = sheet_shape(p, r)))
        goto out_fail;
    *out = r;
    return RPIV_OK;
out_fail:
    rpiv_calib_sheet_result_free(r);
    return st;
}

rpiv_status rpiv_calib_sheet_save_profile(const rpiv_calib_sheet_result *r, const char *path)
{
    return rpiv_sheet_save_profile(path, r->e0, r->e1, r->zm0, r->zm1, r->zplus, r->shape,
                                   r->nshape);
}

rpiv_status rpiv_calib_sheet_write_plates(const rpiv_calib_sheet_result *r, FILE *fp)
{
    fprintf(fp,
            "# rpiv calib sheet: one line per plate\n"
            "# model: z*_max = %.6g + %.6g x*, e* = %.6g + %.6g x*, z*_inf = %.6g + %.6g x*, "
            "z*_sup = %.6g + %.6g x*\n"
            "# raw_*: read along the plate; at_*: the fitted lines at x*_max\n"
            "# plate foot_px angle_deg x_foot x_max raw_zinf raw_zmax raw_zsup raw_e at_zinf "
            "at_zmax at_zsup at_e shape_rms\n",
            r->zm0, r->zm1, r->e0, r->e1, r->inf0, r->inf1, r->sup0, r->sup1);
    for (size_t i = 0; i < r->nplates; i++) {
        const rpiv_calib_sheet_plate *pl = &r->plate[i];
        fprintf(fp, "%zu %.3f %.4f %.5f %.5f %.5f %.5f %.5f %.5f %.5f %.5f %.5f %.5f %.5f\n", i + 1,
                pl->foot_px, pl->angle_deg, pl->x_foot, pl->x_max, pl->raw.zinf, pl->raw.zmax,
                pl->raw.zsup, pl->raw.e, pl->at.zinf, pl->at.zmax, pl->at.zsup, pl->at.e,
                pl->shape_rms);
    }
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "calib sheet: write error");
    return RPIV_OK;
}

rpiv_status rpiv_calib_sheet_write_profiles(const rpiv_calib_sheet_result *r, FILE *fp)
{
    fprintf(fp, "# rpiv calib sheet: profiles along each plate (blank line between plates)\n"
                "# plate zstar xstar I0star zplus\n");
    for (size_t i = 0; i < r->nplates; i++) {
        const rpiv_calib_sheet_plate *pl = &r->plate[i];
        if (i)
            fputc('\n', fp);
        for (size_t j = 0; j < pl->n; j++) {
            double x = pl->x[j];
            double zp = rpiv_sheet_zplus(pl->z[j], r->zm0 + r->zm1 * x, r->e0 + r->e1 * x);
            fprintf(fp, "%zu %.6f %.6f %.6f %.6f\n", i + 1, pl->z[j], x, pl->inten[j], zp);
        }
    }
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "calib sheet: write error");
    return RPIV_OK;
}
