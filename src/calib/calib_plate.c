/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The inclined plate in the image, shared by both analyses: the geometry parameters, the
 * dark-corrected frame and its span-averaged profile, and where the plate's foot is and at
 * which angle it rises (given or detected from its edge). */
#include "calib_impl.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_filter.h>
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
