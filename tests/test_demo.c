/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_demo.c - the demo end to end on a small configuration (seconds in Release, under a
 * minute with sanitizers), and its error paths.
 *
 * The run: the quick parameters on a band 512 px wide whose field of view is moved upstream
 * (channel.fov_x0_star) so that the band spans x* = 1.32 ... 2.38, where the traced sheet's
 * peak rises from the floor (z*_max = 0.08 ... 0.16), 2 pairs per P-PIV plane, 24 R-PIV pairs,
 * with three times the paper's seeding density (the sheet is thin there: few particles are
 * lit in each window, and 24 pairs of the paper's seeding leave E1 ~ 15 % of noise).
 * Checked against the paper (docs/demo.md):
 *  - the traced sheet is used, with the paper's inclination (about 5 deg: we accept 2..6) and
 *    e* = 0.42 at x* = 6.5 (accept 0.3..0.55);
 *  - R-PIV is closest to P-PIV at z*_max: E1 along y* at z*_max below those at z*_inf and
 *    z*_sup, and below 10 % in the core columns;
 *  - the error grows near the walls: near-floor columns (z*_max < wall_z = 0.1) have a larger
 *    E1 at z*_max than the columns further up (z*_max >= core_z = 0.13 here: the band holds
 *    no column above 0.2, the default core_z);
 *  - the E1 against the CCM falls as pairs are added (last snapshot below the first) and ends
 *    below 10 %;
 *  - every plot is a valid PNG (signature, and libpng decodes it), report.md and report.html
 *    exist and reference every plot. */
#include "check.h"

#include "rpiv/demo.h"

#include <omp.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[256];
static rpiv_demo_result res;
static rpiv_status run_status = RPIV_EINVAL;
static char run_dir[300];

static rpiv_demo_params small_params(void)
{
    rpiv_demo_params p = rpiv_demo_params_quick();
    p.width_px = 512;
    p.ppiv_pairs = 2;
    p.rpiv_pairs = 24;
    p.core_z = 0.13;
    p.wall_z = 0.10;
    return p;
}

static rpiv_experiment small_experiment(void)
{
    rpiv_experiment e = rpiv_experiment_default();
    /* the band (512 px = 1.06 x*, centred on the field of view) at x* = 1.32 ... 2.38 */
    double spp = rpiv_camera_pixel_m(&e.camera) / (e.camera.magnification * e.channel.h_m);
    e.channel.fov_x0_star = 1.85 - 0.5 * e.camera.width_px * spp;
    /* three times the paper's seeding, so that 24 pairs converge where the sheet is thin */
    e.particles.density_ppp = 0.045;
    return e;
}

static int file_has(const char *path, const char *needle)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return 0;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    int found = 0;
    if (buf && fread(buf, 1, (size_t)n, fp) == (size_t)n) {
        buf[n] = '\0';
        found = strstr(buf, needle) != NULL;
    }
    free(buf);
    fclose(fp);
    return found;
}

/* The whole file into a NUL-terminated buffer (NULL on failure); *n its size. */
static char *slurp(const char *path, size_t *n)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return NULL;
    fseek(fp, 0, SEEK_END);
    long len = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *buf = len >= 0 ? malloc((size_t)len + 1) : NULL;
    if (buf && fread(buf, 1, (size_t)len, fp) == (size_t)len) {
        buf[len] = '\0';
        *n = (size_t)len;
    } else {
        free(buf);
        buf = NULL;
    }
    fclose(fp);
    return buf;
}

static int b64_value(char ch)
{
    if (ch >= 'A' && ch <= 'Z')
        return ch - 'A';
    if (ch >= 'a' && ch <= 'z')
        return ch - 'a' + 26;
    if (ch >= '0' && ch <= '9')
        return ch - '0' + 52;
    return ch == '+' ? 62 : ch == '/' ? 63 : -1;
}

/* report.html holds the plot `name` as a data URI whose base64 decodes to the bytes of the
 * PNG file beside it (so that the HTML stands alone when copied). */
static int html_embeds(const char *html, const char *png, const char *name)
{
    size_t nh = 0, np = 0;
    char *h = slurp(html, &nh), *p = slurp(png, &np);
    char key[300];
    snprintf(key, sizeof key, "<img data-file=\"%s\" src=\"data:image/png;base64,", name);
    const char *s = h ? strstr(h, key) : NULL;
    int ok = s != NULL && p != NULL;
    size_t k = 0;
    if (ok) {
        s += strlen(key);
        unsigned long acc = 0;
        int bits = 0;
        for (; *s && *s != '"' && *s != '='; s++) {
            int v = b64_value(*s);
            if (v < 0) {
                ok = 0;
                break;
            }
            acc = (acc << 6 | (unsigned long)v) & 0xffffff;
            bits += 6;
            if (bits >= 8) {
                bits -= 8;
                unsigned char byte = (unsigned char)(acc >> bits);
                if (k >= np || (unsigned char)p[k] != byte) {
                    ok = 0;
                    break;
                }
                k++;
            }
        }
    }
    ok = ok && k == np;
    free(h);
    free(p);
    return ok;
}

/* The PNG signature, then a full decode by libpng (simplified API). */
static int valid_png(const char *path, unsigned *w, unsigned *h)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return 0;
    unsigned char sig[8];
    int ok = fread(sig, 1, 8, fp) == 8 && !png_sig_cmp(sig, 0, 8);
    fclose(fp);
    if (!ok)
        return 0;
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&im, path))
        return 0;
    im.format = PNG_FORMAT_GRAY;
    png_bytep buf = malloc(PNG_IMAGE_SIZE(im));
    ok = buf && png_image_finish_read(&im, NULL, buf, 0, NULL);
    png_image_free(&im);
    free(buf);
    *w = im.width;
    *h = im.height;
    return ok;
}

static void run_small(void)
{
    rpiv_experiment e = small_experiment();
    rpiv_demo_params p = small_params();
    p.threads = 1;
    snprintf(run_dir, sizeof run_dir, "%s/run", tmpdir);
    run_status = rpiv_demo_run(&e, &p, run_dir, NULL, NULL, &res);
    CHECK_OK(run_status);
    printf("  demo: %.1f s, band %d x %d, x* %.3f ... %.3f, %d columns (core %d, floor %d)\n",
           res.seconds, res.width_px, res.height_px, res.x0_star, res.x1_star, res.ncols,
           res.ncols_core, res.ncols_wall);
}

static void demo_uses_the_traced_sheet_with_the_papers_shape(void)
{
    if (run_status) {
        check_skip("the run failed");
        return;
    }
    printf("  sheet: %s\n  inclination %.3f deg, e*(6.5) %.4f, x*(z*_max = z*_OP) %.3f\n",
           res.sheet_note, res.sheet_incl_deg, res.trace_e_65, res.sheet_x_zop);
    CHECK(res.sheet_traced == 1);
    CHECK(res.sheet_incl_deg > 2 && res.sheet_incl_deg < 6);
    CHECK(res.trace_e_65 > 0.3 && res.trace_e_65 < 0.55);
    CHECK(res.sheet_x_zop > 4.5 && res.sheet_x_zop < 8);
}

static void demo_ppiv_reference_is_close_to_the_duct(void)
{
    if (run_status) {
        check_skip("the run failed");
        return;
    }
    printf("  P-PIV vs analytic: E1 mean %.4f max %.4f mid %.4f; along z at y* = 0.5: %.4f\n",
           res.ppiv_e1_mean, res.ppiv_e1_max, res.ppiv_e1_mid, res.ppiv_e1_z);
    CHECK(res.ppiv_planes == 15);
    CHECK(res.ppiv_e1_mean > 0 && res.ppiv_e1_mean < 0.05);
    CHECK(res.ppiv_e1_z > 0 && res.ppiv_e1_z < 0.05);
}

static void demo_rpiv_matches_ppiv_at_zmax(void)
{
    if (run_status) {
        check_skip("the run failed");
        return;
    }
    printf("  E1 R-PIV vs P-PIV: z*_inf %.4f z*_max %.4f z*_sup %.4f\n", res.e1_zinf, res.e1_zmax,
           res.e1_zsup);
    CHECK(res.ncols > 10);
    CHECK(res.e1_zmax_core < 0.10);
    CHECK(res.e1_zmax < res.e1_zinf);
    CHECK(res.e1_zmax < res.e1_zsup);
}

static void demo_error_grows_near_the_wall(void)
{
    if (run_status) {
        check_skip("the run failed");
        return;
    }
    printf("  E1 at z*_max: core %.4f (%d columns), near the floor %.4f (%d columns)\n",
           res.e1_zmax_core, res.ncols_core, res.e1_zmax_wall, res.ncols_wall);
    CHECK(res.ncols_core >= 3 && res.ncols_wall >= 3);
    CHECK(res.e1_zmax_wall > res.e1_zmax_core);
}

static void demo_converges_to_the_model(void)
{
    if (run_status) {
        check_skip("the run failed");
        return;
    }
    printf("  R-PIV vs CCM at y* = 0.5:");
    for (size_t k = 0; k < res.nconv; k++)
        printf(" N=%d %.4f", res.conv_n[k], res.conv_e1[k]);
    printf("\n  R-PIV vs P-PIV(z*_max) at y* = 0.5: %.4f; inversion %.4f (association %.4f)\n",
           res.e1_model_ppiv, res.e1_corr, res.e1_assoc);
    /* snapshots 1 2 5 10 20 and 24 */
    CHECK(res.nconv == 6);
    CHECK(res.conv_n[0] == 1 && res.conv_n[res.nconv - 1] == 24);
    CHECK(res.conv_e1[res.nconv - 1] < res.conv_e1[0]);
    CHECK(res.e1_model == res.conv_e1[res.nconv - 1]);
    CHECK(res.e1_model < 0.10);
    /* the inversion (fitting what the engine measures) pays on this near-floor band */
    CHECK(isfinite(res.e1_corr) && res.e1_corr < res.e1_assoc);
    /* the sheet bias per vector on the run's field: four bands of x*, finite figures, and the
     * corrected field against the truth recomputed from the bands' own errors */
    printf("  sheet bias: E1 raw %.4f, corrected %.4f;", res.bias_e1_raw, res.bias_e1_corr);
    for (int k = 0; k < res.nbias_bands; k++)
        printf(" [%.2f, %.2f] %.4f -> %.4f (err %+.4f, bias %+.4f)", res.bias_x0[k], res.bias_x1[k],
               res.bias_raw[k], res.bias_corr[k], res.bias_err[k], res.bias_mean[k]);
    printf("\n");
    CHECK(res.nbias_bands == RPIV_DEMO_BIAS_BANDS);
    CHECK(isfinite(res.bias_e1_raw) && isfinite(res.bias_e1_corr));
    CHECK(res.bias_e1_raw > 0 && res.bias_e1_raw < 0.2 && res.bias_e1_corr < 0.2);
    for (int k = 0; k < res.nbias_bands; k++) {
        CHECK(res.bias_x1[k] > res.bias_x0[k]);
        /* near the floor the sheet's longer lower tail lights slower fluid: negative bias */
        CHECK(isfinite(res.bias_mean[k]) && fabs(res.bias_mean[k]) < 0.2);
    }
    CHECK(res.bias_mean[0] < 0);
    CHECK(res.bias_e1_corr < res.bias_e1_raw); /* the correction pays in this near-floor band */
}

static void demo_writes_report_and_valid_plots(void)
{
    if (run_status) {
        check_skip("the run failed");
        return;
    }
    char md[400], html[400], path[400];
    snprintf(md, sizeof md, "%s/report.md", run_dir);
    snprintf(html, sizeof html, "%s/report.html", run_dir);
    CHECK(access(md, R_OK) == 0 && access(html, R_OK) == 0);
    CHECK(file_has(html, "<table>") && file_has(html, "</html>"));
    /* no plot linked by name: the HTML stands alone */
    CHECK(!file_has(html, "<img src="));
    /* the notation for a reader without the paper, and the worst column explained */
    CHECK(file_has(md, "## Notation and equations") && file_has(html, "Notation and equations"));
    CHECK(file_has(md, "`e*` = `z*_sup - z*_inf`") && file_has(md, "Eq. statform"));
    CHECK(file_has(md, "The largest E1 at `z*_max` is"));
    CHECK(file_has(md, "Sheet bias per vector") && file_has(md, "](bias_map.png)"));
    /* the R-PIV ensemble's uncertainty and its coverage against the synthetic truth */
    printf("  uncertainty: %zu vectors, coverage raw %.3f, after the bias correction %.3f, "
           "median sigma %.4f U*, RMS error %.4f / %.4f U*\n",
           res.unc_n, res.unc_cov_raw, res.unc_cov_corr, res.unc_med_sigma, res.unc_rms_raw,
           res.unc_rms_corr);
    CHECK(file_has(md, "Random uncertainty per vector") && file_has(md, "](uncertainty_map.png)"));
    CHECK(res.unc_n > 100 && res.unc_cov_raw > 0 && res.unc_cov_raw < 1);
    CHECK(res.unc_med_sigma > 0 && res.unc_med_sigma < res.unc_rms_raw);
    CHECK(res.nplots >= 14);
    for (size_t k = 0; k < res.nplots; k++) {
        unsigned w = 0, h = 0;
        snprintf(path, sizeof path, "%s/%s", run_dir, res.plots[k]);
        if (!valid_png(path, &w, &h)) {
            fprintf(stderr, "  %s: not a valid PNG\n", path);
            CHECK(0);
        }
        CHECK(w >= 100 && h >= 100);
        char ref[200];
        snprintf(ref, sizeof ref, "](%s)", res.plots[k]);
        CHECK(file_has(md, ref));
        if (!html_embeds(html, path, res.plots[k])) {
            fprintf(stderr, "  %s: not embedded in report.html\n", res.plots[k]);
            CHECK(0);
        }
    }
    static const char *const data[] = {"data/raytrace_metrics.txt", "data/sheet_fit.txt",
                                       "data/ppiv_z0.5000.txt",     "data/rpiv.txt",
                                       "data/compare_x.txt",        "data/convergence.txt",
                                       "images/rpiv_a.tif",         "images/rpiv_b.tif"};
    for (size_t k = 0; k < sizeof data / sizeof data[0]; k++) {
        snprintf(path, sizeof path, "%s/%s", run_dir, data[k]);
        if (access(path, R_OK)) {
            fprintf(stderr, "  %s missing\n", path);
            CHECK(0);
        }
    }
}

/* ---- error paths ------------------------------------------------------------------------- */

static void demo_params_check_names_the_field(void)
{
    rpiv_demo_params d = rpiv_demo_params_default();
    CHECK_OK(rpiv_demo_params_check(&d));
    rpiv_demo_params q = rpiv_demo_params_quick();
    CHECK_OK(rpiv_demo_params_check(&q));
    struct {
        rpiv_demo_params p;
        const char *field;
    } bad[16];
    size_t n = 0;
    for (size_t k = 0; k < 16; k++)
        bad[k].p = d;
    bad[n].p.width_px = -3, bad[n++].field = "width_px";
    bad[n].p.margin_px = -1, bad[n++].field = "margin_px";
    bad[n].p.rpiv_pairs = 0, bad[n++].field = "rpiv_pairs";
    bad[n].p.ppiv_pairs = 0, bad[n++].field = "ppiv_pairs";
    bad[n].p.ppiv_e_star = 0, bad[n++].field = "ppiv_e_star";
    bad[n].p.ppiv_planes = 1, bad[n++].field = "ppiv_planes";
    bad[n].p.ppiv_dz = -0.0625, bad[n++].field = "ppiv_dz";
    bad[n].p.ppiv_planes = 17, bad[n++].field = "P-PIV planes"; /* reaches z* = 1.0625 */
    bad[n].p.ppiv_slab = 0, bad[n++].field = "ppiv_slab";
    bad[n].p.optics_dx = 0, bad[n++].field = "optics stations";
    bad[n].p.profile_x = (double)NAN, bad[n++].field = "profile_x";
    bad[n].p.wall_z = 1.5, bad[n++].field = "wall_z";
    bad[n].p.snap[1] = 1, bad[n++].field = "snap[1]";
    bad[n].p.nsnap = RPIV_DEMO_MAX_SNAP + 1, bad[n++].field = "nsnap";
    bad[n].p.cache_mb = -1, bad[n++].field = "cache_mb";
    bad[n].p.threads = -2, bad[n++].field = "threads";
    for (size_t k = 0; k < n; k++) {
        CHECK_FAILS(rpiv_demo_params_check(&bad[k].p), RPIV_EINVAL);
        if (!strstr(rpiv_errmsg(), bad[k].field)) {
            fprintf(stderr, "  message '%s' does not name %s\n", rpiv_errmsg(), bad[k].field);
            CHECK(0);
        }
    }
}

static void demo_run_rejects_bad_input(void)
{
    rpiv_experiment e = rpiv_experiment_default();
    rpiv_demo_params p = small_params();
    char dir[300];
    snprintf(dir, sizeof dir, "%s/bad", tmpdir);
    p.rpiv_pairs = 0;
    CHECK_FAILS(rpiv_demo_run(&e, &p, dir, NULL, NULL, NULL), RPIV_EINVAL);
    p = small_params();
    CHECK_FAILS(rpiv_demo_run(&e, &p, "", NULL, NULL, NULL), RPIV_EINVAL);
    e.camera.fnumber = -1;
    CHECK_FAILS(rpiv_demo_run(&e, &p, dir, NULL, NULL, NULL), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "f-number") != NULL);
    /* an output folder under a regular file */
    e = rpiv_experiment_default();
    char file[300];
    snprintf(file, sizeof file, "%s/plain", tmpdir);
    FILE *fp = fopen(file, "w");
    CHECK(fp != NULL);
    if (fp)
        fclose(fp);
    snprintf(dir, sizeof dir, "%s/plain/out", tmpdir);
    CHECK_FAILS(rpiv_demo_run(&e, &p, dir, NULL, NULL, NULL), RPIV_EIO);
    CHECK(strstr(rpiv_errmsg(), "plain") != NULL);
    CHECK_FAILS(rpiv_demo_run(&e, &p, file, NULL, NULL, NULL), RPIV_EIO);
}

static int stop_after(void *user, size_t done, size_t total)
{
    size_t *calls = user;
    (void)total;
    (*calls)++;
    return done >= 3;
}

static void demo_stops_when_progress_asks(void)
{
    rpiv_experiment e = rpiv_experiment_default();
    rpiv_demo_params p = small_params();
    char dir[300];
    snprintf(dir, sizeof dir, "%s/stop", tmpdir);
    size_t calls = 0;
    rpiv_progress prog = {stop_after, &calls};
    CHECK_FAILS(rpiv_demo_run(&e, &p, dir, &prog, NULL, NULL), RPIV_EINTR);
    CHECK(calls >= 3 && calls < 10);
}

static void note(void *user, const char *line)
{
    size_t *n = user;
    (*n)++;
    (void)line;
}

static void demo_log_reports_each_step(void)
{
    /* a line per step as it starts, and what it found: at least two before the third unit */
    rpiv_experiment e = rpiv_experiment_default();
    rpiv_demo_params p = small_params();
    char dir[300];
    snprintf(dir, sizeof dir, "%s/log", tmpdir);
    size_t lines = 0;
    rpiv_demo_log log = {note, &lines};
    size_t calls = 0;
    rpiv_progress prog = {stop_after, &calls};
    CHECK_FAILS(rpiv_demo_run(&e, &p, dir, &prog, &log, NULL), RPIV_EINTR);
    CHECK(lines >= 2);
}

static void demo_falls_back_to_the_configured_sheet(void)
{
    /* beta1 = -3 deg: the axis meets the floor beyond the critical angle, nothing reaches the
     * water in a usable sheet; the synthesis takes the [sheet] section (selfsim, e0 = 0) */
    rpiv_experiment e = rpiv_experiment_default();
    e.laser.beta1_deg = -3;
    rpiv_demo_params p = rpiv_demo_params_quick();
    p.width_px = 128;
    p.ppiv_pairs = 1;
    p.rpiv_pairs = 2;
    p.save_images = 0;
    char dir[300];
    snprintf(dir, sizeof dir, "%s/fallback", tmpdir);
    rpiv_demo_result r;
    CHECK_OK(rpiv_demo_run(&e, &p, dir, NULL, NULL, &r));
    printf("  %s\n", r.sheet_note);
    CHECK(r.sheet_traced == 0);
    CHECK(strstr(r.sheet_note, "kind = selfsim") && strstr(r.sheet_note, "no self-similar fit"));
    /* the configuration's sheet: e* = 0.42 x* / 6.5, z*_max = 0.5 at x* = 6.3 */
    CHECK_NEAR(r.sheet_de_dx, 0.42 / 6.5, 1e-12);
    CHECK_NEAR(r.sheet_incl_deg, atan(0.5 / 6.3) * 180 / M_PI, 1e-9);
    CHECK_NEAR(r.sheet_x_zop, 0.45 * 6.3 / 0.5, 1e-9);
    char path[400];
    snprintf(path, sizeof path, "%s/data/sheet_fit.txt", dir);
    CHECK(access(path, F_OK) != 0);
}

static void demo_fails_when_the_sheet_is_dark_everywhere(void)
{
    /* no usable trace (beta1 = -3 deg) and a configured sheet with no thickness over the band:
     * nothing is lit, nothing can be compared */
    rpiv_experiment e = rpiv_experiment_default();
    e.laser.beta1_deg = -3;
    e.sheet.e1 = -0.1; /* e* = -0.1 x* < 0 over the band */
    rpiv_demo_params p = rpiv_demo_params_quick();
    p.width_px = 128;
    p.ppiv_pairs = 1;
    p.rpiv_pairs = 1;
    p.save_images = 0;
    char dir[300];
    snprintf(dir, sizeof dir, "%s/dark", tmpdir);
    CHECK_FAILS(rpiv_demo_run(&e, &p, dir, NULL, NULL, NULL), RPIV_ENUMERIC);
    CHECK(strstr(rpiv_errmsg(), "dark") != NULL);
}

/* The same numbers with 1 and 2 threads (a tiny run: 128 px band, 1 pair per plane, 3 R-PIV
 * pairs); the other runs of this file use one thread (omp_set_num_threads(1) in main): the
 * development machine is shared, and OpenMP threads that spin at barriers on a busy machine
 * make a two-thread run several times slower. */
static void demo_results_do_not_depend_on_threads(void)
{
    rpiv_experiment e = rpiv_experiment_default();
    rpiv_demo_params p = rpiv_demo_params_quick();
    p.width_px = 128;
    p.ppiv_pairs = 1;
    p.rpiv_pairs = 3;
    p.save_images = 0;
    rpiv_demo_result r[2];
    for (int t = 0; t < 2; t++) {
        char dir[300];
        snprintf(dir, sizeof dir, "%s/threads%d", tmpdir, t + 1);
        omp_set_num_threads(t + 1);
        p.threads = t + 1;
        CHECK_OK(rpiv_demo_run(&e, &p, dir, NULL, NULL, &r[t]));
    }
    omp_set_num_threads(1);
    CHECK(r[0].threads == 1 && r[1].threads == 2);
    printf("  E1 at z*_max %.9f / %.9f, vs CCM %.9f / %.9f\n", r[0].e1_zmax, r[1].e1_zmax,
           r[0].e1_model, r[1].e1_model);
    CHECK(r[0].e1_zmax == r[1].e1_zmax && r[0].e1_zinf == r[1].e1_zinf);
    CHECK(r[0].e1_model == r[1].e1_model && r[0].ppiv_e1_mean == r[1].ppiv_e1_mean);
    CHECK(r[0].rpiv_e1_truth == r[1].rpiv_e1_truth && r[0].e1_corr == r[1].e1_corr);
    CHECK(r[0].trace_e_65 == r[1].trace_e_65);
    for (size_t k = 0; k < r[0].nconv; k++)
        CHECK(r[0].conv_e1[k] == r[1].conv_e1[k]);
}

static void cleanup(void)
{
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmpdir);
}

int main(void)
{
    rpiv_init();
    snprintf(tmpdir, sizeof tmpdir, "%s/rpiv_test_demo_XXXXXX",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    omp_set_num_threads(1);
    RUN_TEST(demo_params_check_names_the_field);
    RUN_TEST(demo_run_rejects_bad_input);
    RUN_TEST(demo_stops_when_progress_asks);
    RUN_TEST(demo_log_reports_each_step);
    RUN_TEST(demo_falls_back_to_the_configured_sheet);
    RUN_TEST(demo_fails_when_the_sheet_is_dark_everywhere);
    RUN_TEST(demo_results_do_not_depend_on_threads);
    RUN_TEST(run_small);
    RUN_TEST(demo_uses_the_traced_sheet_with_the_papers_shape);
    RUN_TEST(demo_ppiv_reference_is_close_to_the_duct);
    RUN_TEST(demo_rpiv_matches_ppiv_at_zmax);
    RUN_TEST(demo_error_grows_near_the_wall);
    RUN_TEST(demo_converges_to_the_model);
    RUN_TEST(demo_writes_report_and_valid_plots);
    cleanup();
    return check_summary();
}
