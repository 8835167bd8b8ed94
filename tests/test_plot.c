/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_plot.c - each plot kind writes a valid PNG of the requested size (signature, and
 * libpng reads width and height), writes nothing else, and rejects bad arguments. */
#include "check.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/plot.h"
#include "rpiv/report.h"

#include <dirent.h>
#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char dir[256];

/* Under AddressSanitizer: fontconfig (through cairo and pango) keeps its font caches for the
 * life of the process and never frees them; that is not rpiv's leak. LeakSanitizer calls this
 * hook, when it is linked in, for its default suppressions. */
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void)
{
    return "leak:libfontconfig.so\n";
}

static const char *tpath(const char *name)
{
    static char buf[512];
    snprintf(buf, sizeof buf, "%s/%s", dir, name);
    return buf;
}

/* Width and height through libpng, after checking the 8-byte signature; 0 on any failure.
 * Also reads every row, so a truncated file fails. *nonwhite counts pixels that are not
 * white (something was drawn). */
static int png_size(const char *path, unsigned *w, unsigned *h, size_t *nonwhite)
{
    *w = *h = 0;
    *nonwhite = 0;
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return 0;
    unsigned char sig[8];
    if (fread(sig, 1, 8, fp) != 8 || png_sig_cmp(sig, 0, 8)) {
        fclose(fp);
        return 0;
    }
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    png_bytep row = NULL;
    if (!png || !info || setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, NULL);
        free(row);
        fclose(fp);
        *w = *h = 0;
        return 0;
    }
    png_init_io(png, fp);
    png_set_sig_bytes(png, 8);
    png_read_info(png, info);
    png_set_expand(png);
    png_set_strip_16(png);
    png_set_gray_to_rgb(png);
    png_set_strip_alpha(png);
    png_read_update_info(png, info);
    *w = png_get_image_width(png, info);
    *h = png_get_image_height(png, info);
    size_t rb = png_get_rowbytes(png, info);
    row = malloc(rb);
    for (unsigned y = 0; y < *h; y++) {
        png_read_row(png, row, NULL);
        for (size_t x = 0; x + 2 < rb; x += 3)
            *nonwhite += row[x] != 255 || row[x + 1] != 255 || row[x + 2] != 255;
    }
    png_read_end(png, NULL);
    png_destroy_read_struct(&png, &info, NULL);
    free(row);
    fclose(fp);
    return 1;
}

static int nfiles(void)
{
    int n = 0;
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d && (e = readdir(d)))
        n += e->d_name[0] != '.';
    if (d)
        closedir(d);
    return n;
}

static void quiver_writes_png_of_requested_size(void)
{
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_field_new(24, 18, 16, 16, 16, 16, &f));
    if (!f)
        return;
    /* a Lamb-Oseen-like swirl with one replaced and one masked vector */
    for (int j = 0; j < 18; j++)
        for (int i = 0; i < 24; i++) {
            double x = i - 11.3187, y = j - 8.71, r2 = x * x + y * y + 1e-9;
            double ut = 6.0 * (1 - exp(-r2 / 16.0)) / sqrt(r2);
            f->u[j * 24 + i] = (float)(-ut * y / sqrt(r2));
            f->v[j * 24 + i] = (float)(ut * x / sqrt(r2));
        }
    f->flag[5] = RPIV_FLAG_REPLACED;
    f->flag[6] = RPIV_FLAG_MASKED;
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.width_px = 640;
    o.height_px = 480;
    CHECK_OK(rpiv_plot_quiver(f, tpath("quiver.png"), "swirl", &o));
    unsigned w, h;
    size_t ink;
    CHECK(png_size(tpath("quiver.png"), &w, &h, &ink));
    CHECK(w == 640 && h == 480);
    CHECK(ink > 640 * 480 / 10); /* the background map covers much of the frame */
    /* without the background, with a stride and default options */
    o.background = 0;
    o.stride = 2;
    CHECK_OK(rpiv_plot_quiver(f, tpath("quiver2.png"), "swirl, every 2nd", &o));
    CHECK(png_size(tpath("quiver2.png"), &w, &h, &ink) && w == 640 && h == 480);
    CHECK(ink > 1000 && ink < 640 * 480 / 3);
    CHECK_OK(rpiv_plot_quiver(f, tpath("quiver3.png"), NULL, NULL));
    CHECK(png_size(tpath("quiver3.png"), &w, &h, &ink) && w == 800 && h == 600);
    o.stride = 0;
    CHECK_FAILS(rpiv_plot_quiver(f, tpath("bad.png"), "x", &o), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "stride 0") != NULL);
    CHECK(access(tpath("bad.png"), F_OK) != 0);
    rpiv_field_free(f);
}

static void lines_writes_png_with_legend(void)
{
    double z[101], a[101], b[101], c[11], cz[11];
    for (int k = 0; k <= 100; k++) {
        z[k] = k / 100.0;
        a[k] = 6 * z[k] * (1 - z[k]);
        b[k] = k == 50 ? (double)NAN : 1.1 * a[k]; /* a gap */
    }
    for (int k = 0; k <= 10; k++) {
        cz[k] = k / 10.0 + 0.013;
        c[k] = 6 * cz[k] * (1 - cz[k]) - 0.05;
    }
    rpiv_plot_series s[3] = {{z, a, 101, "exact", RPIV_PLOT_LINE},
                             {z, b, 101, "scaled 1.1", RPIV_PLOT_BOTH},
                             {cz, c, 11, NULL, RPIV_PLOT_POINTS}};
    CHECK_OK(rpiv_plot_lines(tpath("lines.png"), "Poiseuille", "z*", "U*", s, 3, NULL));
    unsigned w, h;
    size_t ink;
    CHECK(png_size(tpath("lines.png"), &w, &h, &ink) && w == 800 && h == 600);
    CHECK(ink > 2000);
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.width_px = 400;
    o.height_px = 1000;
    o.ymin = -1;
    o.ymax = 2;
    CHECK_OK(rpiv_plot_lines(tpath("lines2.png"), NULL, NULL, NULL, s, 1, &o));
    CHECK(png_size(tpath("lines2.png"), &w, &h, &ink) && w == 400 && h == 1000);
    CHECK_FAILS(rpiv_plot_lines(tpath("bad.png"), "t", "x", "y", s, 0, NULL), RPIV_EINVAL);
    double nan2[2] = {(double)NAN, (double)NAN};
    rpiv_plot_series bad = {nan2, nan2, 2, "all nan", RPIV_PLOT_LINE};
    CHECK_FAILS(rpiv_plot_lines(tpath("bad.png"), "t", "x", "y", &bad, 1, NULL), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "all nan") != NULL);
    o.aspect = 3;
    CHECK_FAILS(rpiv_plot_lines(tpath("bad.png"), "t", "x", "y", s, 1, &o), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "aspect 3") != NULL);
    o.aspect = RPIV_PLOT_AUTO;
    o.width_px = 20;
    CHECK_FAILS(rpiv_plot_lines(tpath("bad.png"), "t", "x", "y", s, 1, &o), RPIV_EINVAL);
    CHECK(access(tpath("bad.png"), F_OK) != 0);
}

static void map_writes_png_for_image_and_scalar(void)
{
    /* a camera-sized image (reduced internally) and a small scalar map with blank cells */
    int nx = 1280, ny = 1080;
    double *im = malloc((size_t)nx * ny * sizeof *im);
    if (!im)
        return;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++)
            im[(size_t)j * nx + i] = 1000 + 800 * sin(i * 0.0131) * cos(j * 0.0217);
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.cmap = RPIV_PLOT_CMAP_GRAY;
    o.zlabel = "counts";
    CHECK_OK(rpiv_plot_map(tpath("image.png"), "image", im, nx, ny, NULL, &o));
    unsigned w, h;
    size_t ink;
    CHECK(png_size(tpath("image.png"), &w, &h, &ink) && w == 800 && h == 600);
    CHECK(ink > 800 * 600 / 10);
    double m[12 * 7];
    for (int k = 0; k < 12 * 7; k++)
        m[k] = k % 5 == 0 ? (double)NAN : 0.3187 * k - 4;
    double ext[4] = {0, 1.2, -0.35, 0.35};
    o = rpiv_plot_opts_default();
    o.cmap = RPIV_PLOT_CMAP_DIVERGING;
    o.y_axis = RPIV_PLOT_UP;
    o.aspect = RPIV_PLOT_FREE;
    o.xlabel = "x*";
    o.ylabel = "z*";
    CHECK_OK(rpiv_plot_map(tpath("map.png"), "map", m, 12, 7, ext, &o));
    CHECK(png_size(tpath("map.png"), &w, &h, &ink) && w == 800 && h == 600);
    double bad_ext[4] = {1, 0, 0, 1};
    CHECK_FAILS(rpiv_plot_map(tpath("bad.png"), "m", m, 12, 7, bad_ext, &o), RPIV_EINVAL);
    CHECK_FAILS(rpiv_plot_map(tpath("bad.png"), "m", m, 0, 7, NULL, &o), RPIV_EINVAL);
    CHECK(access(tpath("bad.png"), F_OK) != 0);
    free(im);
}

/* Each cell of a map covers its own span: 4 rows of which 4, 2 or 1 are filled cover the
 * whole frame, half and a quarter of it, so the ink added by rows 3-4 is twice that of row 2.
 * (PLplot's plimagefr spreads n cells at a step of extent / (n - 1): drawn so, the filled
 * rows covered 1, 2/3 and 1/3 of the frame, a ratio of 1.) */
static void map_cells_cover_their_span(void)
{
    double z[3 * 4];
    size_t ink[3];
    int filled[3] = {4, 2, 1};
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.aspect = RPIV_PLOT_FREE;
    for (int r = 0; r < 3; r++) {
        for (int k = 0; k < 12; k++)
            z[k] = k / 3 < filled[r] ? 1.0 : (double)NAN;
        unsigned w, h;
        CHECK_OK(rpiv_plot_map(tpath("cells.png"), NULL, z, 3, 4, NULL, &o));
        CHECK(png_size(tpath("cells.png"), &w, &h, &ink[r]));
    }
    double two = (double)ink[0] - (double)ink[1], one = (double)ink[1] - (double)ink[2];
    CHECK(one > 1000);
    CHECK_NEAR(two / one, 2.0, 0.1);
}

static void plot_into_missing_folder_fails_with_path(void)
{
    double x[2] = {0, 1};
    rpiv_plot_series s = {x, x, 2, "a", RPIV_PLOT_LINE};
    CHECK_FAILS(rpiv_plot_lines(tpath("no/such/lines.png"), "t", "x", "y", &s, 1, NULL), RPIV_EIO);
    CHECK(strstr(rpiv_errmsg(), "no/such/lines.png") != NULL);
}

static rpiv_status write_two_lines(const void *obj, FILE *fp)
{
    fprintf(fp, "%s\nsecond\n", (const char *)obj);
    return RPIV_OK;
}

static rpiv_status write_then_fail(const void *obj, FILE *fp)
{
    fprintf(fp, "%s\n", (const char *)obj);
    return rpiv_fail(RPIV_ENUMERIC, "writer gave up");
}

/* report.h: the atomic text writer keeps the old file when the writer fails; the profile
 * figure writes a PNG; the even pick takes the ends. The files are removed afterwards. */
static void report_writes_tables_and_profiles(void)
{
    char path[512], line[64] = "";
    snprintf(path, sizeof path, "%s", tpath("table.txt"));
    CHECK_OK(rpiv_report_write_file(path, write_two_lines, "first"));
    CHECK_FAILS(rpiv_report_write_file(path, write_then_fail, "other"), RPIV_ENUMERIC);
    FILE *fp = fopen(path, "r");
    CHECK(fp != NULL);
    if (fp) {
        CHECK(fgets(line, sizeof line, fp) && !strcmp(line, "first\n"));
        fclose(fp);
    }
    CHECK_FAILS(rpiv_report_write_file(tpath("no/such/t.txt"), write_two_lines, "x"), RPIV_EIO);
    CHECK(remove(path) == 0);
    double z[50], a[50];
    for (int k = 0; k < 50; k++) {
        z[k] = (k + 0.5) / 50;
        a[k] = exp(-(z[k] - 0.3) * (z[k] - 0.3) / 0.01);
    }
    rpiv_plot_series s = {a, z, 50, "x* = 4", RPIV_PLOT_LINE};
    snprintf(path, sizeof path, "%s", tpath("profiles.png"));
    CHECK_OK(rpiv_report_sheet_profiles(path, "profiles", "I0*", &s, 1, 1.5));
    unsigned w, h;
    size_t ink;
    CHECK(png_size(path, &w, &h, &ink) && w == 800 && h == 600 && ink > 1000);
    CHECK(remove(path) == 0);
    CHECK(rpiv_report_pick(0, 12, 40) == 0 && rpiv_report_pick(11, 12, 40) == 39);
    CHECK(rpiv_report_pick(0, 1, 5) == 0 && rpiv_report_pick(2, 3, 3) == 2);
}

/* rpiv_plot_field: the numbers it draws follow from the field. A uniform flow (3, +-0.5) px/dt
 * on 56 x 30 points, step 16 px: every = ceil(56 / 28) = 2, arrow length 0.9 * 2 * 16 / 3.04
 * px per px/dt, reference 2 px/dt; with scale 0.05 mm/px and dt 1 ms the speed is 0.152 m/s,
 * reference 0.1 m/s and the same length in mm per m/s. A masked point's huge
 * value stays out of the colour range; a signed quantity gets a range symmetric about 0. */
static void field_figure_numbers(void)
{
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_field_new(56, 30, 8, 8, 16, 16, &f));
    if (!f)
        return;
    for (int k = 0; k < 56 * 30; k++) {
        f->u[k] = 3.0f;
        f->v[k] = k % 2 ? 0.5f : -0.5f;
    }
    f->flag[3] = RPIV_FLAG_MASKED;
    f->u[3] = 1e6f;
    f->flag[4] = RPIV_FLAG_REPLACED;
    rpiv_plot_field_params p = rpiv_plot_field_params_default();
    rpiv_plot_field_info info;
    p.quantity = "u";
    CHECK_OK(rpiv_plot_field(f, tpath("field.png"), "uniform.txt", &p, &info));
    unsigned w, h;
    size_t ink;
    CHECK(png_size(tpath("field.png"), &w, &h, &ink) && w == 1000 && h == 800);
    CHECK(ink > 1000 * 800 / 10);
    CHECK(info.every == 2);
    CHECK(fabs(info.arrow_len - 0.9 * 2 * 16 / hypot(3, 0.5)) < 1e-9);
    CHECK(info.ref_value == 2);
    CHECK(info.physical == 0);
    CHECK(info.nvalid == 1678 && info.nreplaced == 1 && info.nmasked == 1);
    CHECK(info.zmin < 3 && info.zmax > 3 && info.zmax < 4); /* flat 3, widened by 0.5 */
    p.quantity = "v";
    p.every = 1;
    p.width_px = 500;
    p.height_px = 300;
    CHECK_OK(rpiv_plot_field(f, tpath("field_v.png"), "uniform.txt", &p, &info));
    CHECK(png_size(tpath("field_v.png"), &w, &h, &ink) && w == 500 && h == 300);
    CHECK(info.every == 1 && info.zmin == -0.5 && info.zmax == 0.5);
    f->scale_mm_per_px = 0.05;
    f->dt_s = 0.001;
    p = rpiv_plot_field_params_default();
    CHECK_OK(rpiv_plot_field(f, tpath("field_mm.png"), NULL, &p, &info));
    CHECK(info.physical == 1 && info.every == 2);
    double speed = hypot(3, 0.5) * 0.05e-3 / 0.001;
    CHECK(fabs(info.arrow_len - 0.9 * 2 * 16 * 0.05 / speed) < 1e-9);
    CHECK(fabs(info.ref_value - 0.1) < 1e-12);
    CHECK(fabs(info.zmax - info.zmin - 2 * fmax(0.5, 0.05 * speed)) < 1e-9);
    /* errors: a quantity the field lacks (listed), a bad member, not .png; nothing written */
    float *vort = NULL;
    CHECK_OK(rpiv_field_add_quantity(f, "vorticity", RPIV_UNIT_PER_DT | RPIV_UNIT_ODD_Y, &vort));
    p.quantity = "sigma_u";
    CHECK_FAILS(rpiv_plot_field(f, tpath("bad.png"), NULL, &p, NULL), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "'sigma_u'") && strstr(rpiv_errmsg(), "correlation, vorticity"));
    p.quantity = "vorticity";
    p.arrow_scale = 0;
    CHECK_FAILS(rpiv_plot_field(f, tpath("bad.png"), NULL, &p, NULL), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "arrow scale") != NULL);
    p.arrow_scale = 1;
    CHECK_FAILS(rpiv_plot_field(f, tpath("bad.jpg"), NULL, &p, NULL), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "bad.jpg: figures are written as PNG only") != NULL);
    CHECK_OK(rpiv_plot_path_check("a/B.PNG"));
    CHECK_FAILS(rpiv_plot_path_check("a.png/b"), RPIV_EINVAL);
    CHECK_FAILS(rpiv_plot_path_check("png"), RPIV_EINVAL);
    CHECK(access(tpath("bad.png"), F_OK) != 0 && access(tpath("bad.jpg"), F_OK) != 0);
    /* a zero field: no arrows, no reference; the image underneath, flipped for y-up */
    rpiv_image *im = NULL;
    CHECK_OK(rpiv_image_new(900, 500, &im));
    for (int k = 0; im && k < 900 * 500; k++)
        im->px[k] = (float)(k % 900 + k / 900);
    for (int k = 0; k < 56 * 30; k++)
        f->u[k] = f->v[k] = 0;
    CHECK_OK(rpiv_field_y_up(f, 500));
    p.background = im;
    p.quantity = "none";
    CHECK_OK(rpiv_plot_field(f, tpath("field_bg.png"), "zero", &p, &info));
    CHECK(png_size(tpath("field_bg.png"), &w, &h, &ink) && w == 1000 && h == 800);
    CHECK(info.ref_value == 0 && info.arrow_len == 0);
    rpiv_image_free(im);
    rpiv_field_free(f);
}

int main(void)
{
    const char *tmp = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/rpiv_test_plot_XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    RUN_TEST(quiver_writes_png_of_requested_size);
    RUN_TEST(map_cells_cover_their_span);
    RUN_TEST(lines_writes_png_with_legend);
    RUN_TEST(map_writes_png_for_image_and_scalar);
    RUN_TEST(plot_into_missing_folder_fails_with_path);
    RUN_TEST(report_writes_tables_and_profiles);
    RUN_TEST(field_figure_numbers);
    /* exactly the PNGs asked for, no temporary files left behind */
    CHECK(nfiles() == 11);
    int keep = getenv("RPIV_KEEP_PLOTS") != NULL;
    if (keep) {
        printf("plots kept in %s\n", dir);
    } else {
        const char *names[] = {"quiver.png",  "quiver2.png",  "quiver3.png",  "lines.png",
                               "lines2.png",  "image.png",    "map.png",      "field.png",
                               "field_v.png", "field_mm.png", "field_bg.png", "cells.png"};
        for (size_t k = 0; k < sizeof names / sizeof names[0]; k++)
            unlink(tpath(names[k]));
        rmdir(dir);
    }
    return check_summary();
}
