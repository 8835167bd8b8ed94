/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_calib.c - light-sheet and depth-of-focus calibration against target images
 * rendered from the imaging model with a known sheet, object plane and lens. */
#include "calib_impl.h"
#include "check.h"
#include "rpiv/calib.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Local image helpers: the tests build images in memory only. */
static rpiv_image *img_new(int w, int h)
{
    rpiv_image *im = calloc(1, sizeof *im);
    if (!im)
        return NULL;
    im->w = w;
    im->h = h;
    im->bits = 32;
    im->px = calloc((size_t)w * h, sizeof *im->px);
    if (!im->px) {
        free(im);
        return NULL;
    }
    return im;
}

static void img_free(rpiv_image *im)
{
    if (im)
        free(im->px);
    free(im);
}

/* ---- kernels ------------------------------------------------------------------------------- */

static double phi(double x)
{
    return 0.5 * erfc(-x / M_SQRT2);
}

static void kernel_pixel_integrals_are_exact(void)
{
    /* sum over pixels of the pixel-integrated Gaussian is 1; of the bar, its length 2w */
    double s = 0.8131, w = 1.7219, c = 0.3187, sum = 0, sumbar = 0;
    for (int x = -40; x <= 40; x++) {
        sum += calib_boxg(x - c, s);
        sumbar += calib_boxg_bar(x - c, w, s);
    }
    CHECK_NEAR(sum, 1, 1e-12);
    CHECK_NEAR(sumbar, 2 * w, 1e-10);
    /* the bar seen by one pixel, against a midpoint rule over the bar */
    double u = 0.6131, ref = 0;
    int n = 20000;
    for (int i = 0; i < n; i++) {
        double q = -w + (i + 0.5) * 2 * w / n;
        ref += calib_boxg(u - q, s) * 2 * w / n;
    }
    CHECK_NEAR(calib_boxg_bar(u, w, s), ref, 1e-8);
    /* far tails do not lose precision */
    CHECK(calib_boxg_bar(40.2, w, 0.3) >= 0 && calib_boxg_bar(40.2, w, 0.3) < 1e-12);
}

/* Independent brute force: darkness at the pixel centred on (px, py) of a unit ellipse at the
 * origin blurred by s: midpoint rule over the pixel and the ellipse rows, erf along x. */
static double ellipse_brute(double ax, double ay, double s, double px, double py, int nsub,
                            int nrow)
{
    double v = 0;
    for (int b = 0; b < nsub; b++)
        for (int a = 0; a < nsub; a++) {
            double x = px - 0.5 + (a + 0.5) / nsub, y = py - 0.5 + (b + 0.5) / nsub;
            for (int r = 0; r < nrow; r++) {
                double qy = -ay + (r + 0.5) * 2 * ay / nrow;
                double w = ax * sqrt(fmax(0, 1 - qy * qy / (ay * ay)));
                double gy = exp(-0.5 * (y - qy) * (y - qy) / (s * s)) / (s * sqrt(2 * M_PI));
                v += gy * (phi((x + w) / s) - phi((x - w) / s)) * 2 * ay / nrow;
            }
        }
    return v / (nsub * nsub);
}

static void kernel_ellipse_matches_brute_force(void)
{
    calib_gl gl;
    CHECK_OK(calib_gl_init(&gl));
    const double cases[][5] = {{1.33, 1.88, 0.31, 0, 0},     {1.33, 1.88, 0.31, 1.2, 0.4},
                               {1.33, 1.88, 1.7731, 0, 0},   {1.33, 1.88, 1.7731, 2.3, -1.1},
                               {5.2187, 3.1, 0.45, 0.3, 2.9}, {0.7, 0.9, 3.9, 0.5, 0.5}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const double *c = cases[i];
        double lib = calib_ellipse_at(&gl, 0, 0, c[0], c[1], c[2], c[3], c[4]);
        double ref = ellipse_brute(c[0], c[1], c[2], c[3], c[4], 24, 2000);
        CHECK_NEAR(lib, ref, 2e-4);
    }
    /* a big sharp ellipse is fully dark at its centre */
    CHECK_NEAR(calib_ellipse_at(&gl, 0, 0, 6, 8, 0.3, 0, 0), 1, 1e-9);
}

/* ---- sheet --------------------------------------------------------------------------------- */

typedef struct truth {
    double e0, e1, zm0, zm1, skew;
} truth;

static double t_zmax(const truth *t, double x)
{
    return t->zm0 + t->zm1 * x;
}
static double t_e(const truth *t, double x)
{
    return t->e0 + t->e1 * x;
}
/* quarter-height points of the default shape: -skew/(1+skew) and 1/(1+skew) of e* */
static double t_zinf(const truth *t, double x)
{
    return t_zmax(t, x) - t->skew / (1 + t->skew) * t_e(t, x);
}
static double t_zsup(const truth *t, double x)
{
    return t_zmax(t, x) + 1 / (1 + t->skew) * t_e(t, x);
}

static rpiv_status render_plates(const rpiv_sheet_params *sp, const rpiv_calib_render_params *rp0,
                                 const double *xf, size_t n, int w, int h, rpiv_image **ims,
                                 rpiv_calib_shot *shots)
{
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_sheet *sheet = NULL;
    rpiv_status st = rpiv_sheet_new(sp, &sheet);
    if (st)
        return st;
    for (size_t i = 0; i < n && !st; i++) {
        rpiv_calib_render_params rp = *rp0;
        rp.x_foot = xf[i];
        rp.seed = 11 + i;
        ims[i] = img_new(w, h);
        st = rpiv_calib_render_sheet(&rp, &cam, &ch, sheet, ims[i]);
        shots[i] = (rpiv_calib_shot){ims[i], rp.foot_px, xf[i]};
    }
    rpiv_sheet_free(sheet);
    return st;
}

#define NPL 4
static const double plate_x[NPL] = {3.9187, 5.2731, 6.6113, 7.8529};

static void sheet_selfsim_recovered_at_several_plates(void)
{
    truth t = {0.0213, 0.0583, 0.0412, 0.0731, 1.87};
    rpiv_sheet_params sp = rpiv_sheet_params_default();
    sp.kind = RPIV_SHEET_SELFSIM;
    sp.e0 = t.e0;
    sp.e1 = t.e1;
    sp.zm0 = t.zm0;
    sp.zm1 = t.zm1;
    sp.skew = t.skew;
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rp.noise = 0.01 * rp.level;
    rpiv_image *ims[NPL] = {0};
    rpiv_calib_shot shots[NPL];
    CHECK_OK(render_plates(&sp, &rp, plate_x, NPL, 560, 24, ims, shots));
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_sheet_params p = rpiv_calib_sheet_params_default();
    p.geom.dark = rp.dark;
    p.smooth_px = 3;
    rpiv_calib_sheet_result *r = NULL;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, shots, NPL, NULL, &r));
    if (r) {
        double worst = 0, worst_raw_e = 0;
        for (size_t i = 0; i < NPL; i++) {
            const rpiv_calib_sheet_plate *pl = &r->plate[i];
            double x = pl->x_max;
            printf("  plate x*_f %.4f: x*_max %.4f  z*_inf %.4f (%.4f) z*_max %.4f (%.4f) "
                   "z*_sup %.4f (%.4f) e* %.4f (%.4f), raw e* %.4f, shape rms %.4f\n",
                   plate_x[i], x, pl->at.zinf, t_zinf(&t, x), pl->at.zmax, t_zmax(&t, x),
                   pl->at.zsup, t_zsup(&t, x), pl->at.e, t_e(&t, x), pl->raw.e, pl->shape_rms);
            CHECK_NEAR(pl->at.zmax, t_zmax(&t, x), 0.02);
            CHECK_NEAR(pl->at.zinf, t_zinf(&t, x), 0.02);
            CHECK_NEAR(pl->at.zsup, t_zsup(&t, x), 0.02);
            CHECK_NEAR(pl->at.e, t_e(&t, x), 0.02);
            /* the raw points lie on the true lines at their own x* */
            CHECK_NEAR(pl->raw.zmax, t_zmax(&t, pl->x_max), 0.02);
            CHECK_NEAR(pl->raw.zinf, t_zinf(&t, pl->x_inf), 0.02);
            CHECK_NEAR(pl->raw.zsup, t_zsup(&t, pl->x_sup), 0.02);
            worst = fmax(worst, fabs(pl->at.e - t_e(&t, x)));
            worst_raw_e = fmax(worst_raw_e, fabs(pl->raw.e - t_e(&t, x)));
        }
        printf("  fit: e0 %.4f (%.4f) e1 %.5f (%.5f) zm0 %.4f (%.4f) zm1 %.5f (%.5f); worst |de*| "
               "%.4f corrected, %.4f read along the plate\n",
               r->e0, t.e0, r->e1, t.e1, r->zm0, t.zm0, r->zm1, t.zm1, worst, worst_raw_e);
        CHECK_NEAR(r->e1, t.e1, 0.004);
        CHECK_NEAR(r->zm1, t.zm1, 0.004);
        CHECK_NEAR(r->e0, t.e0, 0.02);
        CHECK_NEAR(r->zm0, t.zm0, 0.02);
        /* the mean shape is the default skewed shape */
        double ln4 = log(4), wl = t.skew / (1 + t.skew), wu = 1 / (1 + t.skew), dmax = 0;
        for (size_t j = 0; j < r->nshape; j++) {
            double zp = r->zplus[j], ww = zp < 0 ? wl : wu;
            double dd = fabs(r->shape[j] - exp(-ln4 * zp * zp / (ww * ww)));
            dmax = fmax(dmax, dd);
        }
        printf("  mean shape: %zu rows z+ %.2f..%.2f, max |S - S_true| %.4f\n", r->nshape,
               r->zplus[0], r->zplus[r->nshape - 1], dmax);
        CHECK(dmax < 0.03);
    }
    rpiv_calib_sheet_result_free(r);
    for (size_t i = 0; i < NPL; i++)
        img_free(ims[i]);
}

/* ---- depth of focus ------------------------------------------------------------------------ */

/* Independent model of the focus curve: darkness of the pixel nearest a dot centre (the centre
 * uniform in that pixel: pixel box and phase make a triangular weight on [-1, 1] per axis), for
 * an infinite lattice of ellipses blurred by the Gaussian of Eq. "diam" (written out here),
 * by midpoint rules: rows of the ellipse, then per row the y and x weights summed over the
 * lattice rows and columns. I* is relative to the lattice mean; returns the FWHM of
 * (1/I* - 1) and its centre. */
static void model_dof_brute(const rpiv_camera *cam, double h, double dot_d, double pitch,
                            double angle_deg, double refl, double *dof, double *zc)
{
    double m = cam->magnification, scale = m / rpiv_camera_pixel_m(cam);
    double ca = cos(angle_deg * M_PI / 180), r = 0.5 * dot_d * scale, ax = r * ca, ay = r;
    double ppx = pitch * ca * scale, ppy = pitch * scale, fill = M_PI * ax * ay / (ppx * ppy);
    enum { N = 91, NSUB = 40, NROW = 200 };
    double z[N], g[N], gmax = 0;
    for (int i = 0; i < N; i++) {
        z[i] = cam->zop_star - 0.45 + 0.01 * i;
        double zd = h * fabs(z[i] - cam->zop_star), da = cam->focal_m / cam->fnumber;
        double dif = (m + 1) * cam->lambda_p_m * cam->fnumber, foc = m * zd * da / (cam->s0_m + zd);
        double s = sqrt(5.95 * dif * dif + foc * foc) / sqrt(8 * cam->beta2) * scale / m;
        int kx = (int)ceil((ax + 7 * s + 2) / ppx), ky = (int)ceil((ay + 7 * s + 2) / ppy);
        double dark = 0;
        for (int row = 0; row < NROW; row++) {
            double qy = -ay + (row + 0.5) * 2 * ay / NROW;
            double w = ax * sqrt(1 - qy * qy / (ay * ay)), sy = 0, sx = 0;
            for (int b = 0; b < NSUB; b++) {
                double t = -1 + (b + 0.5) * 2.0 / NSUB, wt = (1 - fabs(t)) * 2.0 / NSUB;
                for (int j = -ky; j <= ky; j++) {
                    double d = t - j * ppy - qy;
                    sy += wt * exp(-0.5 * d * d / (s * s)) / (s * sqrt(2 * M_PI));
                }
                for (int ii = -kx; ii <= kx; ii++) {
                    double u = t - ii * ppx;
                    sx += wt * (phi((u + w) / s) - phi((u - w) / s));
                }
            }
            dark += sy * sx * 2 * ay / NROW;
        }
        double istar = (1 - (1 - refl) * dark) / (1 - (1 - refl) * fill);
        g[i] = 1 / istar - 1;
        gmax = fmax(gmax, g[i]);
    }
    int k = 0;
    while (g[k] < 0.5 * gmax)
        k++;
    double lo = z[k - 1] + (0.5 * gmax - g[k - 1]) / (g[k] - g[k - 1]) * 0.01;
    k = N - 1;
    while (g[k] < 0.5 * gmax)
        k--;
    double hi = z[k] + (g[k] - 0.5 * gmax) / (g[k] - g[k + 1]) * 0.01;
    *dof = hi - lo;
    *zc = 0.5 * (lo + hi);
}

static rpiv_image *render_target(const rpiv_camera *cam, const rpiv_calib_render_params *rp,
                                 int w, int h)
{
    rpiv_channel ch = rpiv_channel_default();
    rpiv_image *im = img_new(w, h);
    if (im && rpiv_calib_render_dots(rp, cam, &ch, im) != RPIV_OK) {
        fprintf(stderr, "render: %s\n", rpiv_errmsg());
        img_free(im);
        return NULL;
    }
    return im;
}

static void dof_case(const char *name, rpiv_camera cam, double noise, double slope)
{
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rp.noise = noise * rp.level;
    rp.white_slope = slope;
    rpiv_image *im = render_target(&cam, &rp, 560, 64);
    CHECK(im != NULL);
    if (!im)
        return;
    rpiv_calib_dof_params p = rpiv_calib_dof_params_default();
    p.geom.dark = rp.dark;
    rpiv_calib_shot shot = {im, rp.foot_px, NAN};
    rpiv_calib_dof_result *r = NULL;
    CHECK_OK(rpiv_calib_dof_run(&p, &cam, &ch, &shot, 1, NULL, &r));
    double dof_ref, zc_ref;
    model_dof_brute(&cam, ch.h_m, rp.dot_d_m, rp.pitch_m, rp.angle_deg, rp.reflectance, &dof_ref,
                    &zc_ref);
    rpiv_calib_focus mc;
    CHECK_OK(rpiv_calib_dof_model(&p, &cam, ch.h_m, rp.reflectance, 0.005, &mc));
    if (r) {
        printf("  %s: %zu dots in %zu columns; z*_OP %.4f (true %.4f, FWHM midpoint %.4f), DOF* "
               "%.4f (model: brute force %.4f, library %.4f); 1/I* max %.3f\n",
               name, r->ndots, r->curve.n, r->curve.zop, cam.zop_star, r->curve.zmid,
               r->curve.dof, dof_ref, mc.dof, r->curve.inv_max);
        CHECK_NEAR(r->curve.zop, cam.zop_star, 0.02);
        CHECK_NEAR(r->curve.zmid, cam.zop_star, 0.02);
        CHECK_NEAR(r->curve.dof, dof_ref, 0.02);
        CHECK_NEAR(mc.dof, dof_ref, 0.002);
        CHECK_NEAR(zc_ref, cam.zop_star, 1e-3);
    }
    rpiv_calib_focus_free(&mc);
    rpiv_calib_dof_result_free(r);
    img_free(im);
}

static void dof_default_lens_recovered(void)
{
    dof_case("f# 5.6, z*_OP 0.45, no noise", rpiv_camera_default(), 0, 0);
}

static void dof_noisy_nonuniform_light_recovered(void)
{
    rpiv_camera cam = rpiv_camera_default();
    cam.zop_star = 0.3817;
    dof_case("f# 5.6, z*_OP 0.3817, noise 1 %, light -12 %..+12 %", cam, 0.01, 0.24);
}

static void dof_other_lens_recovered(void)
{
    rpiv_camera cam = rpiv_camera_default();
    cam.fnumber = 8;
    cam.zop_star = 0.5213;
    dof_case("f# 8, z*_OP 0.5213, noise 0.5 %", cam, 0.005, 0);
}

int main(void)
{
    rpiv_init();
    RUN_TEST(kernel_pixel_integrals_are_exact);
    RUN_TEST(kernel_ellipse_matches_brute_force);
    RUN_TEST(sheet_selfsim_recovered_at_several_plates);
    RUN_TEST(dof_default_lens_recovered);
    RUN_TEST(dof_noisy_nonuniform_light_recovered);
    RUN_TEST(dof_other_lens_recovered);
    return check_summary();
}
