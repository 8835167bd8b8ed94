/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Series helpers: background of a series (min, mean), the per-pair series driver with its
 * sink, and mean/RMS statistics. */
#include "check.h"
#include "piv_testimg.h"
#include "rpiv/image.h"
#include "rpiv/piv.h"
#include "rpiv/series.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void stats_of_known_fields(void)
{
    rpiv_field *f = NULL, *mean = NULL, *rms = NULL;
    rpiv_series_stats *s = NULL;
    CHECK_OK(rpiv_field_new(3, 2, 15.5, 15.5, 16, 16, &f));
    if (!f)
        return;
    CHECK_OK(rpiv_series_stats_new(f, &s));
    const float us[3] = {1.25f, 2.5f, 4.75f};
    for (int t = 0; s && t < 3; t++) {
        for (int k = 0; k < 6; k++) {
            f->u[k] = us[t] + (float)k;
            f->v[k] = -us[t];
            f->flag[k] = RPIV_FLAG_VALID;
            f->corr[k] = 0.5f + 0.1f * (float)t;
            f->peak_ratio[k] = 2.0f * (float)(t + 1);
        }
        f->flag[1] = t == 1 ? RPIV_FLAG_REPLACED : RPIV_FLAG_VALID; /* left out at point 1 */
        f->flag[2] = RPIV_FLAG_REPLACED;                            /* never valid         */
        f->flag[3] = RPIV_FLAG_MASKED;                              /* always masked       */
        CHECK_OK(rpiv_series_stats_add(s, f));
    }
    CHECK(rpiv_series_stats_count(s) == 3);
    CHECK_OK(rpiv_series_stats_finish(s, &mean, &rms));
    if (mean && rms) {
        /* point 0: u = 1.25, 2.5, 4.75: mean 17/6, population std sqrt(1.5 ... ) */
        double m = (1.25 + 2.5 + 4.75) / 3,
               var =
                   ((1.25 - m) * (1.25 - m) + (2.5 - m) * (2.5 - m) + (4.75 - m) * (4.75 - m)) / 3;
        CHECK_NEAR(mean->u[0], m, 1e-6);
        CHECK_NEAR(mean->v[0], -m, 1e-6);
        CHECK_NEAR(rms->u[0], sqrt(var), 1e-6);
        CHECK_NEAR(mean->corr[0], 0.6, 1e-6);
        CHECK_NEAR(mean->peak_ratio[0], 4, 1e-6);
        CHECK(mean->flag[0] == RPIV_FLAG_VALID);
        /* point 1: the replaced vector of field 2 left out */
        CHECK_NEAR(mean->u[1], (1.25 + 4.75) / 2 + 1, 1e-6);
        CHECK_NEAR(rms->u[1], 1.75, 1e-6);
        /* point 2: only replaced vectors: their mean, flagged replaced */
        CHECK(mean->flag[2] == RPIV_FLAG_REPLACED);
        CHECK_NEAR(mean->u[2], m + 2, 1e-6);
        /* point 3: masked throughout */
        CHECK(mean->flag[3] == RPIV_FLAG_MASKED && mean->u[3] == 0 &&
              rms->flag[3] == RPIV_FLAG_MASKED);
    }
    rpiv_field *g = NULL;
    CHECK_OK(rpiv_field_new(3, 2, 15.5, 15.5, 16, 8, &g));
    if (g && s)
        CHECK_FAILS(rpiv_series_stats_add(s, g), RPIV_ESIZE);
    rpiv_series_stats *empty = NULL;
    rpiv_field *m2 = NULL, *r2 = NULL;
    CHECK_OK(rpiv_series_stats_new(f, &empty));
    if (empty)
        CHECK_FAILS(rpiv_series_stats_finish(empty, &m2, &r2), RPIV_EINVAL);
    rpiv_series_stats_free(empty);
    rpiv_field_free(g);
    rpiv_field_free(mean);
    rpiv_field_free(rms);
    rpiv_series_stats_free(s);
    rpiv_field_free(f);
}

typedef struct series_dir {
    char dir[64];
    char *args[8];
    int n;
} series_dir;

/* Three pairs of 96 x 80 float TIFFs: particles on a background that differs per frame:
 * A frames hold 100 + 0.5 x + 10 k, B frames 40 + 0.25 y + 7 k (k = pair index). */
static void write_series(series_dir *sd)
{
    enum { W = 96, H = 80 };
    snprintf(sd->dir, sizeof sd->dir, "/tmp/rpiv_series_XXXXXX");
    CHECK(mkdtemp(sd->dir) != NULL);
    rpiv_image *a = NULL, *b = NULL;
    CHECK_OK(rpiv_image_new(W, H, &a));
    CHECK_OK(rpiv_image_new(W, H, &b));
    sd->n = 0;
    for (int k = 0; a && b && k < 3; k++) {
        const double d[2] = {1.7213, -0.6419};
        ti_params tp = {W, H, 0.05, 2.5, 500, 0, 0, 900 + (uint64_t)k};
        ti_pair(&tp, ti_uniform, (void *)d, a->px, b->px);
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                a->px[y * W + x] += (float)(100 + 0.5 * x + 10 * k);
                b->px[y * W + x] += (float)(40 + 0.25 * y + 7 * k);
            }
        char pa[128], pb[128];
        snprintf(pa, sizeof pa, "%s/s%da.tif", sd->dir, k);
        snprintf(pb, sizeof pb, "%s/s%db.tif", sd->dir, k);
        CHECK_OK(rpiv_image_save_tiff_float(a, pa));
        CHECK_OK(rpiv_image_save_tiff_float(b, pb));
        sd->args[sd->n++] = strdup(pa);
        sd->args[sd->n++] = strdup(pb);
    }
    rpiv_image_free(a);
    rpiv_image_free(b);
}

static void remove_series(series_dir *sd)
{
    for (int i = 0; i < sd->n; i++) {
        remove(sd->args[i]);
        free(sd->args[i]);
    }
    rmdir(sd->dir);
}

/* The per-pixel min and mean over the A frames and over the B frames, computed here from the
 * files, must equal the streamed ones exactly (min) or to float rounding (mean). */
static void background_min_and_mean(void)
{
    enum { N = 96 * 80 };
    series_dir sd;
    write_series(&sd);
    rpiv_pairs *pairs = NULL;
    rpiv_image *ga = NULL, *gb = NULL;
    static float mn[2][N], sum[2][N];
    for (int i = 0; i < N; i++) {
        mn[0][i] = mn[1][i] = 1e30f;
        sum[0][i] = sum[1][i] = 0;
    }
    for (int f = 0; f < sd.n; f++) {
        rpiv_image *im = NULL;
        CHECK_OK(rpiv_image_load(sd.args[f], 0, &im, NULL));
        for (int i = 0; im && i < N; i++) {
            mn[f % 2][i] = fminf(mn[f % 2][i], im->px[i]);
            sum[f % 2][i] += im->px[i] / 3.0f;
        }
        rpiv_image_free(im);
    }
    CHECK_OK(rpiv_pairs_from_args(sd.n, sd.args, RPIV_PAIR_AB, &pairs));
    if (!pairs)
        goto out;
    CHECK_OK(rpiv_series_background(pairs, RPIV_BACKGROUND_MIN, NULL, &ga, &gb));
    if (ga && gb) {
        CHECK(!memcmp(ga->px, mn[0], sizeof mn[0]) && !memcmp(gb->px, mn[1], sizeof mn[1]));
        /* and the minimum of the A frames is at least pair 0's background */
        CHECK((double)ga->px[40 * 96 + 20] >= 100 + 0.5 * 20 - 1e-3);
    }
    rpiv_image_free(ga);
    rpiv_image_free(gb);
    CHECK_OK(rpiv_series_background(pairs, RPIV_BACKGROUND_MEAN, NULL, &ga, &gb));
    if (ga && gb) {
        double e = 0;
        for (int i = 0; i < N; i++)
            e = fmax(e, fmax(fabs((double)ga->px[i] - (double)sum[0][i]),
                             fabs((double)gb->px[i] - (double)sum[1][i])));
        CHECK(e < 1e-3);
    }
    rpiv_image_free(ga);
    rpiv_image_free(gb);
    CHECK_FAILS(rpiv_series_background(pairs, RPIV_BACKGROUND_NONE, NULL, &ga, &gb), RPIV_EINVAL);
    /* a series whose frames change size: the pair is named */
    {
        rpiv_image *sm = NULL;
        char pa[128], pb[128];
        rpiv_pairs *mixed = NULL;
        snprintf(pa, sizeof pa, "%s/t9a.tif", sd.dir);
        snprintf(pb, sizeof pb, "%s/t9b.tif", sd.dir);
        CHECK_OK(rpiv_image_new(64, 48, &sm));
        if (sm) {
            CHECK_OK(rpiv_image_save_tiff_float(sm, pa));
            CHECK_OK(rpiv_image_save_tiff_float(sm, pb));
        }
        char *args[4] = {sd.args[0], sd.args[1], pa, pb};
        CHECK_OK(rpiv_pairs_from_args(4, args, RPIV_PAIR_AB, &mixed));
        if (mixed) {
            CHECK_FAILS(rpiv_series_background(mixed, RPIV_BACKGROUND_MEAN, NULL, &ga, &gb),
                        RPIV_ESIZE);
            CHECK(strstr(rpiv_errmsg(), "t9a.tif") != NULL && ga == NULL);
        }
        rpiv_pairs_free(mixed);
        rpiv_image_free(sm);
        remove(pa);
        remove(pb);
    }
out:
    rpiv_pairs_free(pairs);
    remove_series(&sd);
}

typedef struct sink_state {
    int calls;
    size_t last;
    double err;
} sink_state;

static rpiv_status collect(void *user, size_t index, const rpiv_field *f)
{
    sink_state *s = user;
    s->calls++;
    s->last = index;
    for (int k = 0; k < f->nx * f->ny; k++)
        s->err = fmax(s->err, fmax(fabs((double)f->u[k] - 1.7213), fabs((double)f->v[k] + 0.6419)));
    return index == 1 && s->calls > 10 ? RPIV_EIO : RPIV_OK;
}

static int stop_at_two(void *user, size_t done, size_t total)
{
    (void)user;
    (void)total;
    return done >= 2;
}

/* The series driver with the background removed: every pair measured; a stop request. */
static void series_driver_runs_every_pair(void)
{
    series_dir sd;
    write_series(&sd);
    rpiv_pairs *pairs = NULL;
    rpiv_image *ga = NULL, *gb = NULL;
    rpiv_piv *pv = NULL;
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.win_w[0] = prm.win_h[0] = 48; /* 80 px high frames */
    sink_state s = {0, 0, 0};
    CHECK_OK(rpiv_pairs_from_args(sd.n, sd.args, RPIV_PAIR_AB, &pairs));
    CHECK_OK(rpiv_piv_new(&prm, 96, 80, NULL, &pv));
    if (!pairs || !pv)
        goto out;
    CHECK_OK(rpiv_series_background(pairs, RPIV_BACKGROUND_MIN, NULL, &ga, &gb));
    CHECK_OK(rpiv_piv_set_background(pv, ga, gb));
    CHECK_OK(rpiv_series_run(pv, pairs, collect, &s, NULL));
    CHECK(s.calls == 3 && s.last == 2);
    printf("    3 pairs, min background removed: max error %.4f px\n", s.err);
    CHECK(s.err < 0.05);
    rpiv_progress stop = {stop_at_two, NULL};
    s.calls = 0;
    CHECK_FAILS(rpiv_series_run(pv, pairs, collect, &s, &stop), RPIV_EINTR);
    CHECK(s.calls == 2);
out:
    rpiv_image_free(ga);
    rpiv_image_free(gb);
    rpiv_piv_free(pv);
    rpiv_pairs_free(pairs);
    remove_series(&sd);
}

/* rpiv_series_each: every pair in order, a job's failure stops the loop as it is, a stop
 * request gives RPIV_EINTR naming the count. */
typedef struct visits {
    size_t seen[16], n, fail_at;
} visits;

static rpiv_status visit(void *user, size_t i)
{
    visits *v = user;
    if (i == v->fail_at)
        return rpiv_fail(RPIV_EIO, "pair %zu: cannot write", i + 1);
    v->seen[v->n++] = i;
    return RPIV_OK;
}

static int stop_after_3(void *user, size_t done, size_t total)
{
    size_t *last_total = user;
    *last_total = total;
    return done >= 3;
}

static void each_visits_every_pair_in_order_and_stops(void)
{
    visits v = {.n = 0, .fail_at = 99};
    CHECK_OK(rpiv_series_each(7, NULL, visit, &v, NULL, "test"));
    CHECK(v.n == 7);
    for (size_t i = 0; i < v.n; i++)
        CHECK(v.seen[i] == i);
    v = (visits){.n = 0, .fail_at = 4};
    CHECK_FAILS(rpiv_series_each(7, NULL, visit, &v, NULL, "test"), RPIV_EIO);
    CHECK(strstr(rpiv_errmsg(), "pair 5: cannot write") != NULL);
    CHECK(v.n == 4);
    size_t total = 0;
    rpiv_progress stop = {stop_after_3, &total};
    v = (visits){.n = 0, .fail_at = 99};
    CHECK_FAILS(rpiv_series_each(7, NULL, visit, &v, &stop, "test"), RPIV_EINTR);
    CHECK(strstr(rpiv_errmsg(), "test: interrupted after 3 of 7 pairs") != NULL);
    CHECK(v.n == 3 && total == 7);
    v = (visits){.n = 0, .fail_at = 99};
    CHECK_OK(rpiv_series_each(0, NULL, visit, &v, &stop, "test"));
    CHECK(v.n == 0);
}

/* rpiv_piv_run_pairs: small frames go a pair per thread, yet every field has the bits of the
 * pair run alone on a one-thread plan; `done` sees the pairs in order, a failed load with
 * loaded = 0 and its message, and a stop status ends the run. */
typedef struct rp_ctx {
    float *a[6], *b[6];
    size_t seen[8], nseen;
    int fail_k, stop_k;
    rpiv_field *ref[6];
    int same, checked, msg_ok;
} rp_ctx;

static rpiv_status rp_load(void *user, size_t k, rpiv_image **a, rpiv_image **b)
{
    rp_ctx *c = user;
    if ((int)k == c->fail_k)
        return rpiv_fail(RPIV_EIO, "pair %zu: cannot read (test)", k);
    rpiv_status st = rpiv_image_new(128, 128, a);
    if (!st && (st = rpiv_image_new(128, 128, b))) {
        rpiv_image_free(*a);
        *a = NULL;
    }
    if (!st) {
        memcpy((*a)->px, c->a[k], 128 * 128 * sizeof(float));
        memcpy((*b)->px, c->b[k], 128 * 128 * sizeof(float));
    }
    return st;
}

static rpiv_status rp_done(void *user, size_t k, rpiv_status st, int loaded, rpiv_field *f)
{
    rp_ctx *c = user;
    c->seen[c->nseen++] = k;
    if ((int)k == c->fail_k) {
        c->msg_ok = st == RPIV_EIO && !loaded && !f && strstr(rpiv_errmsg(), "cannot read (test)");
    } else if (!st && f && c->ref[k]) {
        size_t n = (size_t)f->nx * (size_t)f->ny;
        c->checked++;
        c->same += n == (size_t)c->ref[k]->nx * (size_t)c->ref[k]->ny &&
                   !memcmp(f->u, c->ref[k]->u, n * sizeof *f->u) &&
                   !memcmp(f->v, c->ref[k]->v, n * sizeof *f->v) &&
                   !memcmp(f->flag, c->ref[k]->flag, n * sizeof *f->flag);
    }
    rpiv_field_free(f);
    return (int)k == c->stop_k ? rpiv_fail(RPIV_EINTR, "stop (test)") : RPIV_OK;
}

static void run_pairs_in_order_same_bits(void)
{
    rp_ctx c = {.fail_k = 2, .stop_k = 4};
    rpiv_piv_params p = rpiv_piv_params_default();
    p.threads = 1;
    rpiv_piv *one = NULL, *two = NULL;
    CHECK_OK(rpiv_piv_new(&p, 128, 128, NULL, &one));
    p.threads = 2;
    CHECK_OK(rpiv_piv_new(&p, 128, 128, NULL, &two));
    for (int k = 0; k < 6; k++) {
        c.a[k] = malloc(128 * 128 * sizeof(float));
        c.b[k] = malloc(128 * 128 * sizeof(float));
        double d[2] = {1.0 + 0.37 * k, -0.6 + 0.21 * k};
        ti_params tp = {128, 128, 0.04, 2.5, 1000, 0.02, 50, 900 + (uint64_t)k};
        ti_pair(&tp, ti_uniform, d, c.a[k], c.b[k]);
        rpiv_image ia = {128, 128, 8, c.a[k]}, ib = {128, 128, 8, c.b[k]};
        CHECK_OK(rpiv_piv_run(one, &ia, &ib, &c.ref[k]));
    }
    rpiv_status st = rpiv_piv_run_pairs(two, 6, rp_load, rp_done, &c);
    CHECK(st == RPIV_EINTR);
    CHECK(c.nseen == 5);
    for (size_t j = 0; j < c.nseen; j++)
        CHECK(c.seen[j] == j);
    CHECK(c.msg_ok);
    CHECK(c.checked == 4 && c.same == 4);
    printf("  %zu pairs seen in order, %d of %d fields bit-identical to the one-thread run\n",
           c.nseen, c.same, c.checked);
    for (int k = 0; k < 6; k++) {
        free(c.a[k]);
        free(c.b[k]);
        rpiv_field_free(c.ref[k]);
    }
    rpiv_piv_free(one);
    rpiv_piv_free(two);
}

int main(void)
{
    rpiv_init();
    RUN_TEST(stats_of_known_fields);
    RUN_TEST(background_min_and_mean);
    RUN_TEST(series_driver_runs_every_pair);
    RUN_TEST(each_visits_every_pair_in_order_and_stops);
    RUN_TEST(run_pairs_in_order_same_bits);
    return check_summary();
}
