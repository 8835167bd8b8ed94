/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_field.c - vector fields and their files: text round trip and reading foreign
 * column files, NetCDF layout (read back through the netCDF API), Tecplot and VTK parsed back,
 * load errors with file:line, atomic replacement. */
#include "check.h"
#include "rpiv/field.h"

#include <dirent.h>
#include <math.h>
#include <netcdf.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[256];

static const char *tpath(const char *name)
{
    static char buf[512];
    snprintf(buf, sizeof buf, "%s/%s", dir, name);
    return buf;
}

static void write_text(const char *path, const char *text)
{
    FILE *fp = fopen(path, "w");
    if (!fp)
        return;
    fputs(text, fp);
    fclose(fp);
}

static char *read_all(const char *path)
{
    FILE *fp = fopen(path, "r");
    if (!fp)
        return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    rewind(fp);
    char *s = malloc((size_t)n + 1);
    size_t got = fread(s, 1, (size_t)n, fp);
    s[got] = '\0';
    fclose(fp);
    return s;
}

/* A 7 x 5 field with distinct, non-round values everywhere. */
static rpiv_field *sample(void)
{
    rpiv_field *f = NULL;
    if (rpiv_field_new(7, 5, 12.5, 9.25, 16, 12, &f))
        return NULL;
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 7; i++) {
            size_t k = (size_t)j * 7 + (size_t)i;
            f->u[k] = 0.3187f * (float)(i + 1) - 1.7093f * (float)j;
            f->v[k] = -2.4481f + 0.1379f * (float)(i * j) + 1e-5f * (float)k;
            f->flag[k] = (unsigned char)(k % 3);
            f->peak_ratio[k] = 1.0f + 0.2113f * (float)k;
            f->corr[k] = 0.9871f - 0.0107f * (float)k;
        }
    return f;
}

static int count_tmp_files(void)
{
    int n = 0;
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d && (e = readdir(d)))
        if (strstr(e->d_name, ".tmp-"))
            n++;
    if (d)
        closedir(d);
    return n;
}

static void field_new_rejects_bad_grids(void)
{
    rpiv_field *f = (rpiv_field *)1;
    CHECK_FAILS(rpiv_field_new(0, 3, 0, 0, 1, 1, &f), RPIV_EINVAL);
    CHECK(f == NULL);
    CHECK_FAILS(rpiv_field_new(3, 3, 0, 0, 0, 1, &f), RPIV_EINVAL);
    CHECK_FAILS(rpiv_field_new(3, 3, 0, 0, 1, -2, &f), RPIV_EINVAL);
    CHECK_FAILS(rpiv_field_new(3, 3, (double)NAN, 0, 1, 1, &f), RPIV_EINVAL);
}

static void field_copy_is_deep_and_equal(void)
{
    rpiv_field *f = sample(), *c = NULL;
    f->scale_mm_per_px = 0.0213;
    f->dt_s = 3.1e-4;
    CHECK_OK(rpiv_field_copy(f, &c));
    CHECK(c && c->u != f->u);
    CHECK(c && memcmp(c->v, f->v, 35 * sizeof(float)) == 0);
    CHECK(c && memcmp(c->flag, f->flag, 35) == 0);
    CHECK(c && c->corr[34] == f->corr[34] && c->peak_ratio[3] == f->peak_ratio[3]);
    CHECK(c && c->x0 == 12.5 && c->dy == 12 && c->scale_mm_per_px == 0.0213 && c->dt_s == 3.1e-4);
    rpiv_field_free(c);
    rpiv_field_free(f);
}

static void meta_add_replaces_and_rejects_bad_keys(void)
{
    rpiv_meta m = {0};
    CHECK_OK(rpiv_meta_add(&m, "piv.window", "%d,%d", 64, 32));
    CHECK_OK(rpiv_meta_add(&m, "note", "two\nlines"));
    CHECK_OK(rpiv_meta_add(&m, "piv.window", "%s", "32"));
    CHECK(m.n == 2);
    CHECK(strcmp(m.val[0], "32") == 0);
    CHECK(strcmp(m.val[1], "two lines") == 0);
    CHECK_FAILS(rpiv_meta_add(&m, "1abc", "x"), RPIV_EINVAL);
    CHECK_FAILS(rpiv_meta_add(&m, "has space", "x"), RPIV_EINVAL);
    CHECK_FAILS(rpiv_meta_add(&m, "", "x"), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "key ''") != NULL);
    rpiv_meta_clear(&m);
    CHECK(m.n == 0 && m.key == NULL);
}

static void txt_round_trip_is_exact(void)
{
    rpiv_field *f = sample(), *g = NULL;
    f->scale_mm_per_px = 0.0213;
    f->dt_s = 3.1e-4;
    rpiv_meta m = {0};
    CHECK_OK(rpiv_meta_add(&m, "piv.window", "64,32"));
    CHECK_OK(rpiv_field_save(f, &m, tpath("a.txt")));
    CHECK_OK(rpiv_field_load_txt(tpath("a.txt"), &g));
    if (g) {
        CHECK(g->nx == 7 && g->ny == 5);
        CHECK_NEAR(g->x0, 12.5, 1e-12);
        CHECK_NEAR(g->y0, 9.25, 1e-12);
        CHECK_NEAR(g->dx, 16, 1e-12);
        CHECK_NEAR(g->dy, 12, 1e-12);
        /* floats are printed with enough digits to read back bit for bit */
        CHECK(memcmp(g->u, f->u, 35 * sizeof(float)) == 0);
        CHECK(memcmp(g->v, f->v, 35 * sizeof(float)) == 0);
        CHECK(memcmp(g->flag, f->flag, 35) == 0);
        CHECK(memcmp(g->peak_ratio, f->peak_ratio, 35 * sizeof(float)) == 0);
        CHECK(memcmp(g->corr, f->corr, 35 * sizeof(float)) == 0);
        CHECK(g->scale_mm_per_px == 0.0213 && g->dt_s == 3.1e-4);
    }
    /* the header carries the meta; the 11 columns of a data line hold mm and m/s */
    char *s = read_all(tpath("a.txt"));
    CHECK(s && strstr(s, "# piv.window = 64,32\n"));
    CHECK(s && strstr(s, "# x y u v flag peak_ratio correlation x_mm y_mm u_ms v_ms\n"));
    const char *last = s ? strrchr(s, '#') : NULL;
    last = last ? strchr(last, '\n') + 1 : NULL;
    double c[11];
    if (last) {
        /* the first data line is point (0, 0) */
        int n = sscanf(last, "%lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf", &c[0], &c[1], &c[2],
                       &c[3], &c[4], &c[5], &c[6], &c[7], &c[8], &c[9], &c[10]);
        CHECK(n == 11);
        CHECK_NEAR(c[0], 12.5, 0);
        CHECK_NEAR(c[1], 9.25, 0);
        CHECK_NEAR(c[7], 12.5 * 0.0213, 1e-12);
        CHECK_NEAR(c[8], 9.25 * 0.0213, 1e-12);
        CHECK_NEAR(c[9], (double)f->u[0] * 0.0213e-3 / 3.1e-4, 1e-8);
        CHECK_NEAR(c[10], (double)f->v[0] * 0.0213e-3 / 3.1e-4, 1e-8);
    }
    free(s);
    rpiv_meta_clear(&m);
    rpiv_field_free(g);
    rpiv_field_free(f);
}

static void txt_without_units_has_seven_columns(void)
{
    rpiv_field *f = sample();
    CHECK_OK(rpiv_field_save(f, NULL, tpath("b.txt")));
    char *s = read_all(tpath("b.txt"));
    CHECK(s && strstr(s, "# x y u v flag peak_ratio correlation\n"));
    CHECK(s && strstr(s, "\n12.5 9.25 0.3187 -2.4481 0 1 0.9871\n")); /* shortest exact form */
    free(s);
    rpiv_field_free(f);
}

/* Extra quantities: added, copied, written with their units and read back exactly. */
static void quantities_copy_and_round_trip(void)
{
    rpiv_field *f = sample(), *c = NULL, *g = NULL;
    float *w = NULL, *s = NULL;
    CHECK_OK(rpiv_field_add_quantity(f, "vorticity", RPIV_UNIT_PER_DT | RPIV_UNIT_ODD_Y, &w));
    CHECK_OK(rpiv_field_add_quantity(f, "sigma_u", RPIV_UNIT_PX_PER_DT, &s));
    CHECK_FAILS(rpiv_field_add_quantity(f, "vorticity", RPIV_UNIT_ONE, NULL), RPIV_EINVAL);
    CHECK_FAILS(rpiv_field_add_quantity(f, "u", RPIV_UNIT_ONE, NULL), RPIV_EINVAL);
    CHECK_FAILS(rpiv_field_add_quantity(f, "u_ms", RPIV_UNIT_ONE, NULL), RPIV_EINVAL);
    CHECK_FAILS(rpiv_field_add_quantity(f, "a b", RPIV_UNIT_ONE, NULL), RPIV_EINVAL);
    CHECK_FAILS(rpiv_field_add_quantity(f, "ok", 7, NULL), RPIV_EINVAL);
    if (!w || !s)
        goto out;
    for (int k = 0; k < 35; k++) {
        w[k] = 0.0123f * (float)k - 0.21f;
        s[k] = 0.05f + 0.001f * (float)k;
    }
    f->scale_mm_per_px = 0.0213;
    f->dt_s = 3.1e-4;
    CHECK_OK(rpiv_field_copy(f, &c));
    CHECK(c && c->nq == 2 && rpiv_field_quantity(c, "sigma_u") &&
          rpiv_field_quantity(c, "sigma_u")->data != s &&
          memcmp(rpiv_field_quantity(c, "sigma_u")->data, s, 35 * sizeof *s) == 0);
    CHECK_OK(rpiv_field_save(f, NULL, tpath("q.txt")));
    char *text = read_all(tpath("q.txt"));
    CHECK(text && strstr(text, "# quantity = vorticity 1/dt odd_y\n") &&
          strstr(text, "# quantity = sigma_u pix/dt\n"));
    CHECK(text && strstr(text, "# units = pix pix pix/dt pix/dt 1 1 1 1/dt pix/dt mm mm m/s m/s "
                               "1/s m/s\n"));
    CHECK(text && strstr(text, "# x y u v flag peak_ratio correlation vorticity sigma_u x_mm "
                               "y_mm u_ms v_ms vorticity_per_s sigma_u_ms\n"));
    free(text);
    CHECK_OK(rpiv_field_load_txt(tpath("q.txt"), &g));
    const rpiv_quantity *q = g ? rpiv_field_quantity(g, "vorticity") : NULL;
    CHECK(g && g->nq == 2 && q && q->unit == (RPIV_UNIT_PER_DT | RPIV_UNIT_ODD_Y));
    CHECK(q && memcmp(q->data, w, 35 * sizeof *w) == 0);
    q = g ? rpiv_field_quantity(g, "sigma_u") : NULL;
    CHECK(q && q->unit == RPIV_UNIT_PX_PER_DT && memcmp(q->data, s, 35 * sizeof *s) == 0);
    CHECK(g && memcmp(g->u, f->u, 35 * sizeof *f->u) == 0 && g->y_up == 0);
    /* the same columns in Tecplot and VTK */
    CHECK_OK(rpiv_field_save(f, NULL, tpath("q.dat")));
    text = read_all(tpath("q.dat"));
    CHECK(text && strstr(text, "VARIABLES = \"x\",\"y\",\"u\",\"v\",\"flag\",\"peak_ratio\","
                               "\"correlation\",\"vorticity\",\"sigma_u\",\"x_mm\",\"y_mm\","
                               "\"u_ms\",\"v_ms\",\"vorticity_per_s\",\"sigma_u_ms\"\n"));
    CHECK(text && strstr(text, "# units = pix pix pix/dt pix/dt 1 1 1 1/dt pix/dt mm mm"));
    free(text);
    CHECK_OK(rpiv_field_save(f, NULL, tpath("q.vtk")));
    text = read_all(tpath("q.vtk"));
    CHECK(text && strstr(text, "FIELD point_arrays 9\n") &&
          strstr(text, "\nvorticity 1 35 float\n") &&
          strstr(text, "\nvorticity_per_s 1 35 float\n") &&
          strstr(text, "\nvelocity_ms 3 35 float\n") && strstr(text, "\ncoords_mm 3 35 double\n"));
    free(text);
out:
    rpiv_field_free(g);
    rpiv_field_free(c);
    rpiv_field_free(f);
}

/* y-up: rows reversed, y measured from the bottom pixel, v and odd quantities negated, and
 * the orientation recorded and read back. */
static void y_up_turns_and_is_recorded(void)
{
    rpiv_field *f = sample(), *g = NULL, *h = NULL;
    float *w = NULL;
    CHECK_OK(rpiv_field_add_quantity(f, "vorticity", RPIV_UNIT_PER_DT | RPIV_UNIT_ODD_Y, &w));
    CHECK_OK(rpiv_field_add_quantity(f, "sigma_v", RPIV_UNIT_PX_PER_DT, NULL));
    if (!w)
        goto out;
    for (int k = 0; k < 35; k++)
        w[k] = (float)k + 0.5f;
    f->q[1].data[3] = 0.25f;
    CHECK_OK(rpiv_field_copy(f, &g));
    /* an image 80 px high: rows at y = 9.25 ... 57.25 become 80 - 1 - 57.25 = 21.75 ... 69.75 */
    CHECK_OK(rpiv_field_y_up(g, 80));
    CHECK_FAILS(rpiv_field_y_up(g, 80), RPIV_EINVAL);
    CHECK(g->y_up == 1 && g->y0 == 21.75 && g->dy == 12 && g->x0 == 12.5);
    int bad = 0;
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 7; i++) {
            size_t k = (size_t)j * 7 + (size_t)i, m = (size_t)(4 - j) * 7 + (size_t)i;
            bad += g->u[k] != f->u[m] || g->v[k] != -f->v[m] || g->flag[k] != f->flag[m] ||
                   g->q[0].data[k] != -w[m] || g->q[1].data[k] != f->q[1].data[m];
        }
    CHECK(bad == 0);
    CHECK_OK(rpiv_field_save(g, NULL, tpath("up.txt")));
    char *text = read_all(tpath("up.txt"));
    CHECK(text && strstr(text, "# orientation = y-up\n"));
    free(text);
    CHECK_OK(rpiv_field_load_txt(tpath("up.txt"), &h));
    CHECK(h && h->y_up == 1 && h->y0 == 21.75 && memcmp(h->v, g->v, 35 * sizeof *h->v) == 0);
    CHECK_OK(rpiv_field_save(g, NULL, tpath("up.vtk")));
    text = read_all(tpath("up.vtk"));
    CHECK(text && strstr(text, "orientation y-up"));
    free(text);
out:
    rpiv_field_free(h);
    rpiv_field_free(g);
    rpiv_field_free(f);
}

/* Two fields equal in everything the files carry: grid, vectors, flags, scale, dt,
 * orientation and quantities (names, units, values), bit for bit. */
static int same_field(const rpiv_field *a, const rpiv_field *b)
{
    size_t n = (size_t)a->nx * (size_t)a->ny;
    int ok = a->nx == b->nx && a->ny == b->ny && fabs(a->x0 - b->x0) < 1e-12 &&
             fabs(a->y0 - b->y0) < 1e-12 && fabs(a->dx - b->dx) < 1e-12 &&
             fabs(a->dy - b->dy) < 1e-12 && a->scale_mm_per_px == b->scale_mm_per_px &&
             a->dt_s == b->dt_s && a->y_up == b->y_up && a->nq == b->nq;
    ok = ok && !memcmp(a->u, b->u, n * sizeof *a->u) && !memcmp(a->v, b->v, n * sizeof *a->v) &&
         !memcmp(a->flag, b->flag, n) && !memcmp(a->peak_ratio, b->peak_ratio, n * sizeof(float)) &&
         !memcmp(a->corr, b->corr, n * sizeof(float));
    /* quantities by name: a NetCDF-4 file need not list its variables in creation order */
    for (size_t q = 0; ok && q < a->nq; q++) {
        const rpiv_quantity *e = rpiv_field_quantity(b, a->q[q].name);
        ok = e && a->q[q].unit == e->unit && !memcmp(a->q[q].data, e->data, n * sizeof(float));
    }
    return ok;
}

/* rpiv_field_load_nc reads back what rpiv_field_save wrote: image and y-up orientation, with
 * and without physical units, extra quantities with their units and y parity; a series' step
 * K; and bad input gives a one-line error naming the file. */
static void netcdf_round_trip_is_exact(void)
{
    rpiv_field *f = sample(), *g = NULL, *h = NULL;
    float *w = NULL, *s = NULL;
    CHECK_OK(rpiv_field_add_quantity(f, "vorticity", RPIV_UNIT_PER_DT | RPIV_UNIT_ODD_Y, &w));
    CHECK_OK(rpiv_field_add_quantity(f, "sigma_u", RPIV_UNIT_PX_PER_DT, &s));
    if (!f || !w || !s)
        goto out;
    for (int k = 0; k < 35; k++) {
        w[k] = 0.0123f * (float)k - 0.21f;
        s[k] = 0.05f + 0.001f * (float)k;
    }
    for (int pass = 0; pass < 4; pass++) {
        rpiv_field *src = NULL;
        CHECK_OK(rpiv_field_copy(f, &src));
        if (!src)
            break;
        if (pass & 1) {
            src->scale_mm_per_px = 0.0213;
            src->dt_s = 3.1e-4;
        }
        if (pass & 2)
            CHECK_OK(rpiv_field_y_up(src, 80));
        CHECK_OK(rpiv_field_save(src, NULL, tpath("rt.nc")));
        CHECK_OK(rpiv_field_load_nc(tpath("rt.nc"), 0, &g));
        CHECK(g && same_field(src, g));
        if (g && pass == 3)
            CHECK(g->y_up == 1 && g->y0 == 21.75 && g->scale_mm_per_px == 0.0213 &&
                  rpiv_field_quantity(g, "vorticity")->unit ==
                      (RPIV_UNIT_PER_DT | RPIV_UNIT_ODD_Y));
        rpiv_field_free(g);
        g = NULL;
        rpiv_field_free(src);
    }
    /* a series: step 2 is the third field; step 3 is out of range */
    rpiv_field_series *ser = NULL;
    CHECK_OK(rpiv_field_series_open(tpath("rt3.nc"), f, NULL, &ser));
    for (int t = 0; ser && t < 3; t++) {
        f->u[4] = 10.0f + (float)t;
        CHECK_OK(rpiv_field_series_append(ser, f, t));
    }
    CHECK_OK(rpiv_field_series_close(ser, 0));
    CHECK_OK(rpiv_field_load_nc(tpath("rt3.nc"), 2, &g));
    CHECK(g && g->u[4] == 12.0f && same_field(f, g));
    CHECK_OK(rpiv_field_load_nc(tpath("rt3.nc"), 0, &h));
    CHECK(h && h->u[4] == 10.0f && h->u[5] == f->u[5]);
    rpiv_field *z = (rpiv_field *)1;
    CHECK_FAILS(rpiv_field_load_nc(tpath("rt3.nc"), 3, &z), RPIV_EINVAL);
    CHECK(z == NULL && strstr(rpiv_errmsg(), "rt3.nc: time step 3 outside 0..2"));
    CHECK_FAILS(rpiv_field_load_nc(tpath("nope.nc"), 0, &z), RPIV_EIO);
    CHECK(strstr(rpiv_errmsg(), "nope.nc") != NULL);
    write_text(tpath("text.nc"), "x y u v\n1 2 3 4\n");
    CHECK_FAILS(rpiv_field_load_nc(tpath("text.nc"), 0, &z), RPIV_EFORMAT);
    CHECK(strstr(rpiv_errmsg(), "text.nc: not a NetCDF file") != NULL);
    /* a NetCDF file without pivpy's dims */
    int nc, d, var;
    CHECK(nc_create(tpath("other.nc"), NC_NETCDF4 | NC_CLOBBER, &nc) == NC_NOERR);
    CHECK(nc_def_dim(nc, "time", 3, &d) == NC_NOERR &&
          nc_def_var(nc, "w", NC_FLOAT, 1, &d, &var) == NC_NOERR);
    CHECK(nc_close(nc) == NC_NOERR);
    CHECK_FAILS(rpiv_field_load_nc(tpath("other.nc"), 0, &z), RPIV_EFORMAT);
    CHECK(strstr(rpiv_errmsg(), "other.nc: no dimension 'y'") != NULL);
out:
    rpiv_field_free(h);
    rpiv_field_free(g);
    rpiv_field_free(f);
}

static void load_reads_openpiv_style_columns(void)
{
    /* OpenPIV's save(): tab separated, a '# x y u v flags mask' header, 6th column a mask;
     * rows in any order (here y descending) */
    write_text(tpath("openpiv.txt"), "# x\ty\tu\tv\tflags\tmask\n"
                                     "16.0\t40.0\t1.25\t-0.5\t0\t1\n"
                                     "48.0\t40.0\t1.5\t-0.75\t1\t1\n"
                                     "16.0\t8.0\t0.3187\t2.5\t0\t0\n"
                                     "48.0\t8.0\t-4.125\t0.0625\t0\t0\n");
    rpiv_field *g = NULL;
    CHECK_OK(rpiv_field_load_txt(tpath("openpiv.txt"), &g));
    if (g) {
        CHECK(g->nx == 2 && g->ny == 2);
        CHECK(g->x0 == 16 && g->y0 == 8 && g->dx == 32 && g->dy == 32);
        CHECK(g->u[0] == 0.3187f && g->v[1] == 0.0625f);
        CHECK(g->u[2] == 1.25f && g->v[3] == -0.75f && g->flag[3] == 1);
        CHECK(g->peak_ratio[0] == 0 && g->corr[1] == 0); /* mask is not a peak ratio */
        CHECK(g->scale_mm_per_px == 0 && g->dt_s == 0);
    }
    rpiv_field_free(g);
    /* four columns, one row of points: dy borrows dx */
    write_text(tpath("row.txt"), "3 7 0.5 0.25\n5.5 7 0.75 0.125\n8 7 1 0\n");
    CHECK_OK(rpiv_field_load_txt(tpath("row.txt"), &g));
    if (g) {
        CHECK(g->nx == 3 && g->ny == 1 && g->dx == 2.5 && g->dy == 2.5 && g->flag[2] == 0);
        CHECK(g->u[2] == 1.0f);
    }
    rpiv_field_free(g);
}

/* Load path, expect code and a message starting with "<path>:<line>:" (line 0: just path). */
static void expect_load_error(const char *name, const char *text, rpiv_status code, int line,
                              const char *words)
{
    char want[600];
    rpiv_field *g = (rpiv_field *)1;
    const char *p = tpath(name);
    if (text)
        write_text(p, text);
    CHECK_FAILS(rpiv_field_load_txt(p, &g), code);
    CHECK(g == NULL);
    if (line)
        snprintf(want, sizeof want, "%s:%d: ", p, line);
    else
        snprintf(want, sizeof want, "%s: ", p);
    if (strncmp(rpiv_errmsg(), want, strlen(want)) != 0 || !strstr(rpiv_errmsg(), words)) {
        fprintf(stderr, "  message '%s' lacks '%s' ... '%s'\n", rpiv_errmsg(), want, words);
        check_current_failed = 1;
    }
}

static void load_errors_name_file_and_line(void)
{
    expect_load_error("e1.txt", "# c\n0 0 1 1\n1 0 x 1\n", RPIV_EFORMAT, 3, "'x' is not a number");
    expect_load_error("e2.txt", "0 0 1 1\n1 0 1\n", RPIV_EFORMAT, 2, "3 columns, need at least 4");
    expect_load_error("e3.txt", "0 0 1 1\n1 0 nan 1\n", RPIV_EFORMAT, 2, "NaN");
    expect_load_error("e4.txt", "0 0 1 1\n1 0 1 1\n2.37 0 1 1\n", RPIV_EFORMAT, 3,
                      "not a regular grid");
    expect_load_error("e5.txt", "0 0 1 1\n1 0 1 1\n0 1 1 1\n1 0 2 2\n", RPIV_EFORMAT, 4,
                      "repeats line 2");
    expect_load_error("e6.txt", "0 0 1 1\n1 0 1 1\n0 1 1 1\n", RPIV_EFORMAT, 0,
                      "not a regular grid: 3 vectors for 2 x 2 points");
    expect_load_error("e7.txt", "0 0 1 1 0.5\n", RPIV_EFORMAT, 1, "flag 0.5 is not an integer");
    expect_load_error("e8.txt", "0 0 1 1 0\n1 0 1 1\n", RPIV_EFORMAT, 2, "4 columns, line 1 has 5");
    expect_load_error("e9.txt", "# only a comment\n\n", RPIV_EFORMAT, 0, "no vectors");
    expect_load_error("missing.txt", NULL, RPIV_EIO, 0, "cannot open");
}

static void profile_load_reads_and_reverses(void)
{
    write_text(tpath("p.txt"), "# z* U*\n1 0.5 7\n0.6 0.25\n\n0.2 0.125\n");
    rpiv_profile *p = NULL;
    CHECK_OK(rpiv_profile_load(tpath("p.txt"), &p));
    if (p) {
        CHECK(p->n == 3);
        CHECK(p->alpha[0] == 0.2 && p->alpha[2] == 1 && p->value[0] == 0.125 && p->value[2] == 0.5);
    }
    rpiv_profile_free(p);
    int nc = 0;
    CHECK_OK(rpiv_text_columns(tpath("p.txt"), &nc));
    CHECK(nc == 3);
    write_text(tpath("p1.txt"), "0.5\n");
    rpiv_profile *q = (rpiv_profile *)1;
    CHECK_FAILS(rpiv_profile_load(tpath("p1.txt"), &q), RPIV_EFORMAT);
    CHECK(q == NULL && strstr(rpiv_errmsg(), "p1.txt:1: 1 column"));
    write_text(tpath("p2.txt"), "0 1\n0.5 2\n0.5 3\n");
    CHECK_FAILS(rpiv_profile_load(tpath("p2.txt"), &q), RPIV_EFORMAT);
    CHECK(strstr(rpiv_errmsg(), "p2.txt:3: alpha 0.5 is not increasing"));
    write_text(tpath("p3.txt"), "1 1\n0.5 2\n0.7 3\n");
    CHECK_FAILS(rpiv_profile_load(tpath("p3.txt"), &q), RPIV_EFORMAT);
    CHECK(strstr(rpiv_errmsg(), "p3.txt:3: alpha 0.7 is not decreasing"));
    write_text(tpath("p4.txt"), "# nothing\n0.5 1\n");
    CHECK_FAILS(rpiv_profile_load(tpath("p4.txt"), &q), RPIV_EFORMAT);
    CHECK(strstr(rpiv_errmsg(), "p4.txt: 1 point, a profile needs at least 2"));
    write_text(tpath("p5.txt"), "0 1\n0.5 inf\n");
    CHECK_FAILS(rpiv_profile_load(tpath("p5.txt"), &q), RPIV_EFORMAT);
    CHECK(strstr(rpiv_errmsg(), "p5.txt:2: column 2 is infinite"));
    CHECK_FAILS(rpiv_profile_load(tpath("nope.txt"), &q), RPIV_EIO);
    CHECK_OK(rpiv_text_columns(tpath("p4.txt"), &nc));
    CHECK(nc == 2);
    write_text(tpath("p6.txt"), "# only\n");
    CHECK_FAILS(rpiv_text_columns(tpath("p6.txt"), &nc), RPIV_EFORMAT);
}

/* A profile with n samples of a + b alpha + c alpha^2 from alpha0 in steps of h. */
static rpiv_profile *poly(size_t n, double alpha0, double h, double a, double b, double c)
{
    rpiv_profile *p = calloc(1, sizeof *p);
    p->n = n;
    p->alpha = malloc(n * sizeof(double));
    p->value = malloc(n * sizeof(double));
    for (size_t k = 0; k < n; k++) {
        double x = alpha0 + h * (double)k;
        p->alpha[k] = x;
        p->value[k] = a + b * x + c * x * x;
    }
    return p;
}

static void profile_compare_interpolates_and_scales(void)
{
    rpiv_compare r;
    /* a straight line is interpolated exactly from another grid: E1 = 0 on the overlap */
    rpiv_profile *ref = poly(11, 0, 0.1, 0.4, 1.3187, 0), *cmp = poly(4, 0.05, 0.3, 0.4, 1.3187, 0);
    CHECK_OK(rpiv_profile_compare(ref, cmp, &r));
    CHECK(r.n == 9); /* 0.1 .. 0.9 lie in 0.05 .. 0.95 */
    CHECK_NEAR(r.alpha0, 0.1, 1e-12);
    CHECK_NEAR(r.alpha1, 0.9, 1e-12);
    CHECK_NEAR(r.e1, 0, 1e-14);
    CHECK_NEAR(r.max_abs, 0, 1e-14);
    rpiv_profile_free(cmp);
    /* uniform reference, 10 % larger copy on another grid: E1 = 0.1, RMS = max = 0.1 * 2.5 */
    rpiv_profile *u = poly(5, 0, 0.25, 2.5, 0, 0), *u11 = poly(3, 0, 0.5, 2.75, 0, 0);
    CHECK_OK(rpiv_profile_compare(u, u11, &r));
    CHECK_NEAR(r.e1, 0.1, 1e-14);
    CHECK_NEAR(r.rms, 0.25, 1e-14);
    CHECK_NEAR(r.max_abs, 0.25, 1e-14);
    /* the unit of alpha does not matter: the same profiles over 0 .. 8 mm */
    for (size_t k = 0; k < u->n; k++)
        u->alpha[k] *= 8;
    for (size_t k = 0; k < u11->n; k++)
        u11->alpha[k] *= 8;
    CHECK_OK(rpiv_profile_compare(u, u11, &r));
    CHECK_NEAR(r.e1, 0.1, 1e-14);
    /* Poiseuille 6 a (1 - a) against 1.1 times itself: E1 = 0.1 sqrt(int U^2) / int U; the
     * trapezoid sums over 101 samples, computed here independently */
    rpiv_profile *p = poly(101, 0, 0.01, 0, 6, -6), *p11 = poly(101, 0, 0.01, 0, 6.6, -6.6);
    double s1 = 0, s2 = 0;
    for (size_t k = 1; k < 101; k++) {
        s1 += 0.005 * (p->value[k - 1] + p->value[k]);
        s2 += 0.005 * (p->value[k - 1] * p->value[k - 1] + p->value[k] * p->value[k]);
    }
    CHECK_OK(rpiv_profile_compare(p, p11, &r));
    CHECK_NEAR(r.e1, 0.1 * sqrt(s2) / s1, 1e-12);
    CHECK_NEAR(r.e1, 0.1 * sqrt(1.2), 2e-4); /* the continuous value */
    /* no overlap */
    rpiv_profile *far = poly(3, 2, 0.5, 1, 0, 0);
    CHECK_FAILS(rpiv_profile_compare(ref, far, &r), RPIV_ESIZE);
    CHECK(strstr(rpiv_errmsg(), "do not overlap") != NULL);
    /* zero reference */
    rpiv_profile *zero = poly(3, 0, 0.5, 0, 0, 0);
    CHECK_FAILS(rpiv_profile_compare(zero, u11, &r), RPIV_EINVAL);
    rpiv_profile_free(zero);
    rpiv_profile_free(far);
    rpiv_profile_free(p);
    rpiv_profile_free(p11);
    rpiv_profile_free(u);
    rpiv_profile_free(u11);
    rpiv_profile_free(ref);
}

static void field_compare_components_and_masks(void)
{
    rpiv_field *a = NULL, *b = NULL, *c = NULL;
    rpiv_compare r;
    CHECK_OK(rpiv_field_new(4, 3, 8, 8, 16, 16, &a));
    CHECK_OK(rpiv_field_new(4, 3, 8, 8, 16, 16, &b));
    CHECK_OK(rpiv_field_new(3, 4, 8, 8, 16, 16, &c));
    if (!a || !b || !c)
        goto out;
    for (int k = 0; k < 12; k++) {
        a->u[k] = 3.0f;
        a->v[k] = -4.0f; /* |u| = 5 */
        b->u[k] = 3.3f;
        b->v[k] = -4.4f; /* 1.1 times */
    }
    /* a masked point with a wild value is left out */
    b->u[7] = 100.0f;
    b->flag[7] = RPIV_FLAG_MASKED;
    CHECK_OK(rpiv_field_compare(a, b, RPIV_COMPONENT_MAG, &r));
    CHECK(r.n == 11);
    CHECK_NEAR(r.e1, 0.1, 1e-6);
    CHECK_NEAR(r.rms, 0.5, 1e-6);
    CHECK_OK(rpiv_field_compare(a, b, RPIV_COMPONENT_V, &r));
    CHECK_NEAR(r.e1, 0.1, 1e-6); /* |mean v| is the denominator */
    CHECK_NEAR(r.max_abs, 0.4, 1e-6);
    CHECK_OK(rpiv_field_compare(a, a, RPIV_COMPONENT_U, &r));
    CHECK(r.e1 == 0 && r.rms == 0 && r.n == 12);
    CHECK_FAILS(rpiv_field_compare(a, c, RPIV_COMPONENT_U, &r), RPIV_ESIZE);
    CHECK(strstr(rpiv_errmsg(), "grids differ: 4 x 3") != NULL);
    for (int k = 0; k < 12; k++)
        a->u[k] = k < 6 ? 1.0f : -1.0f;
    b->flag[7] = RPIV_FLAG_VALID;
    CHECK_FAILS(rpiv_field_compare(a, b, RPIV_COMPONENT_U, &r), RPIV_EINVAL);
    memset(b->flag, RPIV_FLAG_MASKED, 12);
    CHECK_FAILS(rpiv_field_compare(a, b, RPIV_COMPONENT_U, &r), RPIV_ESIZE);
out:
    rpiv_field_free(a);
    rpiv_field_free(b);
    rpiv_field_free(c);
}

static void save_rejects_unknown_extension(void)
{
    rpiv_field *f = sample();
    CHECK_FAILS(rpiv_field_save(f, NULL, tpath("out.xyz")), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "'.xyz'") != NULL);
    CHECK_FAILS(rpiv_field_save(f, NULL, tpath("noext")), RPIV_EINVAL);
    CHECK(access(tpath("out.xyz"), F_OK) != 0);
    rpiv_field_free(f);
}

static int att_text_is(int ncid, int var, const char *name, const char *want)
{
    size_t len = 0;
    char buf[256] = {0};
    if (nc_inq_attlen(ncid, var, name, &len) || len >= sizeof buf ||
        nc_get_att_text(ncid, var, name, buf))
        return 0;
    return strcmp(buf, want) == 0;
}

static void netcdf_layout_reads_back(void)
{
    rpiv_field *f = sample();
    f->scale_mm_per_px = 0.0213;
    f->dt_s = 3.1e-4;
    float *vort = NULL;
    CHECK_OK(rpiv_field_add_quantity(f, "vorticity", RPIV_UNIT_PER_DT | RPIV_UNIT_ODD_Y, &vort));
    for (int k = 0; vort && k < 35; k++)
        vort[k] = 0.01f * (float)k - 0.2f;
    double ms = 0.0213 * 1e-3 / 3.1e-4;
    rpiv_meta m = {0};
    CHECK_OK(rpiv_meta_add(&m, "piv.window", "64,32"));
    CHECK_OK(rpiv_meta_add(&m, "seed", "%d", 4711));
    CHECK_OK(rpiv_meta_add(&m, "files", "a.tif b.tif"));
    CHECK_OK(rpiv_field_save(f, &m, tpath("f.nc")));
    int ncid, fmt, ndims, nvars, unlim, id, dims[3];
    size_t len;
    if (nc_open(tpath("f.nc"), NC_NOWRITE, &ncid)) {
        CHECK(!"nc_open");
        goto out;
    }
    CHECK(nc_inq_format(ncid, &fmt) == 0 && fmt == NC_FORMAT_NETCDF4);
    /* x y t x_px y_px, u v chc flag peak_ratio correlation vorticity, u_px v_px vorticity_px */
    CHECK(nc_inq(ncid, &ndims, &nvars, NULL, &unlim) == 0 && ndims == 3 && nvars == 15);
    CHECK(nc_inq_dimid(ncid, "t", &id) == 0 && id == unlim);
    CHECK(nc_inq_dimlen(ncid, unlim, &len) == 0 && len == 1);
    CHECK(nc_inq_dimid(ncid, "y", &id) == 0 && nc_inq_dimlen(ncid, id, &len) == 0 && len == 5);
    CHECK(nc_inq_dimid(ncid, "x", &id) == 0 && nc_inq_dimlen(ncid, id, &len) == 0 && len == 7);
    CHECK(nc_inq_varid(ncid, "u", &id) == 0);
    CHECK(nc_inq_vardimid(ncid, id, dims) == 0);
    char dn[3][NC_MAX_NAME + 1];
    for (int d = 0; d < 3; d++)
        nc_inq_dimname(ncid, dims[d], dn[d]);
    CHECK(!strcmp(dn[0], "y") && !strcmp(dn[1], "x") && !strcmp(dn[2], "t"));
    float u[35], v[35], pr[35], cc[35], w[35];
    int bad = 0;
    CHECK(nc_get_var_float(ncid, id, u) == 0);
    CHECK(att_text_is(ncid, id, "units", "m/s"));
    CHECK(nc_inq_varid(ncid, "v", &id) == 0 && nc_get_var_float(ncid, id, v) == 0);
    for (int k = 0; k < 35; k++)
        bad += u[k] != (float)((double)f->u[k] * ms) || v[k] != (float)((double)f->v[k] * ms);
    CHECK(nc_inq_varid(ncid, "u_px", &id) == 0 && nc_get_var_float(ncid, id, u) == 0);
    CHECK(memcmp(u, f->u, sizeof u) == 0 && att_text_is(ncid, id, "units", "pix/dt"));
    CHECK(nc_inq_varid(ncid, "vorticity", &id) == 0 && nc_get_var_float(ncid, id, w) == 0);
    CHECK(att_text_is(ncid, id, "units", "1/s"));
    for (int k = 0; vort && k < 35; k++)
        bad += w[k] != (float)((double)vort[k] / 3.1e-4);
    CHECK(nc_inq_varid(ncid, "vorticity_px", &id) == 0 && nc_get_var_float(ncid, id, w) == 0);
    CHECK(vort && memcmp(w, vort, sizeof w) == 0 && att_text_is(ncid, id, "units", "1/dt"));
    CHECK(bad == 0);
    CHECK(nc_inq_varid(ncid, "peak_ratio", &id) == 0 && nc_get_var_float(ncid, id, pr) == 0);
    CHECK(memcmp(pr, f->peak_ratio, sizeof pr) == 0);
    CHECK(nc_inq_varid(ncid, "correlation", &id) == 0 && nc_get_var_float(ncid, id, cc) == 0);
    CHECK(memcmp(cc, f->corr, sizeof cc) == 0);
    nc_type type;
    unsigned char fl[35];
    signed char chc[35];
    CHECK(nc_inq_varid(ncid, "flag", &id) == 0 && nc_inq_vartype(ncid, id, &type) == 0 &&
          type == NC_BYTE);
    CHECK(nc_get_var_uchar(ncid, id, fl) == 0 && memcmp(fl, f->flag, 35) == 0);
    CHECK(att_text_is(ncid, id, "flag_meanings", "valid replaced masked"));
    CHECK(nc_inq_varid(ncid, "chc", &id) == 0 && nc_get_var_schar(ncid, id, chc) == 0);
    for (int k = 0; k < 35; k++)
        bad += chc[k] != (f->flag[k] == RPIV_FLAG_VALID);
    CHECK(bad == 0);
    double x[7], y[5], t;
    CHECK(nc_inq_varid(ncid, "x", &id) == 0 && nc_get_var_double(ncid, id, x) == 0);
    CHECK(x[0] == 12.5 * 0.0213 && x[6] == (12.5 + 6 * 16) * 0.0213);
    CHECK(att_text_is(ncid, id, "units", "mm"));
    CHECK(nc_inq_varid(ncid, "x_px", &id) == 0 && nc_get_var_double(ncid, id, x) == 0);
    CHECK(x[0] == 12.5 && x[6] == 12.5 + 6 * 16 && att_text_is(ncid, id, "units", "pix"));
    CHECK(nc_inq_varid(ncid, "y", &id) == 0 && nc_get_var_double(ncid, id, y) == 0);
    CHECK(y[0] == 9.25 * 0.0213 && y[4] == (9.25 + 4 * 12) * 0.0213);
    CHECK(nc_inq_varid(ncid, "t", &id) == 0 && nc_get_var_double(ncid, id, &t) == 0 && t == 0);
    CHECK(att_text_is(ncid, id, "units", "frame"));
    CHECK(att_text_is(ncid, NC_GLOBAL, "piv.window", "64,32"));
    CHECK(att_text_is(ncid, NC_GLOBAL, "seed", "4711"));
    CHECK(att_text_is(ncid, NC_GLOBAL, "orientation", "image"));
    double sc = 0, dt = 0;
    CHECK(nc_get_att_double(ncid, NC_GLOBAL, "scale_mm_per_px", &sc) == 0 && sc == 0.0213);
    CHECK(nc_get_att_double(ncid, NC_GLOBAL, "delta_t", &dt) == 0 && dt == 3.1e-4);
    char *files[1] = {NULL};
    CHECK(nc_inq_att(ncid, NC_GLOBAL, "files", &type, &len) == 0 && type == NC_STRING && len == 1);
    CHECK(nc_get_att_string(ncid, NC_GLOBAL, "files", files) == 0 && files[0] &&
          strcmp(files[0], "a.tif b.tif") == 0);
    nc_free_string(1, files);
    nc_close(ncid);
out:
    rpiv_meta_clear(&m);
    rpiv_field_free(f);
}

static void netcdf_series_of_three_along_t(void)
{
    rpiv_field *f = sample(), *other = NULL;
    rpiv_field_series *s = NULL;
    const double times[3] = {0.0, 3.1e-4, 6.2e-4};
    CHECK_OK(rpiv_field_series_open(tpath("s.nc"), f, NULL, &s));
    if (!s)
        goto out;
    for (int k = 0; k < 3; k++) {
        for (int q = 0; q < 35; q++)
            f->u[q] = 0.3187f * (float)(k + 1) + (float)q;
        CHECK_OK(rpiv_field_series_append(s, f, times[k]));
    }
    /* not published before close */
    CHECK(access(tpath("s.nc"), F_OK) != 0);
    CHECK_OK(rpiv_field_new(6, 5, 12.5, 9.25, 16, 12, &other));
    CHECK_FAILS(rpiv_field_series_append(s, other, 1.0), RPIV_ESIZE);
    CHECK(strstr(rpiv_errmsg(), "s.nc: field 3: grid 6 x 5") != NULL);
    CHECK_OK(rpiv_field_series_close(s, 0));
    int ncid, id, unlim;
    size_t nt = 0;
    if (nc_open(tpath("s.nc"), NC_NOWRITE, &ncid)) {
        CHECK(!"nc_open");
        goto out;
    }
    CHECK(nc_inq_unlimdim(ncid, &unlim) == 0 && nc_inq_dimlen(ncid, unlim, &nt) == 0 && nt == 3);
    double t[3];
    CHECK(nc_inq_varid(ncid, "t", &id) == 0 && nc_get_var_double(ncid, id, t) == 0);
    CHECK(t[0] == times[0] && t[1] == times[1] && t[2] == times[2]);
    float u[3 * 35];
    CHECK(nc_inq_varid(ncid, "u", &id) == 0 && nc_get_var_float(ncid, id, u) == 0);
    /* dims (y, x, t): point q of field k at q * 3 + k */
    CHECK(u[0] == 0.3187f && u[20 * 3 + 1] == 0.3187f * 2 + 20 &&
          u[34 * 3 + 2] == 0.3187f * 3 + 34);
    nc_close(ncid);
    CHECK(count_tmp_files() == 0);
    /* an aborted series leaves nothing */
    CHECK_OK(rpiv_field_series_open(tpath("aborted.nc"), f, NULL, &s));
    CHECK_OK(rpiv_field_series_append(s, f, 0));
    CHECK_OK(rpiv_field_series_close(s, 1));
    CHECK(access(tpath("aborted.nc"), F_OK) != 0);
    CHECK(count_tmp_files() == 0);
out:
    rpiv_field_free(other);
    rpiv_field_free(f);
}

static void tecplot_header_and_values_parse_back(void)
{
    rpiv_field *f = sample();
    rpiv_meta m = {0};
    CHECK_OK(rpiv_meta_add(&m, "piv.window", "32"));
    CHECK_OK(rpiv_field_save(f, &m, tpath("f.dat")));
    FILE *fp = fopen(tpath("f.dat"), "r");
    char line[512];
    int nvar = 0, ni = 0, nj = 0, rows = 0, bad = 0, zone = 0, comment = 0;
    while (fp && fgets(line, sizeof line, fp)) {
        if (line[0] == '#') {
            comment += strcmp(line, "# piv.window = 32\n") == 0;
            continue;
        }
        if (strncmp(line, "VARIABLES = ", 12) == 0) {
            nvar = strcmp(line, "VARIABLES = \"x\",\"y\",\"u\",\"v\",\"flag\",\"peak_ratio\","
                                "\"correlation\"\n") == 0
                       ? 7
                       : -1;
            continue;
        }
        if (strncmp(line, "ZONE", 4) == 0) {
            zone = sscanf(line, "ZONE T=\"rpiv\", I=%d, J=%d, F=POINT", &ni, &nj) == 2;
            continue;
        }
        if (!zone)
            continue;
        double c[7];
        if (sscanf(line, "%lf %lf %lf %lf %lf %lf %lf", &c[0], &c[1], &c[2], &c[3], &c[4], &c[5],
                   &c[6]) != 7) {
            bad++;
            continue;
        }
        int i = rows % 7, j = rows / 7;
        bad += c[0] != 12.5 + 16 * i || c[1] != 9.25 + 12 * j || (float)c[2] != f->u[rows] ||
               (float)c[3] != f->v[rows] || c[4] != f->flag[rows] ||
               (float)c[5] != f->peak_ratio[rows] || (float)c[6] != f->corr[rows];
        rows++;
    }
    if (fp)
        fclose(fp);
    CHECK(comment == 1);
    CHECK(nvar == 7);
    CHECK(zone && ni == 7 && nj == 5);
    CHECK(rows == 35);
    CHECK(bad == 0);
    rpiv_meta_clear(&m);
    rpiv_field_free(f);
}

static void vtk_header_and_values_parse_back(void)
{
    rpiv_field *f = sample();
    CHECK_OK(rpiv_field_save(f, NULL, tpath("f.vtk")));
    FILE *fp = fopen(tpath("f.vtk"), "r");
    char line[512];
    int nx = 0, ny = 0, nz = 0, bad = 0;
    size_t npts = 0, npd = 0;
    if (!fp) {
        CHECK(!"open f.vtk");
        goto out;
    }
    CHECK(fgets(line, sizeof line, fp) && strcmp(line, "# vtk DataFile Version 3.0\n") == 0);
    CHECK(fgets(line, sizeof line, fp)); /* title */
    CHECK(fgets(line, sizeof line, fp) && strcmp(line, "ASCII\n") == 0);
    CHECK(fgets(line, sizeof line, fp) && strcmp(line, "DATASET STRUCTURED_GRID\n") == 0);
    CHECK(fscanf(fp, " DIMENSIONS %d %d %d", &nx, &ny, &nz) == 3 && nx == 7 && ny == 5 && nz == 1);
    CHECK(fscanf(fp, " POINTS %zu double", &npts) == 1 && npts == 35);
    for (int k = 0; k < 35; k++) {
        double x, y, z;
        bad += fscanf(fp, "%lf %lf %lf", &x, &y, &z) != 3 || x != 12.5 + 16 * (k % 7) ||
               y != 9.25 + 12 * (k / 7) || z != 0;
    }
    CHECK(fscanf(fp, " POINT_DATA %zu", &npd) == 1 && npd == 35);
    CHECK(fscanf(fp, " VECTORS velocity float") == 0);
    for (int k = 0; k < 35; k++) {
        float u, v, w;
        bad += fscanf(fp, "%f %f %f", &u, &v, &w) != 3 || u != f->u[k] || v != f->v[k] || w != 0;
    }
    /* every other array as FIELD data, which VTK's default reader settings load */
    char name[32], type[32];
    size_t narr = 0, ntup = 0;
    int ncomp = 0;
    CHECK(fscanf(fp, " FIELD point_arrays %zu", &narr) == 1 && narr == 3);
    CHECK(fscanf(fp, " %31s %d %zu %31s", name, &ncomp, &ntup, type) == 4);
    CHECK(strcmp(name, "flag") == 0 && ncomp == 1 && ntup == 35 && strcmp(type, "int") == 0);
    for (int k = 0; k < 35; k++) {
        int fl;
        bad += fscanf(fp, "%d", &fl) != 1 || fl != f->flag[k];
    }
    CHECK(fscanf(fp, " %31s %d %zu %31s", name, &ncomp, &ntup, type) == 4);
    CHECK(strcmp(name, "peak_ratio") == 0 && ncomp == 1 && strcmp(type, "float") == 0);
    for (int k = 0; k < 35; k++) {
        float p;
        bad += fscanf(fp, "%f", &p) != 1 || p != f->peak_ratio[k];
    }
    CHECK(fscanf(fp, " %31s %d %zu %31s", name, &ncomp, &ntup, type) == 4);
    CHECK(strcmp(name, "correlation") == 0 && ncomp == 1 && strcmp(type, "float") == 0);
    for (int k = 0; k < 35; k++) {
        float p;
        bad += fscanf(fp, "%f", &p) != 1 || p != f->corr[k];
    }
    CHECK(bad == 0);
    fclose(fp);
out:
    rpiv_field_free(f);
}

static void failed_write_keeps_the_old_file(void)
{
    rpiv_field *f = sample(), *big = NULL;
    const char *old = "old content\n";
    /* missing folder */
    CHECK_FAILS(rpiv_field_save(f, NULL, tpath("no/such/dir/f.txt")), RPIV_EIO);
    CHECK(strstr(rpiv_errmsg(), "no/such/dir/f.txt") != NULL);
    CHECK_FAILS(rpiv_field_save(f, NULL, tpath("no/such/dir/f.nc")), RPIV_EIO);
    /* the target is a folder: the rename fails, the folder and its folder stay as they were */
    CHECK(mkdir(tpath("adir.txt"), 0755) == 0);
    CHECK_FAILS(rpiv_field_save(f, NULL, tpath("adir.txt")), RPIV_EIO);
    CHECK(count_tmp_files() == 0);
    /* a write that fails halfway (file size limit, works for root too) leaves the old file */
    write_text(tpath("keep.txt"), old);
    write_text(tpath("keep.nc"), old);
    CHECK_OK(rpiv_field_new(300, 300, 0, 0, 8, 8, &big));
    struct rlimit saved, lim;
    getrlimit(RLIMIT_FSIZE, &saved);
    lim = saved;
    lim.rlim_cur = 4096;
    void (*prev)(int) = signal(SIGXFSZ, SIG_IGN);
    CHECK(setrlimit(RLIMIT_FSIZE, &lim) == 0);
    rpiv_status st_txt = rpiv_field_save(big, NULL, tpath("keep.txt"));
    rpiv_status st_vtk = rpiv_field_save(big, NULL, tpath("keep.vtk"));
    setrlimit(RLIMIT_FSIZE, &saved);
    signal(SIGXFSZ, prev);
    CHECK(st_txt == RPIV_EIO && st_vtk == RPIV_EIO);
    char *s = read_all(tpath("keep.txt"));
    CHECK(s && strcmp(s, old) == 0);
    free(s);
    CHECK(access(tpath("keep.vtk"), F_OK) != 0);
    CHECK(count_tmp_files() == 0);
    /* a read-only folder (only meaningful when permissions apply to us) */
    CHECK(mkdir(tpath("ro"), 0755) == 0);
    write_text(tpath("ro/f.txt"), old);
    chmod(tpath("ro"), 0555);
    if (access(tpath("ro"), W_OK) != 0) {
        CHECK_FAILS(rpiv_field_save(f, NULL, tpath("ro/f.txt")), RPIV_EIO);
        CHECK(strstr(rpiv_errmsg(), "ro/f.txt: cannot create a temporary file") != NULL);
        s = read_all(tpath("ro/f.txt"));
        CHECK(s && strcmp(s, old) == 0);
        free(s);
    }
    chmod(tpath("ro"), 0755);
    /* and a successful save replaces the old file */
    CHECK_OK(rpiv_field_save(f, NULL, tpath("keep.txt")));
    s = read_all(tpath("keep.txt"));
    CHECK(s && strncmp(s, "# rpiv vector field 1\n", 22) == 0);
    free(s);
    rpiv_field_free(big);
    rpiv_field_free(f);
}

static void remove_tree(const char *path)
{
    DIR *d = opendir(path);
    struct dirent *e;
    char sub[1024];
    while (d && (e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        snprintf(sub, sizeof sub, "%s/%s", path, e->d_name);
        struct stat sb;
        if (lstat(sub, &sb) == 0 && S_ISDIR(sb.st_mode))
            remove_tree(sub);
        else
            unlink(sub);
    }
    if (d)
        closedir(d);
    rmdir(path);
}

int main(void)
{
    const char *tmp = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/rpiv_test_field_XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    RUN_TEST(field_new_rejects_bad_grids);
    RUN_TEST(field_copy_is_deep_and_equal);
    RUN_TEST(meta_add_replaces_and_rejects_bad_keys);
    RUN_TEST(txt_round_trip_is_exact);
    RUN_TEST(txt_without_units_has_seven_columns);
    RUN_TEST(quantities_copy_and_round_trip);
    RUN_TEST(y_up_turns_and_is_recorded);
    RUN_TEST(load_reads_openpiv_style_columns);
    RUN_TEST(load_errors_name_file_and_line);
    RUN_TEST(profile_load_reads_and_reverses);
    RUN_TEST(profile_compare_interpolates_and_scales);
    RUN_TEST(field_compare_components_and_masks);
    RUN_TEST(save_rejects_unknown_extension);
    RUN_TEST(netcdf_layout_reads_back);
    RUN_TEST(netcdf_series_of_three_along_t);
    RUN_TEST(netcdf_round_trip_is_exact);
    RUN_TEST(tecplot_header_and_values_parse_back);
    RUN_TEST(vtk_header_and_values_parse_back);
    RUN_TEST(failed_write_keeps_the_old_file);
    remove_tree(dir);
    return check_summary();
}
