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
    const double cases[][5] = {{1.33, 1.88, 0.31, 0, 0},      {1.33, 1.88, 0.31, 1.2, 0.4},
                               {1.33, 1.88, 1.7731, 0, 0},    {1.33, 1.88, 1.7731, 2.3, -1.1},
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

/* A thin P-PIV sheet (Gauss, independent of x*): no inclination, e* read directly. */
static void sheet_gauss_recovered(void)
{
    rpiv_sheet_params sp = rpiv_sheet_params_default();
    sp.kind = RPIV_SHEET_GAUSS;
    sp.zb_star = 0.3187;
    sp.e_star = 0.0513;
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rp.noise = 0.01 * rp.level;
    const double xf[2] = {4.1187, 6.0219};
    rpiv_image *ims[2] = {0};
    rpiv_calib_shot shots[2];
    CHECK_OK(render_plates(&sp, &rp, xf, 2, 560, 24, ims, shots));
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_sheet_params p = rpiv_calib_sheet_params_default();
    p.geom.dark = rp.dark;
    rpiv_calib_sheet_result *r = NULL;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, shots, 2, NULL, &r));
    if (r) {
        for (size_t i = 0; i < 2; i++) {
            const rpiv_calib_sheet_plate *pl = &r->plate[i];
            printf("  gauss sheet, plate x*_f %.4f: z*_max %.4f (0.3187) e* %.4f (0.0513) "
                   "z*_inf %.4f z*_sup %.4f (%.4f %.4f)\n",
                   xf[i], pl->at.zmax, pl->at.e, pl->at.zinf, pl->at.zsup, 0.3187 - 0.0513 / 2,
                   0.3187 + 0.0513 / 2);
            CHECK_NEAR(pl->at.zmax, 0.3187, 0.02);
            CHECK_NEAR(pl->at.e, 0.0513, 0.02);
            CHECK_NEAR(pl->at.zinf, 0.3187 - 0.0513 / 2, 0.02);
            CHECK_NEAR(pl->at.zsup, 0.3187 + 0.0513 / 2, 0.02);
        }
        CHECK_NEAR(r->zm1, 0, 0.004);
        CHECK_NEAR(r->e1, 0, 0.004);
    }
    rpiv_calib_sheet_result_free(r);
    for (size_t i = 0; i < 2; i++)
        img_free(ims[i]);
}

static rpiv_sheet_params default_selfsim(void)
{
    rpiv_sheet_params sp = rpiv_sheet_params_default();
    sp.kind = RPIV_SHEET_SELFSIM;
    return sp;
}

/* Foot and angle detected from the plate's faint glow; a mirrored plate (rising toward -x). */
static void sheet_plate_edges_detected(void)
{
    rpiv_sheet_params sp = default_selfsim();
    truth t = {sp.e0, sp.e1, sp.zm0, sp.zm1, sp.skew};
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rp.glow = 0.1 * rp.level;
    rp.noise = 0.005 * rp.level;
    rp.foot_px = 52.713;
    const double xf[1] = {6.2131};
    rpiv_image *im = NULL;
    rpiv_calib_shot shot;
    CHECK_OK(render_plates(&sp, &rp, xf, 1, 600, 24, &im, &shot));
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_sheet_params p = rpiv_calib_sheet_params_default();
    p.geom.dark = rp.dark;
    p.geom.angle_deg = 0; /* detect */
    shot.foot_px = (double)NAN;
    rpiv_calib_sheet_result *r = NULL;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r));
    if (r) {
        const rpiv_calib_sheet_plate *pl = &r->plate[0];
        printf("  detected foot %.3f px (52.713), angle %.3f deg (45); z*_max %.4f (%.4f) on the "
               "plate\n",
               pl->foot_px, pl->angle_deg, pl->raw.zmax, t_zmax(&t, pl->x_max));
        CHECK_NEAR(pl->foot_px, 52.713, 0.5);
        CHECK_NEAR(pl->angle_deg, 45, 0.3);
        CHECK_NEAR(pl->raw.zmax, t_zmax(&t, pl->x_max), 0.02);
        CHECK_NEAR(pl->raw.zinf, t_zinf(&t, pl->x_inf), 0.02);
        CHECK_NEAR(pl->raw.zsup, t_zsup(&t, pl->x_sup), 0.02);
    }
    rpiv_calib_sheet_result_free(r);
    img_free(im);
    /* mirrored: the plate rises toward decreasing image x, foot on the right */
    rp.angle_deg = -45;
    rp.foot_px = 600 - 52.713;
    rp.glow = 0;
    CHECK_OK(render_plates(&sp, &rp, xf, 1, 600, 24, &im, &shot));
    p.geom.angle_deg = -45;
    r = NULL;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r));
    if (r) {
        const rpiv_calib_sheet_plate *pl = &r->plate[0];
        printf("  mirrored plate: z*_max %.4f (%.4f), x*_max %.4f\n", pl->raw.zmax,
               t_zmax(&t, pl->x_max), pl->x_max);
        CHECK(pl->x_max < xf[0]);
        CHECK_NEAR(pl->raw.zmax, t_zmax(&t, pl->x_max), 0.02);
        CHECK_NEAR(pl->raw.zinf, t_zinf(&t, pl->x_inf), 0.02);
        CHECK_NEAR(pl->raw.zsup, t_zsup(&t, pl->x_sup), 0.02);
    }
    rpiv_calib_sheet_result_free(r);
    img_free(im);
}

/* The profile file is read back by the sheet module (generator, CCM) as the measured sheet. */
static void sheet_profile_file_round_trip(void)
{
    rpiv_sheet_params sp = default_selfsim();
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rpiv_image *ims[NPL] = {0};
    rpiv_calib_shot shots[NPL];
    CHECK_OK(render_plates(&sp, &rp, plate_x, NPL, 560, 8, ims, shots));
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_sheet_params p = rpiv_calib_sheet_params_default();
    p.geom.dark = rp.dark;
    rpiv_calib_sheet_result *r = NULL;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, shots, NPL, NULL, &r));
    char path[64];
    snprintf(path, sizeof path, "test_calib_profile_%ld.txt", (long)getpid());
    if (r) {
        CHECK_OK(rpiv_calib_sheet_save_profile(r, path));
        rpiv_sheet_params lp = rpiv_sheet_params_default();
        lp.kind = RPIV_SHEET_SELFSIM;
        snprintf(lp.profile, sizeof lp.profile, "%s", path);
        rpiv_sheet *truth_s = NULL, *meas = NULL;
        CHECK_OK(rpiv_sheet_new(&sp, &truth_s));
        CHECK_OK(rpiv_sheet_new(&lp, &meas));
        if (truth_s && meas) {
            double dmax = 0;
            for (double x = 4.5; x <= 8.0; x += 0.25)
                for (double z = 0.05; z <= 0.95; z += 0.01)
                    dmax = fmax(dmax,
                                fabs(rpiv_sheet_eval(meas, x, z) - rpiv_sheet_eval(truth_s, x, z)));
            printf("  profile file read back: max |I0_measured - I0_true| = %.4f over x* "
                   "4.5..8, z* 0.05..0.95\n",
                   dmax);
            CHECK(dmax < 0.05);
        }
        rpiv_sheet_free(truth_s);
        rpiv_sheet_free(meas);
        remove(path);
        FILE *fp = tmpfile();
        CHECK(fp != NULL);
        if (fp) {
            CHECK_OK(rpiv_calib_sheet_write_plates(r, fp));
            CHECK_OK(rpiv_calib_sheet_write_profiles(r, fp));
            CHECK(ftell(fp) > 1000);
            fclose(fp);
        }
        /* an unwritable place */
        CHECK_FAILS(rpiv_calib_sheet_save_profile(r, "/nonexistent-dir/profile.txt"), RPIV_EIO);
    }
    rpiv_calib_sheet_result_free(r);
    for (size_t i = 0; i < NPL; i++)
        img_free(ims[i]);
}

/* Dark image and dark region give the same dark level as the scalar. */
static void sheet_dark_sources_agree(void)
{
    rpiv_sheet_params sp = default_selfsim();
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rp.background = 0;
    rp.dark = 131.7;
    const double xf[1] = {5.7};
    rpiv_image *im = NULL;
    rpiv_calib_shot shot;
    CHECK_OK(render_plates(&sp, &rp, xf, 1, 560, 8, &im, &shot));
    rpiv_image *dark = img_new(560, 8);
    for (size_t i = 0; dark && i < 560 * 8; i++)
        dark->px[i] = 131.7f;
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_sheet_params p = rpiv_calib_sheet_params_default();
    p.subtract_floor = 0;
    p.geom.dark = 131.7;
    rpiv_calib_sheet_result *a = NULL, *b = NULL, *c = NULL;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &a));
    p.geom.dark = 0;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, dark, &b));
    p.geom.dark_w = 12;
    p.geom.dark_h = 8;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &c));
    if (a && b && c) {
        CHECK_NEAR(c->plate[0].dark, 131.7, 1e-3);
        CHECK_NEAR(a->plate[0].raw.e, b->plate[0].raw.e, 1e-6);
        CHECK_NEAR(a->plate[0].raw.e, c->plate[0].raw.e, 1e-4);
        CHECK_NEAR(a->plate[0].raw.zmax, c->plate[0].raw.zmax, 1e-4);
    }
    /* a wrong dark level without the floor subtraction shows in e* (the check can fail) */
    p.geom.dark_w = 0;
    p.geom.dark = 0;
    rpiv_calib_sheet_result *d = NULL;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &d));
    if (a && d)
        CHECK(fabs(d->plate[0].raw.e - a->plate[0].raw.e) > 0.01);
    rpiv_calib_sheet_result_free(a);
    rpiv_calib_sheet_result_free(b);
    rpiv_calib_sheet_result_free(c);
    rpiv_calib_sheet_result_free(d);
    img_free(dark);
    img_free(im);
}

static void sheet_errors_have_clear_statuses(void)
{
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_sheet_params p = rpiv_calib_sheet_params_default();
    rpiv_calib_sheet_result *r = (rpiv_calib_sheet_result *)&p; /* must be reset to NULL */
    rpiv_image *blank = img_new(400, 8);
    for (size_t i = 0; blank && i < 400 * 8; i++)
        blank->px[i] = 100;
    rpiv_calib_shot shot = {blank, 30.5, 5};
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(r == NULL);
    CHECK(strstr(rpiv_errmsg(), "image 1: blank") != NULL);
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 0, NULL, &r), RPIV_EINVAL);
    p.geom.angle_deg = 3;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "angle 3") != NULL);
    p.geom.angle_deg = 88;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_EINVAL);
    p.geom.angle_deg = 45;
    p.geom.row0 = 5;
    p.geom.row1 = 3;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_EINVAL);
    p.geom.row0 = 0;
    p.geom.row1 = 20;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ESIZE);
    p.geom.row1 = 0;
    p.geom.dark_w = 10;
    p.geom.dark_h = 10;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ESIZE);
    p.geom.dark_w = 0;
    p.geom.dark_h = 0;
    rpiv_image *dark = img_new(399, 8);
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, dark, &r), RPIV_ESIZE);
    img_free(dark);
    p.smooth_px = -1;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_EINVAL);
    p.smooth_px = 0;
    /* the sheet misses the plate: nothing but the plate's glow */
    rpiv_sheet_params sp = default_selfsim();
    sp.zm0 = 3;
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rp.glow = 30;
    const double xf[1] = {5.3};
    rpiv_image *im = NULL;
    rpiv_calib_shot s2;
    CHECK_OK(render_plates(&sp, &rp, xf, 1, 560, 8, &im, &s2));
    p.geom.dark = rp.dark;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &s2, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "no sheet") != NULL);
    printf("  sheet off the plate: %s\n", rpiv_errmsg());
    img_free(im);
    /* the sheet is cut by the channel top: no quarter-height crossing above the peak */
    sp = default_selfsim();
    sp.zm0 = 0.45;
    CHECK_OK(render_plates(&sp, &rp, xf, 1, 560, 8, &im, &s2));
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &s2, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "does not fall to 0.25 above") != NULL);
    printf("  sheet cut by the top: %s\n", rpiv_errmsg());
    img_free(im);
    /* a plate darker than the floor: the foot is still found (step down) */
    rp.glow = 0.02 * rp.level;
    rp.background = 0.1 * rp.level;
    sp = default_selfsim();
    CHECK_OK(render_plates(&sp, &rp, xf, 1, 560, 8, &im, &s2));
    s2.foot_px = (double)NAN;
    CHECK_OK(rpiv_calib_sheet_run(&p, &cam, &ch, &s2, 1, NULL, &r));
    if (r) {
        printf("  plate darker than the floor: foot %.3f px (%.4f)\n", r->plate[0].foot_px,
               rp.foot_px);
        CHECK_NEAR(r->plate[0].foot_px, rp.foot_px, 0.5);
    }
    rpiv_calib_sheet_result_free(r);
    r = NULL;
    img_free(im);
    /* noise only: no edge to detect */
    unsigned long lcg = 12345;
    for (size_t i = 0; blank && i < 400 * 8; i++) {
        lcg = lcg * 6364136223846793005UL + 1442695040888963407UL;
        blank->px[i] = (float)(100 + (double)(lcg >> 40) / (double)(1UL << 24));
    }
    shot.foot_px = (double)NAN;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "cannot detect the plate foot") != NULL);
    printf("  foot in noise: %s\n", rpiv_errmsg());
    /* the same noise with the foot given: no sheet */
    shot.foot_px = 30.5;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "no sheet") != NULL);
    printf("  noise only: %s\n", rpiv_errmsg());
    img_free(blank);
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
        double zd = h * fabs(z[i] - cam->zop_star) / cam->n_medium; /* apparent depth */
        double da = cam->focal_m / cam->fnumber;
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

static rpiv_image *render_target(const rpiv_camera *cam, const rpiv_calib_render_params *rp, int w,
                                 int h)
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
    rpiv_calib_shot shot = {im, rp.foot_px, (double)NAN};
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
               name, r->ndots, r->curve.n, r->curve.zop, cam.zop_star, r->curve.zmid, r->curve.dof,
               dof_ref, mc.dof, r->curve.inv_max);
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

/* Two images of the target at different places, feet detected from the plate's edge: the dots
 * are pooled by z*. */
static void dof_pooled_shots_with_detected_feet(void)
{
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rp.noise = 0.005 * rp.level;
    rpiv_image *a = render_target(&cam, &rp, 560, 40);
    rp.foot_px = 47.9131;
    rp.phase_x = 0.7219;
    rp.seed = 7;
    rpiv_image *b = render_target(&cam, &rp, 560, 40);
    CHECK(a && b);
    if (!a || !b) {
        img_free(a);
        img_free(b);
        return;
    }
    rpiv_calib_dof_params p = rpiv_calib_dof_params_default();
    p.geom.dark = rp.dark;
    rpiv_calib_shot shots[2] = {{a, (double)NAN, (double)NAN}, {b, (double)NAN, (double)NAN}};
    rpiv_calib_dof_result *r = NULL;
    CHECK_OK(rpiv_calib_dof_run(&p, &cam, &ch, shots, 2, NULL, &r));
    rpiv_calib_focus mc;
    CHECK_OK(rpiv_calib_dof_model(&p, &cam, ch.h_m, rp.reflectance, 0.005, &mc));
    if (r) {
        printf("  pooled: feet %.3f, %.3f px (40.3187, 47.9131); %zu dots, %zu columns; z*_OP "
               "%.4f, DOF* %.4f (model %.4f)\n",
               r->foot_px[0], r->foot_px[1], r->ndots, r->curve.n, r->curve.zop, r->curve.dof,
               mc.dof);
        CHECK_NEAR(r->foot_px[0], 40.3187, 1);
        CHECK_NEAR(r->foot_px[1], 47.9131, 1);
        CHECK_NEAR(r->curve.zop, cam.zop_star, 0.02);
        CHECK_NEAR(r->curve.dof, mc.dof, 0.02);
        double rho = -1;
        CHECK_OK(rpiv_calib_dof_reflectance(&p, &cam, ch.h_m, r->curve.inv_max, &rho));
        printf("  dot reflectance inferred from the measured peak 1/I* %.3f: %.4f (0.1)\n",
               r->curve.inv_max, rho);
        CHECK_NEAR(rho, rp.reflectance, 0.02);
        CHECK_FAILS(rpiv_calib_dof_reflectance(&p, &cam, ch.h_m, 500, &rho), RPIV_ENUMERIC);
        FILE *fp = tmpfile();
        CHECK(fp != NULL);
        if (fp) {
            CHECK_OK(rpiv_calib_focus_write(&r->curve, fp));
            CHECK(ftell(fp) > 100 * (long)r->curve.n / 4);
            CHECK_OK(rpiv_calib_dof_write_dots(r, fp));
            fclose(fp);
        }
    }
    rpiv_calib_focus_free(&mc);
    rpiv_calib_dof_result_free(r);
    img_free(a);
    img_free(b);
}

/* The paper measured DOF* = 0.43 at f# 5.6 (its Fig. 13). What the model gives for the default
 * camera depends on how dark the dots are; the finding is printed, and the checks are the
 * model's own properties: darker dots give a narrower curve, and 1/I* (with its baseline) is
 * narrower than the darkness 1 - I*. */
static void dof_default_camera_model_finding(void)
{
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_dof_params p = rpiv_calib_dof_params_default();
    const double refl[] = {0.02, 0.05, 0.1, 0.2, 0.3};
    double prev = 0;
    for (size_t i = 0; i < sizeof refl / sizeof refl[0]; i++) {
        rpiv_calib_focus c;
        CHECK_OK(rpiv_calib_dof_model(&p, &cam, ch.h_m, refl[i], 0.005, &c));
        printf("  default camera (f 135 mm, f# 5.6, M 0.39, s0 500 mm, h 8 mm), dots %.3g "
               "reflectance: DOF* %.3f (1/I* - 1), %.3f (1/I* alone), %.3f (darkness); 1/I* max "
               "%.2f; paper 0.43\n",
               refl[i], c.dof, c.dof_raw, c.dof_contrast, c.inv_max);
        CHECK(c.dof > prev);
        CHECK(c.dof < c.dof_contrast);
        CHECK_NEAR(c.zop, cam.zop_star, 0.003);
        prev = c.dof;
        rpiv_calib_focus_free(&c);
    }
}

static void dof_errors_have_clear_statuses(void)
{
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_calib_dof_params p = rpiv_calib_dof_params_default();
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    p.geom.dark = rp.dark;
    rpiv_calib_dof_result *r = NULL;
    /* blank */
    rpiv_image *im = img_new(560, 24);
    for (size_t i = 0; im && i < 560 * 24; i++)
        im->px[i] = 2000;
    rpiv_calib_shot shot = {im, rp.foot_px, (double)NAN};
    CHECK_FAILS(rpiv_calib_dof_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(r == NULL && strstr(rpiv_errmsg(), "blank") != NULL);
    img_free(im);
    /* dots too faint to find */
    rp.reflectance = 0.995;
    im = render_target(&cam, &rp, 560, 24);
    shot.image = im;
    CHECK_FAILS(rpiv_calib_dof_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "no dots found") != NULL);
    printf("  faint dots: %s\n", rpiv_errmsg());
    img_free(im);
    rp.reflectance = 0.1;
    /* a lens whose depth of focus is wider than the target */
    rpiv_camera wide = cam;
    wide.fnumber = 16;
    im = render_target(&wide, &rp, 560, 24);
    shot.image = im;
    CHECK_FAILS(rpiv_calib_dof_run(&p, &wide, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "wider than the target") != NULL);
    printf("  f# 22: %s\n", rpiv_errmsg());
    /* the dots are not resolved at this scale */
    shot.image = im;
    p.geom.scale_px_m = 2e4;
    CHECK_FAILS(rpiv_calib_dof_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "at least 3 px") != NULL);
    p.geom.scale_px_m = 0;
    /* parameters */
    p.pitch_m = 50e-6;
    CHECK_FAILS(rpiv_calib_dof_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "pitch") != NULL);
    p.pitch_m = 125e-6;
    p.geom.angle_deg = -90;
    CHECK_FAILS(rpiv_calib_dof_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_EINVAL);
    p.geom.angle_deg = 45;
    CHECK_FAILS(rpiv_calib_dof_run(&p, &cam, &ch, &shot, 0, NULL, &r), RPIV_EINVAL);
    rpiv_calib_focus c;
    CHECK_FAILS(rpiv_calib_dof_model(&p, &cam, ch.h_m, 1.0, 0.005, &c), RPIV_EINVAL);
    /* the model agrees that this lens' depth of focus exceeds the target's z* range of 1 */
    CHECK_OK(rpiv_calib_dof_model(&p, &wide, ch.h_m, 0.1, 0.01, &c));
    CHECK(c.dof > 0.8);
    rpiv_calib_focus_free(&c);
    CHECK_FAILS(rpiv_calib_dof_model(&p, &wide, ch.h_m, 0.1, 0.5, &c), RPIV_EINVAL);
    /* render parameters */
    rp.angle_deg = 0;
    CHECK_FAILS(rpiv_calib_render_dots(&rp, &cam, &ch, im), RPIV_EINVAL);
    rp.angle_deg = 45;
    rp.pitch_m = rp.dot_d_m;
    CHECK_FAILS(rpiv_calib_render_dots(&rp, &cam, &ch, im), RPIV_EINVAL);
    img_free(im);
}

/* The remaining failure paths of the plate geometry and of the parameters. */
static void geometry_and_parameter_errors(void)
{
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_sheet_params sp = default_selfsim();
    rpiv_calib_render_params rp = rpiv_calib_render_params_default();
    rp.glow = 0.1 * rp.level;
    const double xf[1] = {5.3};
    rpiv_image *im = NULL;
    rpiv_calib_shot shot;
    CHECK_OK(render_plates(&sp, &rp, xf, 1, 560, 8, &im, &shot));
    rpiv_calib_sheet_params p = rpiv_calib_sheet_params_default();
    p.geom.dark = rp.dark;
    rpiv_calib_sheet_result *r = NULL;
    /* the angle detected from a plate said to be 1 m high is out of range */
    p.geom.angle_deg = 0;
    p.geom.plate_height_m = 1;
    shot.foot_px = (double)NAN;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "detected plate angle") != NULL);
    p.geom.angle_deg = 45;
    p.geom.plate_height_m = 0;
    /* an edge window wider than a quarter of the image */
    p.geom.edge_window = 200;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "too narrow") != NULL);
    p.geom.edge_window = 8;
    /* the plate is off the image */
    shot.foot_px = 900;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "at least 8 needed") != NULL);
    img_free(im);
    /* a plate that starts at the image's right edge */
    rp.foot_px = 553.4;
    CHECK_OK(render_plates(&sp, &rp, xf, 1, 560, 8, &im, &shot));
    shot.foot_px = (double)NAN;
    CHECK_FAILS(rpiv_calib_sheet_run(&p, &cam, &ch, &shot, 1, NULL, &r), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "too close to the image edge") != NULL);
    img_free(im);
    /* parameters */
    rpiv_calib_sheet_params q = rpiv_calib_sheet_params_default();
    q.margin = 0.5;
    CHECK_FAILS(rpiv_calib_sheet_params_check(&q), RPIV_EINVAL);
    q = rpiv_calib_sheet_params_default();
    q.zplus_step = 0;
    CHECK_FAILS(rpiv_calib_sheet_params_check(&q), RPIV_EINVAL);
    q = rpiv_calib_sheet_params_default();
    q.min_signal = -1;
    CHECK_FAILS(rpiv_calib_sheet_params_check(&q), RPIV_EINVAL);
    q = rpiv_calib_sheet_params_default();
    q.geom.edge_window = 1;
    CHECK_FAILS(rpiv_calib_sheet_params_check(&q), RPIV_EINVAL);
    q.geom.edge_window = 8;
    q.geom.dark_w = 4; /* no height */
    CHECK_FAILS(rpiv_calib_sheet_params_check(&q), RPIV_EINVAL);
    rpiv_calib_dof_params d = rpiv_calib_dof_params_default();
    CHECK_OK(rpiv_calib_dof_params_check(&d));
    d.min_contrast = 0;
    CHECK_FAILS(rpiv_calib_dof_params_check(&d), RPIV_EINVAL);
    d = rpiv_calib_dof_params_default();
    d.fit_columns = -1;
    CHECK_FAILS(rpiv_calib_dof_params_check(&d), RPIV_EINVAL);
    d = rpiv_calib_dof_params_default();
    d.ref_cells = 0;
    CHECK_FAILS(rpiv_calib_dof_params_check(&d), RPIV_EINVAL);
    d = rpiv_calib_dof_params_default();
    d.lattice_tol = 0.7;
    CHECK_FAILS(rpiv_calib_dof_params_check(&d), RPIV_EINVAL);
    d = rpiv_calib_dof_params_default();
    d.min_snr = -1;
    CHECK_FAILS(rpiv_calib_dof_params_check(&d), RPIV_EINVAL);
    /* a target image with too few columns of dots */
    rpiv_calib_render_params rd = rpiv_calib_render_params_default();
    rd.foot_px = 10.3187;
    rpiv_image *t = render_target(&cam, &rd, 36, 32);
    CHECK(t != NULL);
    if (t) {
        rpiv_calib_dof_params dp = rpiv_calib_dof_params_default();
        dp.geom.dark = rd.dark;
        rpiv_calib_shot ts = {t, rd.foot_px, (double)NAN};
        rpiv_calib_dof_result *dr = NULL;
        CHECK_FAILS(rpiv_calib_dof_run(&dp, &cam, &ch, &ts, 1, NULL, &dr), RPIV_ENUMERIC);
        CHECK(strstr(rpiv_errmsg(), "columns of dots") != NULL);
        printf("  narrow target: %s\n", rpiv_errmsg());
    }
    img_free(t);
}

int main(void)
{
    rpiv_init();
    RUN_TEST(kernel_pixel_integrals_are_exact);
    RUN_TEST(kernel_ellipse_matches_brute_force);
    RUN_TEST(sheet_selfsim_recovered_at_several_plates);
    RUN_TEST(sheet_gauss_recovered);
    RUN_TEST(sheet_plate_edges_detected);
    RUN_TEST(sheet_profile_file_round_trip);
    RUN_TEST(sheet_dark_sources_agree);
    RUN_TEST(sheet_errors_have_clear_statuses);
    RUN_TEST(dof_default_lens_recovered);
    RUN_TEST(dof_noisy_nonuniform_light_recovered);
    RUN_TEST(dof_other_lens_recovered);
    RUN_TEST(dof_pooled_shots_with_detected_feet);
    RUN_TEST(dof_default_camera_model_finding);
    RUN_TEST(dof_errors_have_clear_statuses);
    RUN_TEST(geometry_and_parameter_errors);
    return check_summary();
}
