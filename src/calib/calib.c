/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Calibration: shared geometry and image preparation, and the light-sheet profile from a
 * fluorescent inclined plate (paper, "Measurement of the laser sheet intensity after the
 * refraction"). The reasoning behind each step is in docs/calib.md. */
#include "calib_impl.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_filter.h>
#include <gsl/gsl_fit.h>
#include <gsl/gsl_integration.h>
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

/* ---- optics helpers ------------------------------------------------------------------------ */

double calib_scale(double scale_px_m, const rpiv_camera *cam)
{
    return scale_px_m > 0 ? scale_px_m : cam->magnification / rpiv_camera_pixel_m(cam);
}

double calib_blur_px(const rpiv_camera *cam, double h_m, double scale, double zstar)
{
    double zdef = rpiv_imaging_defocus_m(cam, h_m, zstar);
    double sig_sensor = rpiv_imaging_sigma_m(cam, rpiv_imaging_de_m(cam, 0, zdef));
    /* sensor metres -> image pixels: the sensor pixel is M / scale */
    return sig_sensor * scale / cam->magnification;
}

/* Upper tail Q(x) = 1 - Phi(x), accurate for large x. */
static double upper(double x)
{
    return 0.5 * erfc(x / M_SQRT2);
}

double calib_boxg(double u, double s)
{
    double a = (u - 0.5) / s, b = (u + 0.5) / s;
    /* Phi(b) - Phi(a) written with the tail that does not cancel */
    if (a > 0)
        return upper(a) - upper(b);
    return upper(-b) - upper(-a);
}

/* F(x) = integral of Phi from -inf to x = x Phi(x) + phi(x); F(x) = x + F(-x). */
static double phi_int(double x)
{
    double ax = -fabs(x);
    double f = ax * upper(-ax) + exp(-0.5 * ax * ax) / sqrt(2 * M_PI);
    return x > 0 ? x + f : f;
}

double calib_boxg_bar(double u, double w, double s)
{
    if (!(w > 0))
        return 0;
    double a = (u + w + 0.5) / s, b = (u - w + 0.5) / s, c = (u + w - 0.5) / s,
           d = (u - w - 0.5) / s;
    double v = s * (phi_int(a) - phi_int(b) - phi_int(c) + phi_int(d));
    return v > 0 ? v : 0;
}

rpiv_status calib_gl_init(calib_gl *gl)
{
    gsl_integration_glfixed_table *t = gsl_integration_glfixed_table_alloc(CALIB_GL_BASE);
    if (!t)
        return rpiv_fail(RPIV_ENOMEM, "calib: out of memory (quadrature table)");
    for (size_t i = 0; i < CALIB_GL_BASE; i++)
        gsl_integration_glfixed_point(-1, 1, i, &gl->x[i], &gl->w[i], t);
    gsl_integration_glfixed_table_free(t);
    return RPIV_OK;
}

/* Nodes in theta for an ellipse of row semi-axis ay blurred by s: the pixel-row term varies
 * over about s / ay in theta, so the panels are made that narrow (within limits). */
static int gl_nodes(const calib_gl *gl, double ay, double s, double *theta, double *weight)
{
    double want = ceil(ay / (2 * fmax(s, 1e-3)));
    int np = want < 4 ? 4 : want > CALIB_GL_PANELS ? CALIB_GL_PANELS : (int)want;
    double hw = M_PI / (2 * np); /* panel half-width */
    int n = 0;
    for (int p = 0; p < np; p++) {
        double c = -M_PI / 2 + (2 * p + 1) * hw;
        for (int k = 0; k < CALIB_GL_BASE; k++, n++) {
            theta[n] = c + hw * gl->x[k];
            weight[n] = hw * gl->w[k];
        }
    }
    return n;
}

/* The ellipse is integrated row by row: qy = ay sin(theta), so the half-width of the row is
 * ax cos(theta) and dqy = ay cos(theta) dtheta; the integrand is smooth in theta. */
void calib_ellipse_add(const calib_gl *gl, double cx, double cy, double ax, double ay, double s,
                       int x0, int y0, int nx, int ny, double scale, double *out, double *work)
{
    double theta[CALIB_GL_MAX], weight[CALIB_GL_MAX];
    int K = gl_nodes(gl, ay, s, theta, weight);
    double *col = work, *row = work + (size_t)nx * K;
    for (int i = 0; i < nx; i++)
        for (int k = 0; k < K; k++) {
            double c = cos(theta[k]);
            col[(size_t)i * K + k] = weight[k] * ay * c * calib_boxg_bar(x0 + i - cx, ax * c, s);
        }
    for (int j = 0; j < ny; j++)
        for (int k = 0; k < K; k++)
            row[(size_t)j * K + k] = calib_boxg(y0 + j - cy - ay * sin(theta[k]), s);
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double v = 0;
            const double *r = row + (size_t)j * K, *c = col + (size_t)i * K;
            for (int k = 0; k < K; k++)
                v += r[k] * c[k];
            out[(size_t)j * nx + i] += scale * v;
        }
}

double calib_ellipse_at(const calib_gl *gl, double cx, double cy, double ax, double ay, double s,
                        double px, double py)
{
    double theta[CALIB_GL_MAX], weight[CALIB_GL_MAX], v = 0;
    int K = gl_nodes(gl, ay, s, theta, weight);
    for (int k = 0; k < K; k++) {
        double c = cos(theta[k]);
        v += weight[k] * ay * c * calib_boxg(py - cy - ay * sin(theta[k]), s) *
             calib_boxg_bar(px - cx, ax * c, s);
    }
    return v;
}

double calib_lattice_pixel(const calib_gl *gl, double ax, double ay, double ppx, double ppy,
                           double s, const double *node, const double *wt, int n)
{
    /* For one ellipse row (node theta), the row term depends only on the lattice row j and the
     * column term only on the lattice column i, so the lattice sum and the phase average
     * factor into two 1-D sums per node. */
    double theta[CALIB_GL_MAX], weight[CALIB_GL_MAX], v = 0;
    int K = gl_nodes(gl, ay, s, theta, weight);
    int kx = (int)ceil((ax + 6 * s + 2) / ppx), ky = (int)ceil((ay + 6 * s + 2) / ppy);
    for (int k = 0; k < K; k++) {
        double c = cos(theta[k]), sy = ay * sin(theta[k]), wx = ax * c, ry = 0, rx = 0;
        for (int b = 0; b < n; b++)
            for (int j = -ky; j <= ky; j++)
                ry += wt[b] * calib_boxg(node[b] - j * ppy - sy, s);
        for (int a = 0; a < n; a++)
            for (int i = -kx; i <= kx; i++)
                rx += wt[a] * calib_boxg_bar(node[a] - i * ppx, wx, s);
        v += weight[k] * ay * c * ry * rx;
    }
    return v;
}

/* ---- geometry ------------------------------------------------------------------------------- */

rpiv_calib_geom rpiv_calib_geom_default(void)
{
    return (rpiv_calib_geom){.angle_deg = 45,
                             .plate_height_m = 0,
                             .scale_px_m = 0,
                             .row0 = 0,
                             .row1 = 0,
                             .dark = 0,
                             .dark_x = 0,
                             .dark_y = 0,
                             .dark_w = 0,
                             .dark_h = 0,
                             .edge_window = 8};
}

rpiv_status rpiv_calib_geom_check(const rpiv_calib_geom *g)
{
    double a = fabs(g->angle_deg);
    if (!(g->angle_deg == 0 || (a >= 5 && a <= 85)))
        return rpiv_fail(RPIV_EINVAL,
                         "calib: plate angle %g deg out of range (|angle| in 5..85, 0 = detect)",
                         g->angle_deg);
    if (!(g->plate_height_m >= 0 && g->plate_height_m < 10))
        return rpiv_fail(RPIV_EINVAL, "calib: plate height %g m outside 0..10", g->plate_height_m);
    if (!(g->scale_px_m >= 0 && g->scale_px_m < 1e9))
        return rpiv_fail(RPIV_EINVAL, "calib: image scale %g px/m outside 0..1e9", g->scale_px_m);
    if (g->row0 < 0 || g->row1 < 0 || (g->row1 != 0 && g->row1 <= g->row0))
        return rpiv_fail(RPIV_EINVAL, "calib: span rows %d..%d are not a range", g->row0, g->row1);
    if (!isfinite(g->dark))
        return rpiv_fail(RPIV_EINVAL, "calib: dark level must be finite");
    if (g->dark_w < 0 || g->dark_h < 0 || g->dark_x < 0 || g->dark_y < 0 ||
        (g->dark_w > 0 && g->dark_h == 0))
        return rpiv_fail(RPIV_EINVAL, "calib: dark region %d,%d,%d,%d is not a rectangle",
                         g->dark_x, g->dark_y, g->dark_w, g->dark_h);
    if (g->edge_window < 2 || g->edge_window > 1000)
        return rpiv_fail(RPIV_EINVAL, "calib: edge window %d px outside 2..1000", g->edge_window);
    return RPIV_OK;
}

/* ---- frames --------------------------------------------------------------------------------- */

rpiv_status calib_frame_init(const rpiv_calib_geom *g, const rpiv_image *im, const rpiv_image *dark,
                             const char *what, calib_frame *f)
{
    f->im = im;
    f->dark = dark;
    f->dark_level = g->dark;
    f->row0 = g->row0;
    f->row1 = g->row1 ? g->row1 : im->h;
    if (f->row1 > im->h)
        return rpiv_fail(RPIV_ESIZE, "%s: span rows %d..%d outside the image's %d rows", what,
                         f->row0, f->row1, im->h);
    if (dark) {
        if (dark->w != im->w || dark->h != im->h)
            return rpiv_fail(RPIV_ESIZE, "%s: dark image is %dx%d, the image %dx%d", what, dark->w,
                             dark->h, im->w, im->h);
        return RPIV_OK;
    }
    if (g->dark_w > 0) {
        if (g->dark_x + g->dark_w > im->w || g->dark_y + g->dark_h > im->h)
            return rpiv_fail(RPIV_ESIZE, "%s: dark region %d,%d,%d,%d outside the %dx%d image",
                             what, g->dark_x, g->dark_y, g->dark_w, g->dark_h, im->w, im->h);
        double sum = 0;
        for (int y = g->dark_y; y < g->dark_y + g->dark_h; y++)
            for (int x = g->dark_x; x < g->dark_x + g->dark_w; x++)
                sum += (double)im->px[(size_t)y * im->w + x];
        f->dark_level = sum / ((double)g->dark_w * g->dark_h);
    }
    return RPIV_OK;
}

double calib_frame_at(const calib_frame *f, int x, int y)
{
    size_t i = (size_t)y * f->im->w + x;
    return (double)f->im->px[i] - (f->dark ? (double)f->dark->px[i] : f->dark_level);
}

void calib_frame_profile(const calib_frame *f, double *p)
{
    int w = f->im->w;
    for (int x = 0; x < w; x++)
        p[x] = 0;
    for (int y = f->row0; y < f->row1; y++)
        for (int x = 0; x < w; x++)
            p[x] += calib_frame_at(f, x, y);
    for (int x = 0; x < w; x++)
        p[x] /= f->row1 - f->row0;
}

rpiv_status calib_frame_noise(const calib_frame *f, double *noise)
{
    int w = f->im->w, nr = f->row1 - f->row0;
    *noise = 0;
    if (nr < 2)
        return RPIV_OK;
    double *sd = malloc((size_t)w * sizeof *sd);
    if (!sd)
        return rpiv_fail(RPIV_ENOMEM, "calib: out of memory");
    for (int x = 0; x < w; x++) {
        double m = 0, ss = 0;
        for (int y = f->row0; y < f->row1; y++)
            m += calib_frame_at(f, x, y);
        m /= nr;
        for (int y = f->row0; y < f->row1; y++) {
            double d = calib_frame_at(f, x, y) - m;
            ss += d * d;
        }
        sd[x] = sqrt(ss / (nr - 1));
    }
    gsl_sort(sd, 1, (size_t)w);
    *noise = gsl_stats_median_from_sorted_data(sd, 1, (size_t)w) / sqrt((double)nr);
    free(sd);
    return RPIV_OK;
}

/* Median of p[idx(i)] for i in [i0, i1) (scan order), into tmp. */
static double scan_median(const double *p, int w, int side, int i0, int i1, double *tmp)
{
    size_t n = 0;
    for (int i = i0; i < i1 && i < w; i++)
        tmp[n++] = p[side > 0 ? i : w - 1 - i];
    gsl_sort(tmp, 1, n);
    return gsl_stats_median_from_sorted_data(tmp, 1, n);
}

/* Plate edge seen from one side of the span-averaged profile: the background is the first
 * `win` columns, the plate level the median of `win` columns just inside (the plate may be
 * brighter or darker than the floor); the edge is where the profile crosses half-way (the
 * half-height point of a blurred step is the step itself). The plate level is re-read once from
 * the first estimate, so a blurred ramp does not bias it. */
static rpiv_status detect_edge(const double *p, int w, int side, int win, const char *what,
                               const char *name, double *edge)
{
    if (w < 4 * win)
        return rpiv_fail(RPIV_ENUMERIC,
                         "%s: image too narrow (%d px) to detect the plate %s (edge window %d px)",
                         what, w, name, win);
    double *tmp = malloc((size_t)w * sizeof *tmp);
    if (!tmp)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
#define AT(i) p[side > 0 ? (i) : w - 1 - (i)]
    double bg = scan_median(p, w, side, 0, win, tmp);
    for (int i = 0; i < win; i++)
        tmp[i] = fabs(AT(i) - bg);
    gsl_sort(tmp, 1, (size_t)win);
    double noise = 1.4826 * gsl_stats_median_from_sorted_data(tmp, 1, (size_t)win);
    double dev = 0;
    for (int i = 0; i < w; i++)
        dev = fmax(dev, fabs(AT(i) - bg));
    double thr = fmax(8 * noise, 0.02 * dev);
    int i1 = -1;
    for (int i = win; i + 1 < w; i++)
        if (fabs(AT(i) - bg) > thr && fabs(AT(i + 1) - bg) > thr &&
            (AT(i) > bg) == (AT(i + 1) > bg)) {
            i1 = i;
            break;
        }
    rpiv_status st = RPIV_OK;
    if (i1 < 0 || !(dev > 0)) {
        st = rpiv_fail(RPIV_ENUMERIC,
                       "%s: cannot detect the plate %s (no step from the background in the "
                       "span-averaged profile); give it explicitly",
                       what, name);
        goto out_free;
    }
    double sgn = AT(i1) > bg ? 1 : -1, pos = i1;
    for (int iter = 0; iter < 2; iter++) {
        int start = (int)floor(pos) + win / 2;
        if (start + win > w) {
            st = rpiv_fail(RPIV_ENUMERIC, "%s: plate %s too close to the image edge", what, name);
            goto out_free;
        }
        double level = scan_median(p, w, side, start, start + win, tmp);
        double half = bg + 0.5 * (level - bg);
        int j = i1 - 1;
        while (j > 0 && sgn * (AT(j) - half) >= 0)
            j--;
        while (j + 1 < w && sgn * (AT(j + 1) - half) < 0)
            j++;
        if (j + 1 >= w || !(sgn * (level - bg) > 0)) {
            st = rpiv_fail(RPIV_ENUMERIC, "%s: cannot locate the plate %s", what, name);
            goto out_free;
        }
        double a = AT(j), b = AT(j + 1);
        pos = j + (b != a ? (half - a) / (b - a) : 0.5);
    }
    *edge = side > 0 ? pos : w - 1 - pos;
#undef AT
out_free:
    free(tmp);
    return st;
}

rpiv_status calib_place_init(const rpiv_calib_geom *g, const rpiv_camera *cam,
                             const rpiv_channel *ch, const rpiv_calib_shot *shot, const double *p,
                             int w, const char *what, calib_place *pl)
{
    rpiv_status st;
    pl->scale = calib_scale(g->scale_px_m, cam);
    pl->h_m = ch->h_m;
    pl->angle_deg = g->angle_deg;
    int side = g->angle_deg < 0 ? -1 : 1;
    if (isfinite(shot->foot_px))
        pl->foot = shot->foot_px;
    else if ((st = detect_edge(p, w, side, g->edge_window, what, "foot", &pl->foot)))
        return st;
    if (g->angle_deg == 0) {
        double top, hp = g->plate_height_m > 0 ? g->plate_height_m : ch->h_m;
        if ((st = detect_edge(p, w, -1, g->edge_window, what, "top edge", &top)))
            return st;
        double len = top - pl->foot;
        double a = len > 0 ? atan(hp * pl->scale / len) * 180 / M_PI : 0;
        if (!(a >= 5 && a <= 85))
            return rpiv_fail(RPIV_ENUMERIC,
                             "%s: detected plate angle %.3g deg (foot %.1f px, top %.1f px) out "
                             "of range 5..85; give --plate-angle",
                             what, a, pl->foot, top);
        pl->angle_deg = a;
    }
    pl->k = tan(pl->angle_deg * M_PI / 180) / (pl->scale * ch->h_m);
    pl->x_foot =
        isfinite(shot->x_foot) ? shot->x_foot : ch->fov_x0_star + pl->foot / (pl->scale * ch->h_m);
    return RPIV_OK;
}

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

/* Linear interpolation in an increasing table; returns 0 outside. */
static int interp(const double *xs, const double *ys, size_t n, double x, double *y)
{
    if (n < 2 || x < xs[0] || x > xs[n - 1])
        return 0;
    size_t lo = 0, hi = n - 1;
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (xs[mid] <= x)
            lo = mid;
        else
            hi = mid;
    }
    double f = xs[hi] > xs[lo] ? (x - xs[lo]) / (xs[hi] - xs[lo]) : 0;
    *y = ys[lo] + f * (ys[hi] - ys[lo]);
    return 1;
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
            z[j] = (pl->z[j] - (r->zm0 + r->zm1 * x)) / (r->e0 + r->e1 * x);
            if (j && !(z[j] > z[j - 1])) {
                st = rpiv_fail(RPIV_ENUMERIC,
                               "calib sheet: z+ does not increase along plate %zu (the fitted "
                               "sheet is steeper than the plate)",
                               i + 1);
                goto out_free;
            }
        }
        for (size_t g = 0; g < ng; g++) {
            double v, zg = ((double)g - (double)half) * p->zplus_step;
            if (interp(z, pl->inten, pl->n, zg, &v)) {
                sum[g] += v;
                cnt[g]++;
            }
        }
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
        for (size_t j = 0; j < m; j++)
            if (interp(zp + i * nmax, pl->inten, pl->n, r->zplus[j], &v)) {
                ss += (v - r->shape[j]) * (v - r->shape[j]);
                k++;
            }
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
            double zp = (pl->z[j] - (r->zm0 + r->zm1 * x)) / (r->e0 + r->e1 * x);
            fprintf(fp, "%zu %.6f %.6f %.6f %.6f\n", i + 1, pl->z[j], x, pl->inten[j], zp);
        }
    }
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "calib sheet: write error");
    return RPIV_OK;
}
