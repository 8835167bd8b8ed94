/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_batch.c - long runs over a series (rpiv/batch.h) in one process, and the team of
 * one (rpiv/mpi.h): the batch ensemble equals rpiv_series_ensemble and the imposed shift; a run
 * stopped after any pair of any pass and resumed from its checkpoint ends with the same bits;
 * unreadable pairs are reported once, listed and left out (the result equals the run over
 * the readable pairs, background included); per-pair sinks see every field in order; and
 * every parameter error; the ensemble over pairs made in memory (rpiv_series_source) equals the
 * one over files. The MPI side runs for real in tests/cli/mpi.sh. */
#include "check.h"
#include "piv_testimg.h"

#include "rpiv/batch.h"
#include "rpiv/ensemble.h"
#include "rpiv/mpi.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum { W = 128, H = 96, NP = 4 };
static double SHIFT[2] = {2.3187, -1.1471};

static char dir[] = "/tmp/rpiv_batch_XXXXXX";
static char *paths[2 * (NP + 1)]; /* NP good pairs, then one whose B file is missing */

static void make_files(void)
{
    CHECK(mkdtemp(dir) != NULL);
    float *a = malloc(sizeof(float) * W * H), *b = malloc(sizeof(float) * W * H);
    rpiv_image ia = {W, H, 32, a}, ib = {W, H, 32, b};
    for (int i = 0; i <= NP; i++) {
        ti_params tp = {W, H, 0.03, 2.6, 800, 0.02, 40, 3001u + (uint64_t)i};
        char p[256];
        ti_pair(&tp, ti_uniform, SHIFT, a, b);
        for (int f = 0; f < 2; f++) {
            snprintf(p, sizeof p, "%s/f%02d%c.tif", dir, i, f ? 'b' : 'a');
            paths[2 * i + f] = strdup(p);
            if (i < NP || f == 0)
                CHECK_OK(rpiv_image_save_tiff_float(f ? &ib : &ia, p));
        }
    }
    free(a);
    free(b);
}

static void remove_files(void)
{
    for (int i = 0; i < 2 * (NP + 1); i++) {
        remove(paths[i]);
        free(paths[i]);
    }
    rmdir(dir);
}

/* The pairs `sel` (indices into the files, -1 ends), in that order (a list file). */
static rpiv_pairs *pairs_of(const int *sel)
{
    char list[300];
    snprintf(list, sizeof list, "%s/list.txt", dir);
    FILE *fp = fopen(list, "w");
    CHECK(fp != NULL);
    if (!fp)
        return NULL;
    for (int n = 0; sel[n] >= 0; n++)
        fprintf(fp, "%s %s\n", paths[2 * sel[n]], paths[2 * sel[n] + 1]);
    fclose(fp);
    rpiv_pairs *pp = NULL;
    char *args[1] = {list};
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &pp));
    remove(list);
    return pp;
}

static const int GOOD[] = {0, 1, 2, 3, -1};
static const int WITH_BAD[] = {0, 1, 4, 2, 3, -1}; /* pair index 2 cannot be read */

static rpiv_piv *plan(void)
{
    rpiv_piv_params p = rpiv_piv_params_default();
    rpiv_piv *pv = NULL;
    p.threads = 2;
    CHECK_OK(rpiv_piv_new(&p, W, H, NULL, &pv));
    return pv;
}

static int same_field(const rpiv_field *a, const rpiv_field *b)
{
    if (!a || !b || a->nx != b->nx || a->ny != b->ny)
        return 0;
    size_t n = (size_t)a->nx * (size_t)a->ny, fb = n * sizeof(float);
    return !memcmp(a->u, b->u, fb) && !memcmp(a->v, b->v, fb) && !memcmp(a->flag, b->flag, n) &&
           !memcmp(a->peak_ratio, b->peak_ratio, fb) && !memcmp(a->corr, b->corr, fb);
}

static void params_errors_are_named(void)
{
    rpiv_batch_params p = rpiv_batch_params_default();
    CHECK(p.checkpoint_every == 100 && !p.resume && !p.skip_bad && !p.checkpoint);
    CHECK_OK(rpiv_batch_params_check(&p));
    p.resume = 1;
    CHECK_FAILS(rpiv_batch_params_check(&p), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "resume needs a checkpoint") != NULL);
    p.checkpoint = "";
    CHECK_FAILS(rpiv_batch_params_check(&p), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "empty checkpoint") != NULL);
    rpiv_pairs none = {0, NULL};
    rpiv_batch *b = NULL;
    CHECK_FAILS(rpiv_batch_new(&none, NULL, NULL, &b), RPIV_EINVAL);
    CHECK(b == NULL);
    p.checkpoint = NULL;
    rpiv_pairs *pp = pairs_of(GOOD);
    CHECK_FAILS(rpiv_batch_new(pp, &p, NULL, &b), RPIV_EINVAL);
    rpiv_pairs_free(pp);
}

/* Run without a launcher: a team of one that never calls MPI_Init, also when RPIV_MPI=0
 * overrides launcher variables. */
static void mpi_team_of_one(void)
{
    rpiv_mpi *m = NULL;
    CHECK(rpiv_mpi_size(NULL) == 1 && rpiv_mpi_rank(NULL) == 0 && rpiv_mpi_mine(NULL, 7));
    CHECK_OK(rpiv_mpi_new(NULL, NULL, &m));
    if (m) {
        CHECK(rpiv_mpi_size(m) == 1 && rpiv_mpi_rank(m) == 0);
        CHECK(rpiv_mpi_mine(m, 0) && rpiv_mpi_mine(m, 3));
        CHECK(rpiv_mpi_agree(m, RPIV_OK) == RPIV_OK);
        (void)rpiv_fail(RPIV_EIO, "x.tif: gone");
        CHECK(rpiv_mpi_agree(m, RPIV_EIO) == RPIV_EIO);
        CHECK(!strcmp(rpiv_errmsg(), "x.tif: gone")); /* a team of one keeps the message */
    }
    rpiv_mpi_free(m);
    setenv("OMPI_COMM_WORLD_SIZE", "2", 1);
    setenv("RPIV_MPI", "0", 1);
    CHECK_OK(rpiv_mpi_new(NULL, NULL, &m));
    if (m)
        CHECK(rpiv_mpi_size(m) == 1);
    rpiv_mpi_free(m);
    unsetenv("OMPI_COMM_WORLD_SIZE");
    unsetenv("RPIV_MPI");
    rpiv_mpi_free(NULL);
}

static void ensemble_equals_ensemble_run_and_the_shift(void)
{
    rpiv_pairs *pp = pairs_of(GOOD);
    rpiv_piv *pv = plan();
    rpiv_batch *b = NULL;
    rpiv_field *fb = NULL, *fr = NULL;
    int w = 0, h = 0;
    CHECK_OK(rpiv_batch_new(pp, NULL, NULL, &b));
    if (b && pv) {
        CHECK_OK(rpiv_batch_size(b, &w, &h));
        CHECK(w == W && h == H);
        CHECK_OK(rpiv_batch_ensemble(b, pv, NULL, &fb));
        CHECK(rpiv_batch_npairs(b) == NP && rpiv_batch_nskipped(b) == 0);
        CHECK(!rpiv_batch_resumed(b, NULL, NULL));
        CHECK_OK(rpiv_series_ensemble(pv, pp, NULL, &fr));
        CHECK(same_field(fb, fr));
        double e = 0;
        size_t n = fb ? (size_t)fb->nx * (size_t)fb->ny : 0;
        for (size_t k = 0; k < n; k++)
            e += pow((double)fb->u[k] - SHIFT[0], 2) + pow((double)fb->v[k] - SHIFT[1], 2);
        CHECK(n > 0);
        CHECK_NEAR(sqrt(e / (double)(n ? n : 1)), 0, 0.02);
    }
    rpiv_field_free(fb);
    rpiv_field_free(fr);
    rpiv_batch_free(b);
    rpiv_piv_free(pv);
    rpiv_pairs_free(pp);
}

/* A progress callback that asks to stop after `stop` reports. */
static int stop_after(void *user, size_t done, size_t total)
{
    (void)total;
    return done >= *(size_t *)user;
}

/* Stopped after any pair of any pass (with `repeats` repeats of the final pass, tolerance 0 so
 * that they all run) and resumed: the same bits as the run in one go. */
static void resume_check(int repeats)
{
    rpiv_pairs *pp = pairs_of(GOOD);
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = 2;
    prm.ensemble_refine = repeats;
    prm.ensemble_refine_tol_px = 0;
    rpiv_piv *pv = NULL;
    rpiv_field *ref = NULL;
    char ck[300];
    snprintf(ck, sizeof ck, "%s/run.ck", dir);
    CHECK_OK(rpiv_piv_new(&prm, W, H, NULL, &pv));
    if (!pv || !pp)
        goto out;
    CHECK_OK(rpiv_series_ensemble(pv, pp, NULL, &ref));
    int npass = rpiv_piv_npass(pv) + repeats, bad = 0;
    for (size_t stop = 1; stop < (size_t)(NP * npass); stop++) {
        rpiv_batch_params p = rpiv_batch_params_default();
        rpiv_progress pr = {stop_after, &stop};
        rpiv_batch *b = NULL;
        rpiv_field *f = NULL;
        int pass = -1;
        size_t done = 0;
        p.checkpoint = ck;
        p.checkpoint_every = 3;
        CHECK_OK(rpiv_batch_new(pp, &p, NULL, &b));
        CHECK_FAILS(rpiv_batch_ensemble(b, pv, &pr, &f), RPIV_EINTR);
        CHECK(strstr(rpiv_errmsg(), "checkpoint") && strstr(rpiv_errmsg(), "saved"));
        CHECK(f == NULL && access(ck, F_OK) == 0);
        rpiv_batch_free(b);
        p.resume = 1;
        CHECK_OK(rpiv_batch_new(pp, &p, NULL, &b));
        CHECK_OK(rpiv_batch_ensemble(b, pv, NULL, &f));
        CHECK(rpiv_batch_resumed(b, &pass, &done));
        /* stopped after the stop-th pair: its pass, and the pairs summed there */
        CHECK(pass == (int)((stop - 1) / NP) && done == (stop - 1) % NP + 1);
        bad += !same_field(f, ref);
        CHECK(access(ck, F_OK) != 0); /* removed once complete */
        rpiv_field_free(f);
        rpiv_batch_free(b);
    }
    CHECK(bad == 0);
    if (repeats) { /* the repeats ran and changed the field */
        rpiv_piv_params off = prm;
        off.ensemble_refine = 0;
        rpiv_piv *pv0 = NULL;
        rpiv_field *f0 = NULL;
        CHECK_OK(rpiv_piv_new(&off, W, H, NULL, &pv0));
        if (pv0)
            CHECK_OK(rpiv_series_ensemble(pv0, pp, NULL, &f0));
        CHECK(f0 && ref && !same_field(f0, ref));
        rpiv_field_free(f0);
        rpiv_piv_free(pv0);
    }
out:
    rpiv_field_free(ref);
    rpiv_piv_free(pv);
    rpiv_pairs_free(pp);
}

static void resume_after_any_pair_is_bit_identical(void)
{
    resume_check(0);
}

static void resume_in_a_repeat_of_the_final_pass_is_bit_identical(void)
{
    resume_check(2);
}

typedef struct skips {
    int calls;
    size_t index;
    char msg[512];
} skips;

static void on_skip(void *user, size_t index, const char *msg)
{
    skips *s = user;
    s->calls++;
    s->index = index;
    snprintf(s->msg, sizeof s->msg, "%s", msg);
}

static void unreadable_pairs_are_skipped_and_listed(void)
{
    rpiv_pairs *bad = pairs_of(WITH_BAD), *good = pairs_of(GOOD);
    rpiv_piv *pv = plan();
    rpiv_batch_params p = rpiv_batch_params_default();
    rpiv_batch *b = NULL;
    rpiv_field *fs = NULL, *fg = NULL;
    skips s = {0};
    if (!bad || !good || !pv)
        goto out;
    /* without skip_bad: the error names the pair and the missing file */
    CHECK_OK(rpiv_batch_new(bad, &p, NULL, &b));
    CHECK_FAILS(rpiv_batch_ensemble(b, pv, NULL, &fs), RPIV_EIO);
    CHECK(strstr(rpiv_errmsg(), "pair 3 of 5") && strstr(rpiv_errmsg(), "f04b.tif"));
    rpiv_batch_free(b);
    p.skip_bad = 1;
    p.on_skip = on_skip;
    p.user = &s;
    CHECK_OK(rpiv_batch_new(bad, &p, NULL, &b));
    CHECK_OK(rpiv_batch_ensemble(b, pv, NULL, &fs));
    CHECK(s.calls == 1 && s.index == 2 && strstr(s.msg, "f04b.tif"));
    CHECK(rpiv_batch_nskipped(b) == 1 && rpiv_batch_skipped(b, 0) == 2);
    CHECK(rpiv_batch_npairs(b) == NP);
    CHECK_OK(rpiv_series_ensemble(pv, good, NULL, &fg));
    CHECK(same_field(fs, fg));
    /* the background over the readable pairs equals the good list's (a new batch finds the
     * bad pair again) */
    for (int kind = RPIV_BACKGROUND_MIN; kind <= RPIV_BACKGROUND_MEAN; kind++) {
        rpiv_image *ba = NULL, *bb = NULL, *ga = NULL, *gb = NULL;
        rpiv_batch_free(b);
        b = NULL;
        CHECK_OK(rpiv_batch_new(bad, &p, NULL, &b));
        CHECK_OK(rpiv_batch_background(b, (rpiv_background)kind, W, H, NULL, &ba, &bb));
        CHECK(rpiv_batch_nskipped(b) == 1 && rpiv_batch_skipped(b, 0) == 2);
        CHECK_OK(rpiv_series_background(good, (rpiv_background)kind, NULL, &ga, &gb));
        CHECK(ba && ga && !memcmp(ba->px, ga->px, sizeof(float) * W * H));
        CHECK(bb && gb && !memcmp(bb->px, gb->px, sizeof(float) * W * H));
        rpiv_image_free(ba);
        rpiv_image_free(bb);
        rpiv_image_free(ga);
        rpiv_image_free(gb);
    }
    CHECK(s.calls == 3); /* reported once by each batch */
out:
    rpiv_field_free(fs);
    rpiv_field_free(fg);
    rpiv_batch_free(b);
    rpiv_piv_free(pv);
    rpiv_pairs_free(bad);
    rpiv_pairs_free(good);
}

typedef struct seen {
    int nlocal, nroot;
    size_t order[8];
    rpiv_field *f[8];
} seen;

static rpiv_status local_fn(void *user, size_t i, const rpiv_field *f)
{
    seen *s = user;
    (void)f;
    s->order[s->nlocal++] = i;
    return RPIV_OK;
}

static rpiv_status root_fn(void *user, size_t i, const rpiv_field *f)
{
    seen *s = user;
    if (s->nroot == 8 || s->order[s->nroot] != i)
        return rpiv_fail(RPIV_EINVAL, "root sink before the local one for pair %zu", i + 1);
    return rpiv_field_copy(f, &s->f[s->nroot++]);
}

static rpiv_status failing_fn(void *user, size_t i, const rpiv_field *f)
{
    (void)user;
    (void)f;
    return rpiv_fail(RPIV_EIO, "sink refused pair %zu", i + 1);
}

static void series_calls_the_sinks_in_order(void)
{
    rpiv_pairs *bad = pairs_of(WITH_BAD);
    rpiv_piv *pv = plan();
    rpiv_batch_params p = rpiv_batch_params_default();
    rpiv_batch *b = NULL;
    seen s = {0};
    p.skip_bad = 1;
    if (!bad || !pv)
        goto out;
    CHECK_OK(rpiv_batch_new(bad, &p, NULL, &b));
    CHECK_OK(rpiv_batch_series(b, pv, local_fn, root_fn, &s, NULL));
    CHECK(s.nlocal == NP && s.nroot == NP);
    CHECK(s.order[0] == 0 && s.order[1] == 1 && s.order[2] == 3 && s.order[3] == 4);
    CHECK(rpiv_batch_nskipped(b) == 1 && rpiv_batch_skipped(b, 0) == 2);
    /* each field is the pair's own run */
    for (int k = 0; k < s.nroot; k++) {
        rpiv_image *a = NULL, *bb = NULL;
        rpiv_field *f = NULL;
        CHECK_OK(rpiv_pairs_load(bad, s.order[k], &a, &bb));
        CHECK_OK(rpiv_piv_run(pv, a, bb, &f));
        CHECK(same_field(f, s.f[k]));
        rpiv_field_free(f);
        rpiv_image_free(a);
        rpiv_image_free(bb);
    }
    CHECK_FAILS(rpiv_batch_series(b, pv, failing_fn, NULL, NULL, NULL), RPIV_EIO);
    CHECK(!strcmp(rpiv_errmsg(), "sink refused pair 1"));
out:
    for (int k = 0; k < s.nroot; k++)
        rpiv_field_free(s.f[k]);
    rpiv_batch_free(b);
    rpiv_piv_free(pv);
    rpiv_pairs_free(bad);
}

/* Pairs made in memory (here: read from the files, so the result can be compared), with a
 * count of the hook's calls; pair `fail_at` (0-based, -1 none) is refused. */
typedef struct made {
    const rpiv_pairs *pp;
    int fail_at, nadded, order_ok;
} made;

static rpiv_status made_pair(void *user, size_t i, int pass, rpiv_image *a, rpiv_image *b)
{
    made *m = user;
    rpiv_image *fa = NULL, *fb = NULL;
    (void)pass;
    if ((int)i == m->fail_at)
        return rpiv_fail(RPIV_EIO, "source: pair %zu refused", i + 1);
    rpiv_status st = rpiv_pairs_load(m->pp, i, &fa, &fb);
    if (!st && (fa->w != a->w || fa->h != a->h))
        st = rpiv_fail(RPIV_ESIZE, "source: pair %zu has another size", i + 1);
    if (!st) {
        memcpy(a->px, fa->px, sizeof(float) * (size_t)a->w * (size_t)a->h);
        memcpy(b->px, fb->px, sizeof(float) * (size_t)b->w * (size_t)b->h);
    }
    rpiv_image_free(fa);
    rpiv_image_free(fb);
    return st;
}

static rpiv_status made_added(void *user, int pass, size_t i, const rpiv_ensemble *e)
{
    made *m = user;
    m->order_ok &= rpiv_ensemble_pass(e) == pass && rpiv_ensemble_npairs(e) == i + 1;
    m->nadded++;
    return RPIV_OK;
}

/* The ensemble over a source is the ensemble over the same pairs in files, to the bit; the
 * hook sees every pair of every pass in order; a source's error stops the run as it is. */
static void ensemble_over_a_source_equals_the_files(void)
{
    rpiv_pairs *pp = pairs_of(GOOD);
    rpiv_piv *pv = plan();
    rpiv_field *ff = NULL, *fm = NULL;
    made m = {pp, -1, 0, 1};
    rpiv_series_source src = {pp ? pp->n : 0, made_pair, made_added, &m};
    if (!pp || !pv)
        goto out;
    CHECK_OK(rpiv_series_ensemble(pv, pp, NULL, &ff));
    CHECK_OK(rpiv_series_ensemble_source(pv, &src, NULL, &fm));
    CHECK(same_field(ff, fm));
    CHECK(m.nadded == NP * rpiv_piv_npass(pv) && m.order_ok);
    rpiv_field_free(fm);
    fm = NULL;
    m.fail_at = 2;
    CHECK_FAILS(rpiv_series_ensemble_source(pv, &src, NULL, &fm), RPIV_EIO);
    CHECK(fm == NULL && !strcmp(rpiv_errmsg(), "source: pair 3 refused"));
    src.n = 0;
    CHECK_FAILS(rpiv_series_ensemble_source(pv, &src, NULL, &fm), RPIV_EINVAL);
out:
    rpiv_field_free(ff);
    rpiv_field_free(fm);
    rpiv_piv_free(pv);
    rpiv_pairs_free(pp);
}

int main(void)
{
    rpiv_init();
    make_files();
    RUN_TEST(params_errors_are_named);
    RUN_TEST(mpi_team_of_one);
    RUN_TEST(ensemble_equals_ensemble_run_and_the_shift);
    RUN_TEST(resume_after_any_pair_is_bit_identical);
    RUN_TEST(resume_in_a_repeat_of_the_final_pass_is_bit_identical);
    RUN_TEST(unreadable_pairs_are_skipped_and_listed);
    RUN_TEST(series_calls_the_sinks_in_order);
    RUN_TEST(ensemble_over_a_source_equals_the_files);
    remove_files();
    return check_summary();
}
