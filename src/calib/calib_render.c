/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Calibration targets rendered from the imaging model: a fluorescent plate in a light sheet and
 * a dotted target, both on an inclined plate seen from below (docs/calib.md). */
#include "calib_impl.h"

#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Sub-samples per pixel of the 1-D emission integral along x. */
#define RENDER_SUB 16

rpiv_calib_render_params rpiv_calib_render_params_default(void)
{
    return (rpiv_calib_render_params){.angle_deg = 45,
                                      .foot_px = 40.3187,
                                      .x_foot = (double)NAN,
                                      .plate_height_m = 0,
                                      .scale_px_m = 0,
                                      .dark = 100,
                                      .background = 150,
                                      .level = 3000,
                                      .glow = 0,
                                      .white_slope = 0,
                                      .dot_d_m = 62.5e-6,
                                      .pitch_m = 125e-6,
                                      .reflectance = 0.1,
                                      .phase_x = 0.3187,
                                      .phase_y = 0.2219,
                                      .noise = 0,
                                      .seed = 1};
}

rpiv_status rpiv_calib_render_params_check(const rpiv_calib_render_params *rp)
{
    double a = fabs(rp->angle_deg);
    if (!(a >= 5 && a <= 85))
        return rpiv_fail(RPIV_EINVAL,
                         "calib render: plate angle %g deg out of range (|angle| "
                         "in 5..85)",
                         rp->angle_deg);
    if (!isfinite(rp->foot_px) || fabs(rp->foot_px) > 1e6)
        return rpiv_fail(RPIV_EINVAL, "calib render: foot column %g px must be finite",
                         rp->foot_px);
    if (!(rp->plate_height_m >= 0 && rp->plate_height_m < 10) ||
        !(rp->scale_px_m >= 0 && rp->scale_px_m < 1e9))
        return rpiv_fail(RPIV_EINVAL, "calib render: plate height or scale out of range");
    if (!(rp->dark >= 0 && rp->background >= 0 && rp->glow >= 0 && rp->level > 0 &&
          rp->dark + rp->background + rp->glow + rp->level < 1e9))
        return rpiv_fail(RPIV_EINVAL, "calib render: grey levels must be >= 0 (level > 0)");
    if (!(fabs(rp->white_slope) < 1))
        return rpiv_fail(RPIV_EINVAL, "calib render: white slope %g outside (-1, 1)",
                         rp->white_slope);
    if (!(rp->dot_d_m > 0 && rp->pitch_m > rp->dot_d_m && rp->pitch_m < 0.1))
        return rpiv_fail(RPIV_EINVAL,
                         "calib render: dot diameter %g m and pitch %g m (pitch > diameter > 0)",
                         rp->dot_d_m, rp->pitch_m);
    if (!(rp->reflectance >= 0 && rp->reflectance < 1))
        return rpiv_fail(RPIV_EINVAL, "calib render: dot reflectance %g outside 0..1",
                         rp->reflectance);
    if (!isfinite(rp->phase_x) || !isfinite(rp->phase_y))
        return rpiv_fail(RPIV_EINVAL, "calib render: lattice phases must be finite");
    if (!(rp->noise >= 0 && rp->noise < 1e9))
        return rpiv_fail(RPIV_EINVAL, "calib render: noise %g must be >= 0", rp->noise);
    return RPIV_OK;
}

/* What both renders share: the plate's place and the optics. */
typedef struct scene {
    const rpiv_calib_render_params *rp;
    const rpiv_camera *cam;
    const rpiv_channel *ch;
    const rpiv_sheet *sheet;               /* NULL: dots (white plate) */
    double scale, k, x_foot, zcap, lo, hi; /* plate spans columns [lo, hi] */
    int w, h;
} scene;

static rpiv_status scene_init(scene *sc, const rpiv_calib_render_params *rp, const rpiv_camera *cam,
                              const rpiv_channel *ch, const rpiv_sheet *sheet, const rpiv_image *im)
{
    rpiv_status st = rpiv_calib_render_params_check(rp);
    if (st || (st = rpiv_camera_check(cam)) || (st = rpiv_channel_check(ch)))
        return st;
    if (im->w < 1 || im->h < 1 || !im->px)
        return rpiv_fail(RPIV_EINVAL, "calib render: empty image");
    sc->rp = rp;
    sc->cam = cam;
    sc->ch = ch;
    sc->sheet = sheet;
    sc->w = im->w;
    sc->h = im->h;
    sc->scale = calib_scale(rp->scale_px_m, cam);
    sc->k = tan(rp->angle_deg * M_PI / 180) / (sc->scale * ch->h_m);
    sc->x_foot =
        isfinite(rp->x_foot) ? rp->x_foot : ch->fov_x0_star + rp->foot_px / (sc->scale * ch->h_m);
    double hp = rp->plate_height_m > 0 ? rp->plate_height_m : ch->h_m;
    sc->zcap = hp / ch->h_m;
    double top = rp->foot_px + sc->zcap / sc->k;
    sc->lo = fmin(rp->foot_px, top);
    sc->hi = fmax(rp->foot_px, top);
    return RPIV_OK;
}

/* Height z* of the plate (or floor / top) seen at column xs. */
static double scene_z(const scene *sc, double xs)
{
    double z = (xs - sc->rp->foot_px) * sc->k;
    return fmin(fmax(z, 0.0), sc->zcap);
}

/* Light collected from a point at z* relative to one in the object plane (Eq. "int"). */
static double collect(const scene *sc, double z)
{
    double zd = rpiv_imaging_defocus_m(sc->cam, sc->ch->h_m, z), s0 = sc->cam->s0_m;
    return (s0 / (s0 + zd)) * (s0 / (s0 + zd));
}

/* Emission per unit image length at column xs (before the lens). */
static double emission(const scene *sc, double xs)
{
    const rpiv_calib_render_params *rp = sc->rp;
    if (xs < sc->lo || xs > sc->hi)
        return rp->background * collect(sc, scene_z(sc, xs));
    double z = scene_z(sc, xs), c = collect(sc, z);
    if (sc->sheet) {
        double xstar = sc->x_foot + (xs - rp->foot_px) / (sc->scale * sc->ch->h_m);
        return c * (rp->level * rpiv_sheet_eval(sc->sheet, xstar, z) + rp->glow);
    }
    return c * rp->level * (1 + rp->white_slope * (xs / (sc->w > 1 ? sc->w - 1 : 1) - 0.5));
}

/* The span-uniform part of the image: every source point along x spreads with its own blur.
 * The plate edges split the integral so that the steps are exact. */
static void render_profile(const scene *sc, double *q)
{
    double smax = fmax(calib_blur_px(sc->cam, sc->ch->h_m, sc->scale, 0),
                       calib_blur_px(sc->cam, sc->ch->h_m, sc->scale, sc->zcap));
    double margin = 6 * smax + 2;
    double cut[4] = {-margin, sc->lo, sc->hi, sc->w - 1 + margin};
    for (int x = 0; x < sc->w; x++)
        q[x] = 0;
    for (int seg = 0; seg < 3; seg++) {
        double a = fmax(cut[seg], -margin), b = fmin(cut[seg + 1], sc->w - 1 + margin);
        if (!(b > a))
            continue;
        long n = (long)ceil((b - a) * RENDER_SUB);
        double dx = (b - a) / (double)n;
        for (long i = 0; i < n; i++) {
            double xs = a + (i + 0.5) * dx, e = emission(sc, xs) * dx;
            if (e == 0)
                continue;
            double s = calib_blur_px(sc->cam, sc->ch->h_m, sc->scale, scene_z(sc, xs));
            int x0 = (int)floor(xs - 6 * s - 1), x1 = (int)ceil(xs + 6 * s + 1);
            for (int x = x0 < 0 ? 0 : x0; x <= x1 && x < sc->w; x++)
                q[x] += e * calib_boxg(x - xs, s);
        }
    }
}

static rpiv_status finish(const scene *sc, const double *q, const double *dk, rpiv_image *im)
{
    gsl_rng *rng = NULL;
    if (sc->rp->noise > 0) {
        rng = gsl_rng_alloc(gsl_rng_mt19937);
        if (!rng)
            return rpiv_fail(RPIV_ENOMEM, "calib render: out of memory");
        gsl_rng_set(rng, sc->rp->seed);
    }
    for (int y = 0; y < sc->h; y++)
        for (int x = 0; x < sc->w; x++) {
            size_t i = (size_t)y * sc->w + x;
            double v = sc->rp->dark + q[x] - (dk ? dk[i] : 0);
            if (rng)
                v += gsl_ran_gaussian(rng, sc->rp->noise);
            im->px[i] = (float)v;
        }
    gsl_rng_free(rng);
    return RPIV_OK;
}

rpiv_status rpiv_calib_render_sheet(const rpiv_calib_render_params *rp, const rpiv_camera *cam,
                                    const rpiv_channel *ch, const rpiv_sheet *sheet, rpiv_image *im)
{
    scene sc;
    rpiv_status st = scene_init(&sc, rp, cam, ch, sheet, im);
    if (st)
        return st;
    double *q = malloc((size_t)im->w * sizeof *q);
    if (!q)
        return rpiv_fail(RPIV_ENOMEM, "calib render: out of memory");
    render_profile(&sc, q);
    st = finish(&sc, q, NULL, im);
    free(q);
    return st;
}

rpiv_status rpiv_calib_render_dots(const rpiv_calib_render_params *rp, const rpiv_camera *cam,
                                   const rpiv_channel *ch, rpiv_image *im)
{
    scene sc;
    calib_gl gl;
    rpiv_status st = scene_init(&sc, rp, cam, ch, NULL, im);
    if (st || (st = calib_gl_init(&gl)))
        return st;
    double ca = fabs(cos(rp->angle_deg * M_PI / 180));
    double r = 0.5 * rp->dot_d_m * sc.scale, ax = r * ca, ay = r;
    double ppx = rp->pitch_m * ca * sc.scale, ppy = rp->pitch_m * sc.scale;
    double smax = fmax(calib_blur_px(cam, ch->h_m, sc.scale, 0),
                       calib_blur_px(cam, ch->h_m, sc.scale, sc.zcap));
    int half = (int)ceil(fmax(ax, ay) + 6 * smax + 1);
    size_t npx = (size_t)im->w * im->h;
    double *q = malloc((size_t)im->w * sizeof *q), *dk = calloc(npx, sizeof *dk);
    double *patch = malloc((size_t)(2 * half + 1) * (2 * half + 1) * sizeof *patch);
    double *work = malloc((size_t)2 * (2 * half + 1) * CALIB_GL_MAX * sizeof *work);
    if (!q || !dk || !patch || !work) {
        st = rpiv_fail(RPIV_ENOMEM, "calib render: out of memory");
        goto out_free;
    }
    render_profile(&sc, q);
    double dir = sc.k > 0 ? 1 : -1, len = sc.hi - sc.lo;
    /* dots whose ellipse lies wholly on the plate; rows past the image edge still shade it */
    for (long i = 0;; i++) {
        double off = (i + rp->phase_x) * ppx;
        if (off + ax > len)
            break;
        if (off - ax < 0)
            continue;
        double cx = rp->foot_px + dir * off;
        if (cx < -half || cx > im->w - 1 + half)
            continue;
        double z = scene_z(&sc, cx);
        double s = calib_blur_px(cam, ch->h_m, sc.scale, z);
        double amp = (1 - rp->reflectance) * emission(&sc, cx);
        int hd = (int)ceil(fmax(ax, ay) + 6 * s + 1); /* this dot's reach, <= half */
        int x0 = (int)floor(cx) - hd, nx = 2 * hd + 1;
        for (long j = (long)floor(-half / ppy - rp->phase_y) - 1;; j++) {
            double cy = (j + rp->phase_y) * ppy;
            if (cy > im->h - 1 + half)
                break;
            int y0 = (int)floor(cy) - hd, ny = 2 * hd + 1;
            memset(patch, 0, (size_t)nx * ny * sizeof *patch);
            calib_ellipse_add(&gl, cx, cy, ax, ay, s, x0, y0, nx, ny, amp, patch, work);
            for (int b = 0; b < ny; b++) {
                int y = y0 + b;
                if (y < 0 || y >= im->h)
                    continue;
                for (int a = 0; a < nx; a++) {
                    int x = x0 + a;
                    if (x >= 0 && x < im->w)
                        dk[(size_t)y * im->w + x] += patch[(size_t)b * nx + a];
                }
            }
        }
    }
    st = finish(&sc, q, dk, im);
out_free:
    free(q);
    free(dk);
    free(patch);
    free(work);
    return st;
}
