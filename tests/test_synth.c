/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "rpiv/config.h"
#include "rpiv/piv.h"
#include "rpiv/synth.h"

#include <gsl/gsl_integration.h>
#include <gsl/gsl_randist.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[] = "/tmp/rpiv-test-synth.XXXXXX";

static const char *write_file(const char *name, const char *text)
{
    static char path[256];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *fp = fopen(path, "w");
    if (fp) {
        fputs(text, fp);
        fclose(fp);
    }
    return path;
}

/* Images and fields made here so that the test needs only the synth module. */
static rpiv_image *image(int w, int h)
{
    rpiv_image *im = calloc(1, sizeof *im);
    im->w = w;
    im->h = h;
    im->px = calloc((size_t)w * (size_t)h, sizeof *im->px);
    return im;
}

static void image_free(rpiv_image *im)
{
    if (im)
        free(im->px);
    free(im);
}

/* A noiseless setup with a uniform sheet and a uniform flow. */
static rpiv_synth_setup quiet_experiment(int w, int h)
{
    rpiv_synth_setup e = rpiv_synth_setup_default();
    e.synth.width_px = w;
    e.synth.height_px = h;
    e.synth.shot_noise = 0;
    e.synth.read_noise = 0;
    e.synth.background = 0;
    e.sheet.kind = RPIV_SHEET_UNIFORM;
    e.particles.dp_sigma_m = 0;
    strcpy(e.synth.flow, "uniform:3.3187,-1.7421");
    return e;
}

/* Intensity centroid and second moments of im inside [x0, x1] x [y0, y1]. */
static void moments(const rpiv_image *im, int x0, int x1, int y0, int y1, double *sum, double *cx,
                    double *cy, double *vx, double *vy)
{
    double s = 0, sx = 0, sy = 0, sxx = 0, syy = 0;
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) {
            double v = (double)im->px[(size_t)y * (size_t)im->w + (size_t)x];
            s += v;
            sx += v * x;
            sy += v * y;
            sxx += v * x * x;
            syy += v * y * y;
        }
    *sum = s;
    *cx = sx / s;
    *cy = sy / s;
    if (vx)
        *vx = sxx / s - *cx * *cx;
    if (vy)
        *vy = syy / s - *cy * *cy;
}

/* Eq. "diam" by hand from the paper's numbers (the default camera). */
static double de_by_hand_m(double z)
{
    double m = 0.39, dp = 10e-6, lam = 570e-9, fn = 5.6, f = 0.135, s0 = 0.5, h = 8e-3;
    double da = f / fn, zp = h * fabs(z - 0.45) / 1.33; /* apparent depth in water */
    return sqrt(m * m * dp * dp + 5.95 * (m + 1) * (m + 1) * lam * lam * fn * fn +
                m * m * zp * zp * da * da / ((s0 + zp) * (s0 + zp)));
}

static void particle_count_matches_density_per_window(void)
{
    rpiv_synth_setup e = rpiv_synth_setup_default();
    e.particles.density_ppp = 0.05; /* the test's figures are for 0.05 (default 0.015) */
    e.synth.width_px = 512;
    e.synth.height_px = 384;
    strcpy(e.synth.flow, "uniform:3.3187,-1.7421");
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    double area = (512 + 32.0) * (384 + 32.0);
    CHECK(in.nparticles == (size_t)floor(0.05 * area + 0.5));
    enum { NP = 4, NW = 16 * 12 };
    static double cnt[NP * NW];
    memset(cnt, 0, sizeof cnt);
    for (int k = 0; k < NP; k++) {
        rpiv_synth_particle *p;
        size_t n;
        CHECK_OK(rpiv_synth_particles_new(s, (unsigned long)k, &p, &n));
        CHECK(n == in.nparticles);
        for (size_t i = 0; i < n; i++) {
            /* window (i, j) covers pixels 32i .. 32i+31, i.e. x in [32i - 0.5, 32i + 31.5) */
            double fx = (p[i].x + 0.5) / 32, fy = (p[i].y + 0.5) / 32;
            if (fx >= 0 && fx < 16 && fy >= 0 && fy < 12)
                cnt[k * NW + (int)fy * 16 + (int)fx] += 1;
            CHECK(p[i].z >= 0 && p[i].z < 1);
        }
        rpiv_synth_particles_free(p);
    }
    double mean = 0, var = 0;
    for (int i = 0; i < NP * NW; i++)
        mean += cnt[i];
    mean /= NP * NW;
    for (int i = 0; i < NP * NW; i++)
        var += (cnt[i] - mean) * (cnt[i] - mean);
    var /= NP * NW - 1;
    /* The count in the image is binomial(N, q), q = image / region area; the mean per window
     * over NP pairs has sd sqrt(NP N q (1-q)) / (NP NW). The per-window counts are multinomial:
     * variance lambda (1 - 1/(region/window)) ~ lambda; its estimate has relative sd
     * sqrt(2/(NP NW - 1)). Bounds: 4 sd. */
    double lambda = 0.05 * 1024, q = 512.0 * 384 / area, nn = (double)in.nparticles;
    double sd_mean = sqrt(NP * nn * q * (1 - q)) / (NP * NW);
    double expect_mean = nn * q / NW;
    printf("  windows: mean %.4f (expected %.4f = 0.05 x 1024 within rounding, sd %.4f), "
           "variance %.3f (Poisson %.3f)\n",
           mean, expect_mean, sd_mean, var, lambda);
    CHECK_NEAR(expect_mean, lambda, 0.01);
    CHECK_NEAR(mean, expect_mean, 4 * sd_mean);
    double var_expect = lambda * (1 - 1024 / area);
    CHECK_NEAR(var / var_expect, 1, 4 * sqrt(2.0 / (NP * NW - 1)));
    rpiv_synth_free(s);
}

static void single_particle_centroid_is_its_position(void)
{
    rpiv_synth_setup e = quiet_experiment(96, 64);
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_image *im = image(96, 64);
    /* defocused (sigma ~ 1 px) so that the pixel-integrated centroid has no sampling bias */
    rpiv_synth_particle p = {40.3187, 25.7421, 0.0318, 10e-6};
    double amp, de, sig;
    rpiv_synth_image_model(s, &p, &amp, &de, &sig);
    CHECK_OK(rpiv_synth_render(s, &p, 1, im));
    double sum, cx, cy;
    moments(im, 0, 95, 0, 63, &sum, &cx, &cy, NULL, NULL);
    printf("  centroid (%.6f, %.6f), sigma %.4f px, error (%.2e, %.2e) px\n", cx, cy, sig, cx - p.x,
           cy - p.y);
    CHECK(sig > 0.8);
    CHECK_NEAR(cx, 40.3187, 1e-3);
    CHECK_NEAR(cy, 25.7421, 1e-3);
    /* only a small neighbourhood is touched: nothing beyond radius_sigma sigma + 1 px */
    double r = e.synth.radius_sigma * sig + 1;
    int outside = 0;
    for (int y = 0; y < 64; y++)
        for (int x = 0; x < 96; x++)
            if ((fabs(x - p.x) > r || fabs(y - p.y) > r) && im->px[y * 96 + x] != 0)
                outside++;
    CHECK(outside == 0);
    image_free(im);
    rpiv_synth_free(s);
}

static void particle_diameter_follows_eq_diam(void)
{
    rpiv_synth_setup e = quiet_experiment(128, 128);
    e.synth.radius_sigma = 7; /* no truncation in the moments */
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    const double pix = 16.6e-3 / 2560, beta = sqrt(3.67);
    const double zs[] = {0.1318, 0.45, 0.8213, 0.9871};
    for (int k = 0; k < 4; k++) {
        rpiv_synth_particle p = {63.2718, 61.8934, zs[k], 10e-6};
        double de_px, sig;
        rpiv_synth_image_model(s, &p, NULL, &de_px, &sig);
        double hand = de_by_hand_m(zs[k]) / pix;
        CHECK_NEAR(de_px, hand, 1e-9 * hand);
        CHECK_NEAR(sig, hand / (sqrt(8.0) * beta), 1e-9 * hand);
        if (sig < 0.8) { /* in focus: the moments of a sub-pixel Gaussian are biased */
            printf("  z* %.4f: d_e %.4f px (Eq. diam by hand %.4f)\n", zs[k], de_px, hand);
            continue;
        }
        rpiv_image *im = image(128, 128);
        CHECK_OK(rpiv_synth_render(s, &p, 1, im));
        double sum, cx, cy, vx, vy;
        moments(im, 0, 127, 0, 127, &sum, &cx, &cy, &vx, &vy);
        /* pixel integration adds 1/12 px^2 to the variance (Sheppard) */
        double de_x = sqrt(8.0) * beta * sqrt(vx - 1.0 / 12),
               de_y = sqrt(8.0) * beta * sqrt(vy - 1.0 / 12);
        printf("  z* %.4f: d_e from the image %.5f, %.5f px; Eq. diam by hand %.5f px\n", zs[k],
               de_x, de_y, hand);
        CHECK_NEAR(de_x, hand, 1e-3 * hand);
        CHECK_NEAR(de_y, hand, 1e-3 * hand);
        image_free(im);
    }
    rpiv_synth_free(s);
}

static void total_intensity_follows_amplitude_law(void)
{
    rpiv_synth_setup e = quiet_experiment(128, 128);
    e.synth.radius_sigma = 7;
    e.synth.peak_counts = 1318.7;
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    const double pix = 16.6e-3 / 2560, beta2 = 3.67, s0 = 0.5, h = 8e-3;
    const double de0 = de_by_hand_m(0.45) / pix;
    const double zs[] = {0.0271, 0.2318, 0.45, 0.6893, 0.9614};
    for (int k = 0; k < 5; k++) {
        rpiv_synth_particle p = {60.4127, 66.2283, zs[k], 10e-6};
        rpiv_image *im = image(128, 128);
        CHECK_OK(rpiv_synth_render(s, &p, 1, im));
        double sum, cx, cy;
        moments(im, 0, 127, 0, 127, &sum, &cx, &cy, NULL, NULL);
        double amp, de, sig;
        rpiv_synth_image_model(s, &p, &amp, &de, &sig);
        /* the integral of A exp(-4 beta^2 r^2 / d_e^2) is A pi d_e^2 / (4 beta^2) */
        CHECK_NEAR(sum, amp * M_PI * de * de / (4 * beta2), 1e-6 * sum);
        /* Eq. "int": A d_e^2 (s0 + z')^2 / (I0 d_p^2) is the same for every z* (I0 = 1), and
         * equals peak_counts * d_e0^2 s0^2 for the reference particle in focus */
        double zp = h * fabs(zs[k] - 0.45) / 1.33; /* apparent depth in water */
        double law = sum * (s0 + zp) * (s0 + zp) / (s0 * s0);
        double expect = 1318.7 * M_PI * de0 * de0 / (4 * beta2);
        printf("  z* %.4f: d_e %.3f px, peak %.2f, total %.2f counts, total (s0+z')^2/s0^2 "
               "%.3f (law %.3f)\n",
               zs[k], de, amp, sum, law, expect);
        CHECK_NEAR(law, expect, 1e-6 * expect);
        image_free(im);
    }
    /* the sheet's I0 and d_p^2 scale the amplitude */
    rpiv_synth_free(s);
    e.sheet.kind = RPIV_SHEET_GAUSS;
    e.sheet.zb_star = 0.45;
    e.sheet.e_star = 0.1;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_particle p0 = {60.4127, 66.2283, 0.45, 10e-6},
                        p1 = {60.4127, 66.2283, 0.4737, 7.3e-6};
    double a0, a1, d0, d1;
    rpiv_synth_image_model(s, &p0, &a0, &d0, NULL);
    rpiv_synth_image_model(s, &p1, &a1, &d1, NULL);
    double dz = (0.4737 - 0.45) / 0.1, i0 = exp(-4 * log(4.0) * dz * dz);
    double zp = h * (0.4737 - 0.45) / 1.33;
    double ratio =
        i0 * (7.3 * 7.3 / 100) * (d0 * d0) / (d1 * d1) * (s0 * s0) / ((s0 + zp) * (s0 + zp));
    CHECK_NEAR(a0, 1318.7, 1e-9);
    CHECK_NEAR(a1 / a0, ratio, 1e-12);
    rpiv_synth_free(s);
}

static int images_equal(const rpiv_image *a, const rpiv_image *b)
{
    return !memcmp(a->px, b->px, (size_t)a->w * (size_t)a->h * sizeof *a->px);
}

static void same_seed_same_pair_for_any_thread_count(void)
{
    rpiv_synth_setup e = rpiv_synth_setup_default();
    e.synth.width_px = 300; /* not a multiple of the band height */
    e.synth.height_px = 211;
    e.synth.seed = 2385;
    strcpy(e.synth.flow, "oseen:6,48");
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_image *a1 = image(300, 211), *b1 = image(300, 211), *a2 = image(300, 211),
               *b2 = image(300, 211);
    int nt = omp_get_max_threads();
    omp_set_num_threads(1);
    CHECK_OK(rpiv_synth_pair(s, 7, a1, b1));
    omp_set_num_threads(2);
    CHECK_OK(rpiv_synth_pair(s, 7, a2, b2));
    CHECK(images_equal(a1, a2));
    CHECK(images_equal(b1, b2));
    CHECK(!images_equal(a1, b1));
    CHECK(a1->bits == 16);
    /* another index and another seed give other images */
    CHECK_OK(rpiv_synth_pair(s, 8, a2, b2));
    CHECK(!images_equal(a1, a2));
    rpiv_synth_free(s);
    e.synth.seed = 2386;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    CHECK_OK(rpiv_synth_pair(s, 7, a2, b2));
    CHECK(!images_equal(a1, a2));
    CHECK(!images_equal(b1, b2));
    omp_set_num_threads(3);
    rpiv_image *ab = image(300, 422);
    CHECK_OK(rpiv_synth_pair_double(s, 7, ab));
    CHECK(!memcmp(ab->px, a2->px, 300 * 211 * sizeof(float)));
    CHECK(!memcmp(ab->px + 300 * 211, b2->px, 300 * 211 * sizeof(float)));
    omp_set_num_threads(nt);
    image_free(ab);
    image_free(a1);
    image_free(b1);
    image_free(a2);
    image_free(b2);
    rpiv_synth_free(s);
}

static void frame_b_moves_by_the_uniform_displacement(void)
{
    rpiv_synth_setup e = quiet_experiment(256, 192);
    e.particles.density_ppp = 0.0008;
    e.synth.peak_counts = 1e6; /* fine grey levels after rounding; defocused peaks < 65535 */
    /* all particles near z* = 0.007: defocused (apparent distance 0.443 h / 1.33 from the
     * object plane), sigma ~ 1.7 px */
    strcpy(e.synth.pz_profile, write_file("pz_band.txt", "# P(z*)\n0.002 1\n0.012 1\n"));
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_image *a = image(256, 192), *b = image(256, 192);
    CHECK_OK(rpiv_synth_pair(s, 3, a, b));
    rpiv_synth_particle *p;
    size_t n;
    CHECK_OK(rpiv_synth_particles_new(s, 3, &p, &n));
    int used = 0;
    double sdx = 0, sdy = 0, worst = 0;
    for (size_t i = 0; i < n; i++) {
        rpiv_synth_particle pa, pb;
        rpiv_synth_advect(s, &p[i], -0.5, &pa);
        rpiv_synth_advect(s, &p[i], 0.5, &pb);
        CHECK_NEAR(pb.x - pa.x, 3.3187, 1e-12);
        CHECK_NEAR(pb.y - pa.y, -1.7421, 1e-12);
        double sig;
        rpiv_synth_image_model(s, &pa, NULL, NULL, &sig);
        double r = 4 * sig + 2;
        int iso = pa.x > r && pa.x < 255 - r && pa.y > r && pa.y < 191 - r && pb.x > r &&
                  pb.x < 255 - r && pb.y > r && pb.y < 191 - r;
        for (size_t j = 0; j < n && iso; j++) {
            double dx = p[j].x - p[i].x, dy = p[j].y - p[i].y;
            if (j != i && fabs(dx) < 2 * r + 4 && fabs(dy) < 2 * r + 4)
                iso = 0;
        }
        if (!iso)
            continue;
        double sa, ax, ay, sb, bx, by;
        moments(a, (int)ceil(pa.x - r), (int)floor(pa.x + r), (int)ceil(pa.y - r),
                (int)floor(pa.y + r), &sa, &ax, &ay, NULL, NULL);
        moments(b, (int)ceil(pb.x - r), (int)floor(pb.x + r), (int)ceil(pb.y - r),
                (int)floor(pb.y + r), &sb, &bx, &by, NULL, NULL);
        double ex = bx - ax - 3.3187, ey = by - ay + 1.7421;
        worst = fmax(worst, fmax(fabs(ex), fabs(ey)));
        sdx += ex;
        sdy += ey;
        CHECK_NEAR(ax, pa.x, 2e-3);
        CHECK_NEAR(ay, pa.y, 2e-3);
        used++;
    }
    printf("  %d isolated particles: mean displacement error (%.2e, %.2e) px, worst %.2e px\n",
           used, sdx / used, sdy / used, worst);
    CHECK(used >= 5);
    CHECK(worst < 2e-3);
    CHECK_NEAR(sdx / used, 0, 1e-3);
    CHECK_NEAR(sdy / used, 0, 1e-3);
    rpiv_synth_particles_free(p);
    image_free(a);
    image_free(b);
    rpiv_synth_free(s);
}

static void duct_maps_to_bulk_displacement_in_pixels(void)
{
    rpiv_synth_setup e = rpiv_synth_setup_default(); /* flow "duct", full sensor */
    e.particles.density_ppp = 0.05;
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    /* U_b = Re nu / h; bulk displacement U_b dt M / pixel */
    double ub = 465 * 1e-6 / 8e-3, pix = 16.6e-3 / 2560, bulk = ub * 1e-3 * 0.39 / pix;
    printf("  U_b = %.6f m/s, bulk %.4f px, centre %.4f px over dt = 1 ms\n", ub, in.bulk_px,
           in.bulk_px * rpiv_duct_u(0.5, 0.5));
    CHECK_NEAR(in.bulk_px, bulk, 1e-12);
    CHECK_NEAR(in.flow.a, bulk, 1e-12);
    CHECK_NEAR(in.bulk_px * rpiv_duct_u(0.5, 0.5), 7.329, 2e-3);
    /* image row of y* = 0.5: y* = y0 + (y + 0.5) pixel/(M h) */
    double spp = pix / (0.39 * 8e-3), y0 = 0.5 - 0.5 * 4.46;
    CHECK_NEAR(in.star_per_px, spp, 1e-15);
    CHECK_NEAR(in.y0_star, y0, 1e-12);
    double yc = (0.5 - y0) / spp - 0.5;
    rpiv_synth_particle mid = {1234.5678, yc, 0.5, 10e-6}, pa, pb;
    rpiv_synth_advect(s, &mid, -0.5, &pa);
    rpiv_synth_advect(s, &mid, 0.5, &pb);
    CHECK_NEAR(pb.x - pa.x, bulk * rpiv_duct_u(0.5, 0.5), 1e-9);
    CHECK_NEAR(pb.y - pa.y, 0, 0);
    /* particles only in the fluid: 0 < y* < 1 */
    CHECK_NEAR(in.region[1], (0 - y0) / spp - 0.5, 1e-9);
    CHECK_NEAR(in.region[3], (1 - y0) / spp - 0.5, 1e-9);
    double area = (2560 + 32.0) * (1 / spp);
    CHECK(in.nparticles == (size_t)floor(0.05 * area + 0.5));
    /* the truth at z* = 0.5 on a grid */
    rpiv_synth_free(s);
    e.synth.truth_z = 0.5;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    float u[3], v[3];
    unsigned char fl[3];
    rpiv_field f = {0};
    f.nx = 1;
    f.ny = 3;
    f.x0 = 1000;
    f.y0 = yc - 600;
    f.dx = 16;
    f.dy = 600;
    f.u = u;
    f.v = v;
    f.flag = fl;
    rpiv_synth_truth(s, &f);
    CHECK(fl[0] == RPIV_FLAG_MASKED && fl[1] == RPIV_FLAG_VALID && fl[2] == RPIV_FLAG_MASKED);
    CHECK_NEAR(u[1], bulk * rpiv_duct_u(0.5, 0.5), 1e-5);
    CHECK_NEAR(u[0], 0, 0);
    CHECK_NEAR(v[1], 0, 0);
    CHECK_NEAR(f.scale_mm_per_px, pix / 0.39 * 1e3, 1e-12);
    CHECK_NEAR(f.dt_s, 1e-3, 0);
    rpiv_synth_free(s);
}

static void truth_at_the_sheet_peak_for_rpiv(void)
{
    /* default R-PIV sheet: peak z*_max(x*) = zm1 x*; truth = bulk U*(y*, z*_max) */
    rpiv_synth_setup e = rpiv_synth_setup_default();
    e.synth.width_px = 512;
    e.synth.height_px = 256;
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    float u[2], v[2];
    unsigned char fl[2];
    rpiv_field f = {0};
    f.nx = 2;
    f.ny = 1;
    f.x0 = 15.5;
    f.y0 = 127.5;
    f.dx = 480;
    f.dy = 16;
    f.u = u;
    f.v = v;
    f.flag = fl;
    rpiv_synth_truth(s, &f);
    for (int i = 0; i < 2; i++) {
        double x = 15.5 + 480 * i, xs = in.x0_star + (x + 0.5) * in.star_per_px;
        double ys = in.y0_star + 128 * in.star_per_px, zmax = 0.5 / 6.3 * xs;
        CHECK_NEAR(u[i], in.bulk_px * rpiv_duct_u(ys, zmax), 1e-5);
    }
    rpiv_synth_free(s);
}

typedef struct path_ctx {
    double y, zmid, w;
} path_ctx;

static double duct_on_path(double t, void *user)
{
    const path_ctx *c = user;
    return rpiv_duct_u(c->y, c->zmid + (t - 0.5) * c->w);
}

static void duct_with_w_integrates_along_the_path(void)
{
    /* with an out-of-plane w the particle crosses the profile: B - A = A_bulk * integral over
     * the pulse separation of U*(y*, z*(t)), by RK4; reference by GSL quadrature */
    rpiv_synth_setup e = rpiv_synth_setup_default();
    e.synth.width_px = 256;
    e.synth.height_px = 256;
    e.synth.w_star = 0.1318;
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    gsl_integration_workspace *ws = gsl_integration_workspace_alloc(100);
    const double zs[] = {0.1187, 0.4913, 0.8234};
    for (int k = 0; k < 3; k++) {
        rpiv_synth_particle mid = {100.25, 97.3, zs[k], 10e-6}, pa, pb;
        rpiv_synth_advect(s, &mid, -0.5, &pa);
        rpiv_synth_advect(s, &mid, 0.5, &pb);
        CHECK_NEAR(pb.z - pa.z, 0.1318, 1e-15);
        CHECK_NEAR(pb.y, pa.y, 0);
        path_ctx c = {in.flow.y0_star + 97.3 * in.flow.ystar_per_px, zs[k], 0.1318};
        gsl_function fn = {duct_on_path, &c};
        double ref, err;
        CHECK(gsl_integration_qag(&fn, 0, 1, 1e-13, 1e-12, 100, GSL_INTEG_GAUSS31, ws, &ref,
                                  &err) == 0);
        printf("  z*_mid %.4f: B - A = %.9f px, quadrature %.9f px\n", zs[k], pb.x - pa.x,
               in.bulk_px * ref);
        CHECK_NEAR(pb.x - pa.x, in.bulk_px * ref, 1e-7);
    }
    gsl_integration_workspace_free(ws);
    rpiv_synth_free(s);
}

static void oseen_particles_stay_on_their_circle(void)
{
    rpiv_synth_setup e = quiet_experiment(256, 256);
    strcpy(e.synth.flow, "oseen:6,48");
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    CHECK_NEAR(in.flow.cx, 127.5, 0);
    const double rs[] = {13.71, 53.8, 101.3};
    for (int k = 0; k < 3; k++) {
        double r = rs[k], th = 0.7391;
        rpiv_synth_particle mid = {127.5 + r * cos(th), 127.5 + r * sin(th), 0.4, 10e-6}, pa, pb;
        rpiv_synth_advect(s, &mid, -0.5, &pa);
        rpiv_synth_advect(s, &mid, 0.5, &pb);
        double ra = hypot(pa.x - 127.5, pa.y - 127.5), rb = hypot(pb.x - 127.5, pb.y - 127.5);
        double vth = 6 / (0.638161 / 48) * (1 - exp(-r * r / (48.0 * 48))) / r;
        double dth = atan2(pb.y - 127.5, pb.x - 127.5) - atan2(pa.y - 127.5, pa.x - 127.5);
        CHECK_NEAR(ra, r, 1e-6);
        CHECK_NEAR(rb, r, 1e-6);
        CHECK_NEAR(dth, vth / r, 1e-7);
    }
    rpiv_synth_free(s);
}

static void piv_recovers_the_uniform_displacement(void)
{
    /* end to end: a noiseless pair with particle images of ~2.5 px (f# 8, all particles within
     * 0.01 h of the object plane) at 0.05 ppp, processed by rpiv piv with its defaults
     * (64, 32, 32 px at 50 %, deformation): the PIV issue's accuracy target for uniform
     * sub-pixel displacements, RMS <= 0.015 px and |mean| <= 0.005 px per component */
    rpiv_synth_setup e = quiet_experiment(384, 320);
    e.particles.density_ppp = 0.05;
    e.camera.fnumber = 8;
    e.synth.bits = 16;
    e.synth.peak_counts = 2000;
    strcpy(e.synth.pz_profile, write_file("pz_focus.txt", "0.44 1\n0.46 1\n"));
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    rpiv_image *a = image(384, 320), *b = image(384, 320);
    CHECK_OK(rpiv_synth_pair(s, 11, a, b));
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL, *t = NULL;
    rpiv_piv_params pp = rpiv_piv_params_default();
    CHECK_OK(rpiv_piv_new(&pp, 384, 320, NULL, &pv));
    if (pv) {
        CHECK_OK(rpiv_piv_run(pv, a, b, &f));
        CHECK_OK(rpiv_piv_grid(pv, rpiv_piv_npass(pv) - 1, &t));
    }
    if (f && t) {
        rpiv_synth_truth(s, t);
        double su = 0, sv = 0, qu = 0, qv = 0;
        int n = 0;
        for (int k = 0; k < f->nx * f->ny; k++) {
            if (f->flag[k] != RPIV_FLAG_VALID)
                continue;
            double du = (double)f->u[k] - (double)t->u[k], dv = (double)f->v[k] - (double)t->v[k];
            su += du;
            sv += dv;
            qu += du * du;
            qv += dv * dv;
            n++;
        }
        printf("  d_e in focus %.3f px; %d of %d vectors valid; error mean (%.4f, %.4f) px, RMS "
               "(%.4f, %.4f) px\n",
               in.de_focus_px, n, f->nx * f->ny, su / n, sv / n, sqrt(qu / n), sqrt(qv / n));
        CHECK(n >= f->nx * f->ny - 2);
        CHECK(fabs(su / n) <= 0.005 && fabs(sv / n) <= 0.005);
        CHECK(sqrt(qu / n) <= 0.015 && sqrt(qv / n) <= 0.015);
    }
    rpiv_field_free(f);
    rpiv_field_free(t);
    rpiv_piv_free(pv);
    image_free(a);
    image_free(b);
    rpiv_synth_free(s);
}

static void noise_has_poisson_and_read_statistics(void)
{
    const int w = 512, h = 512;
    const double n = (double)w * h;
    /* the last case has fewer shot-noise tables (a high background) */
    struct {
        int shot;
        double bg, read, var;
    } cases[] = {{1, 100, 5, 100 + 25 + 1.0 / 12},
                 {1, 100, 0, 100},
                 {0, 100, 5, 25 + 1.0 / 12},
                 {1, 41318.7, 0, 41318.7}};
    for (int c = 0; c < 4; c++) {
        rpiv_synth_setup e = quiet_experiment(w, h);
        e.particles.density_ppp = 0;
        e.synth.background = cases[c].bg;
        e.synth.shot_noise = cases[c].shot;
        e.synth.read_noise = cases[c].read;
        rpiv_synth *s;
        CHECK_OK(rpiv_synth_new(&e, NULL, &s));
        if (!s)
            return;
        rpiv_image *a = image(w, h), *b = image(w, h);
        CHECK_OK(rpiv_synth_pair(s, 0, a, b));
        double m = 0, v = 0, at100 = 0;
        for (int i = 0; i < w * h; i++) {
            double x = (double)a->px[i];
            m += x;
            at100 += x == 100;
            CHECK(x == floor(x));
        }
        m /= n;
        for (int i = 0; i < w * h; i++)
            v += ((double)a->px[i] - m) * ((double)a->px[i] - m);
        v /= n - 1;
        double var = cases[c].var, bg = cases[c].bg;
        /* sd of the mean sqrt(var/n); of the variance ~ var sqrt(2/n) (near-Gaussian counts,
         * kurtosis excess 1/mu neglected); bounds 4.5 sd. A Poisson count is an integer
         * already; rounding a Gaussian adds 1/12. */
        printf("  shot %d background %g read %g: mean %.4f (%g +- %.4f), variance %.3f (%.3f "
               "+- %.3f)\n",
               cases[c].shot, bg, cases[c].read, m, bg, sqrt(var / n), v, var, var * sqrt(2 / n));
        CHECK_NEAR(m, bg, 4.5 * sqrt(var / n));
        CHECK_NEAR(v, var, 4.5 * var * sqrt(2 / n));
        if (cases[c].shot && cases[c].read == 0 && bg == 100) {
            double p = gsl_ran_poisson_pdf(100, 100);
            CHECK_NEAR(at100 / n, p, 4.5 * sqrt(p * (1 - p) / n));
        }
        CHECK(!images_equal(a, b)); /* independent noise in the two frames */
        image_free(a);
        image_free(b);
        rpiv_synth_free(s);
    }
}

static void quantisation_saturates_at_the_bit_depth(void)
{
    rpiv_synth_setup e = quiet_experiment(64, 40);
    e.particles.density_ppp = 0;
    e.synth.background = 300.4;
    e.synth.bits = 8;
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_image *a = image(64, 40), *b = image(64, 40);
    CHECK_OK(rpiv_synth_pair(s, 0, a, b));
    CHECK(a->px[0] == 255 && a->px[64 * 40 - 1] == 255 && a->bits == 8);
    rpiv_synth_free(s);
    e.synth.bits = 12;
    e.synth.background = 300.4;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    CHECK_OK(rpiv_synth_pair(s, 0, a, b));
    CHECK(a->px[17] == 300 && b->px[1000] == 300);
    /* a bright in-focus particle saturates at 4095 */
    memset(a->px, 0, 64 * 40 * sizeof(float));
    rpiv_synth_free(s);
    e.synth.peak_counts = 1e5;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    CHECK_OK(rpiv_synth_render(s, &(rpiv_synth_particle){30.2, 20.7, 0.45, 10e-6}, 1, a));
    CHECK(a->px[21 * 64 + 30] > 4095); /* the noiseless render is not quantised */
    image_free(a);
    image_free(b);
    rpiv_synth_free(s);
}

static void tabulated_pz_is_sampled(void)
{
    /* P(z*) = 2 z*: mean 2/3, variance 1/18 */
    rpiv_synth_setup e = quiet_experiment(512, 512);
    e.particles.density_ppp = 0.05;
    strcpy(e.synth.pz_profile, write_file("pz_ramp.txt", "# ramp\n0 0\n0.5 1\n1 2\n"));
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_particle *p;
    size_t n;
    CHECK_OK(rpiv_synth_particles_new(s, 0, &p, &n));
    double m = 0, below = 0;
    for (size_t i = 0; i < n; i++) {
        m += p[i].z;
        below += p[i].z < 0.3187;
    }
    m /= (double)n;
    double fb = 0.3187 * 0.3187; /* P(z* < a) = a^2 */
    printf("  %zu particles: mean z* %.4f (2/3), P(z* < 0.3187) %.4f (%.4f)\n", n, m,
           below / (double)n, fb);
    CHECK_NEAR(m, 2.0 / 3, 4.5 * sqrt(1.0 / 18 / (double)n));
    CHECK_NEAR(below / (double)n, fb, 4.5 * sqrt(fb * (1 - fb) / (double)n));
    rpiv_synth_particles_free(p);
    rpiv_synth_free(s);
}

static void diameters_are_uniform_in_the_spread(void)
{
    rpiv_synth_setup e = quiet_experiment(256, 256);
    e.particles.density_ppp = 0.05;
    e.particles.dp_sigma_m = 4e-6;
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_particle *p;
    size_t n;
    CHECK_OK(rpiv_synth_particles_new(s, 5, &p, &n));
    double m = 0, lo = 1, hi = 0;
    for (size_t i = 0; i < n; i++) {
        m += p[i].dp_m;
        lo = fmin(lo, p[i].dp_m);
        hi = fmax(hi, p[i].dp_m);
    }
    m /= (double)n;
    double sd = 8e-6 / sqrt(12.0);
    CHECK_NEAR(m, 10e-6, 4.5 * sd / sqrt((double)n));
    CHECK(lo >= 6e-6 && lo < 6.01e-6 && hi <= 14e-6 && hi > 13.99e-6);
    rpiv_synth_particles_free(p);
    rpiv_synth_free(s);
}

static void uniform_truth_on_a_grid(void)
{
    rpiv_synth_setup e = quiet_experiment(256, 200);
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    float u[6], v[6];
    unsigned char fl[6];
    rpiv_field f = {0};
    f.nx = 3;
    f.ny = 2;
    f.x0 = 15.5;
    f.y0 = 23.5;
    f.dx = f.dy = 16;
    f.u = u;
    f.v = v;
    f.flag = fl;
    rpiv_synth_truth(s, &f);
    for (int i = 0; i < 6; i++) {
        CHECK_NEAR(u[i], 3.3187, 1e-6);
        CHECK_NEAR(v[i], -1.7421, 1e-6);
        CHECK(fl[i] == RPIV_FLAG_VALID);
    }
    rpiv_synth_free(s);
}

static void params_file_reads_back_to_the_same_experiment(void)
{
    rpiv_experiment e = rpiv_experiment_default();
    e.synth.seed = 918273;
    e.synth.width_px = 320;
    strcpy(e.synth.flow, "sine:3,64");
    e.synth.w_star = 0.0123;
    rpiv_synth *s;
    CHECK_OK(rpiv_config_synth_new(&e, NULL, &s));
    if (!s)
        return;
    char path[256];
    snprintf(path, sizeof path, "%s/synth.ini", tmpdir);
    CHECK_OK(rpiv_config_save_synth(&e, s, path));
    rpiv_experiment r = rpiv_experiment_default();
    CHECK_OK(rpiv_config_load(path, &r));
    CHECK(r.synth.seed == 918273 && r.synth.width_px == 320 && !strcmp(r.synth.flow, "sine:3,64"));
    CHECK(r.synth.w_star == 0.0123);
    char b1[65536], b2[65536];
    FILE *f1 = fmemopen(b1, sizeof b1, "w"), *f2 = fmemopen(b2, sizeof b2, "w");
    CHECK_OK(rpiv_config_write(&e, f1));
    CHECK_OK(rpiv_config_write(&r, f2));
    fclose(f1);
    fclose(f2);
    CHECK(!strcmp(b1, b2));
    CHECK_FAILS(rpiv_config_save_synth(&e, s, "/nonexistent-dir/synth.ini"), RPIV_EIO);
    rpiv_synth_free(s);
}

static void flow_specs_parse_and_fail(void)
{
    rpiv_flow f;
    int ha, hc;
    CHECK_OK(rpiv_synth_flow_parse("uniform:3.3187,-1.7421", &f, &ha, &hc));
    CHECK(f.kind == RPIV_FLOW_UNIFORM && f.a == 3.3187 && f.b == -1.7421);
    CHECK_OK(rpiv_synth_flow_parse("duct", &f, &ha, &hc));
    CHECK(f.kind == RPIV_FLOW_DUCT && !ha);
    CHECK_OK(rpiv_synth_flow_parse("poiseuille:2.5", &f, &ha, &hc));
    CHECK(f.kind == RPIV_FLOW_POISEUILLE && ha && f.a == 2.5);
    CHECK_OK(rpiv_synth_flow_parse("oseen:6,48,100.5,90", &f, &ha, &hc));
    CHECK(f.kind == RPIV_FLOW_OSEEN && hc && f.cx == 100.5 && f.cy == 90);
    CHECK_OK(rpiv_synth_flow_parse("poiseuille-y:4", &f, &ha, &hc));
    CHECK(f.kind == RPIV_FLOW_POISEUILLE_Y);
    const char *bad[] = {
        "",           "vortex",        "uniform",    "uniform:1", "uniform:1,2,3", "uniform:1,x",
        "uniform:1,", "duct:1,2",      "oseen:6",    "oseen:6,0", "oseen:6,48,1",  "sine:3,-64",
        "sine:3",     "uniform:nan,1", "uniform:1;2"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        int st = rpiv_synth_flow_parse(bad[i], &f, &ha, &hc);
        if (st != RPIV_EINVAL)
            fprintf(stderr, "  spec '%s' accepted\n", bad[i]);
        CHECK(st == RPIV_EINVAL);
        CHECK(strstr(rpiv_errmsg(), "flow") != NULL);
    }
}

static void bad_inputs_fail_with_codes(void)
{
    rpiv_synth_setup e = quiet_experiment(64, 64);
    rpiv_synth *s = (rpiv_synth *)&e; /* must be reset to NULL on failure */
    strcpy(e.synth.flow, "vortex:1");
    CHECK_FAILS(rpiv_synth_new(&e, NULL, &s), RPIV_EINVAL);
    CHECK(s == NULL);
    e = quiet_experiment(64, 64);
    e.synth.bits = 10;
    CHECK_FAILS(rpiv_synth_new(&e, NULL, &s), RPIV_EINVAL);
    e = quiet_experiment(64, 64);
    e.synth.rk_steps = 0;
    CHECK_FAILS(rpiv_synth_new(&e, NULL, &s), RPIV_EINVAL);
    e = quiet_experiment(64, 64);
    e.camera.fnumber = 0;
    CHECK_FAILS(rpiv_synth_new(&e, NULL, &s), RPIV_EINVAL);
    e = quiet_experiment(64, 64);
    rpiv_flow f = {RPIV_FLOW_OSEEN, 6, 0, 0, 0, 0, 0, 0};
    CHECK_FAILS(rpiv_synth_new(&e, &f, &s), RPIV_EINVAL);
    f.b = (double)NAN;
    CHECK_FAILS(rpiv_synth_new(&e, &f, &s), RPIV_EINVAL);
    /* P(z) files */
    char missing[300];
    snprintf(missing, sizeof missing, "%s/no-such-pz.txt", tmpdir);
    strcpy(e.synth.pz_profile, missing);
    CHECK_FAILS(rpiv_synth_new(&e, NULL, &s), RPIV_EIO);
    CHECK(strstr(rpiv_errmsg(), "no-such-pz.txt") != NULL);
    const char *bad[] = {"0 1\n",          "0 1\n0.5 x\n", "0 1\n0.5 -1\n", "0 1\n1.5 1\n",
                         "0.5 1\n0.2 1\n", "0 0\n1 0\n",   "0 1 2\n1 1\n"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        strcpy(e.synth.pz_profile, write_file("pz_bad.txt", bad[i]));
        CHECK_FAILS(rpiv_synth_new(&e, NULL, &s), RPIV_EFORMAT);
        CHECK(strstr(rpiv_errmsg(), "pz_bad.txt") != NULL);
    }
    /* a missing sheet profile */
    e = quiet_experiment(64, 64);
    e.sheet.kind = RPIV_SHEET_SELFSIM;
    strcpy(e.sheet.profile, missing);
    CHECK_FAILS(rpiv_synth_new(&e, NULL, &s), RPIV_EIO);
    /* image sizes */
    e = quiet_experiment(64, 64);
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_image *a = image(64, 64), *b = image(64, 63);
    CHECK_FAILS(rpiv_synth_pair(s, 0, a, b), RPIV_ESIZE);
    CHECK_FAILS(rpiv_synth_pair_double(s, 0, a), RPIV_ESIZE);
    CHECK_FAILS(rpiv_synth_render(s, NULL, 0, b), RPIV_ESIZE);
    image_free(a);
    image_free(b);
    rpiv_synth_free(s);
    rpiv_synth_free(NULL);
    rpiv_synth_particles_free(NULL);
}

static void duct_outside_the_channel_has_no_particles(void)
{
    rpiv_synth_setup e = rpiv_synth_setup_default();
    e.synth.width_px = 128;
    e.synth.height_px = 128;
    e.channel.fov_y0_star = 3.2; /* the centred window sees y* > 1 only */
    rpiv_synth *s;
    CHECK_OK(rpiv_synth_new(&e, NULL, &s));
    if (!s)
        return;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    CHECK(in.nparticles == 0);
    rpiv_image *a = image(128, 128), *b = image(128, 128);
    CHECK_OK(rpiv_synth_pair(s, 0, a, b));
    image_free(a);
    image_free(b);
    rpiv_synth_free(s);
}

int main(void)
{
    rpiv_init();
    if (!mkdtemp(tmpdir))
        return 1;
    RUN_TEST(particle_count_matches_density_per_window);
    RUN_TEST(single_particle_centroid_is_its_position);
    RUN_TEST(particle_diameter_follows_eq_diam);
    RUN_TEST(total_intensity_follows_amplitude_law);
    RUN_TEST(same_seed_same_pair_for_any_thread_count);
    RUN_TEST(frame_b_moves_by_the_uniform_displacement);
    RUN_TEST(duct_maps_to_bulk_displacement_in_pixels);
    RUN_TEST(truth_at_the_sheet_peak_for_rpiv);
    RUN_TEST(duct_with_w_integrates_along_the_path);
    RUN_TEST(oseen_particles_stay_on_their_circle);
    RUN_TEST(piv_recovers_the_uniform_displacement);
    RUN_TEST(noise_has_poisson_and_read_statistics);
    RUN_TEST(quantisation_saturates_at_the_bit_depth);
    RUN_TEST(tabulated_pz_is_sampled);
    RUN_TEST(diameters_are_uniform_in_the_spread);
    RUN_TEST(uniform_truth_on_a_grid);
    RUN_TEST(params_file_reads_back_to_the_same_experiment);
    RUN_TEST(flow_specs_parse_and_fail);
    RUN_TEST(bad_inputs_fail_with_codes);
    RUN_TEST(duct_outside_the_channel_has_no_particles);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmpdir);
    return check_summary();
}
