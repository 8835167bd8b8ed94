/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench_ccm - the cross-correlation model's two speed targets (issue 6):
 *  - an integral prediction (Eq. "statform" + peak) at 100 positions in under 0.1 s: the R-PIV
 *    sheet at 100 sections; reference: the naive method, Brent's search on -<R_D> with a full
 *    adaptive quadrature (rpiv_ccm_stat_eval) at every step;
 *  - the Monte-Carlo convergence study, 20 repeats x 500 pairs x 15 particles, in under 2 s on
 *    2 cores.
 * Each case checks its result: the predictions agree with the naive method, the Monte-Carlo
 * results are identical for every thread count and converge to the integral. */
#include "rpiv/ccm.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_min.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define NPOS 100

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double cpu_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

typedef struct naive {
    const rpiv_ccm_model *m;
    rpiv_ccm_work *w;
    int failed;
} naive;

static double neg_stat(double dx, void *u)
{
    naive *n = u;
    double v = 0;
    if (rpiv_ccm_stat_eval(n->m, n->w, dx, 0, &v))
        n->failed = 1;
    return -v;
}

/* The naive prediction: Brent on -<R_D> bracketed by the integer samples, each evaluation an
 * adaptive quadrature. */
static int naive_peak(const rpiv_ccm_model *m, rpiv_ccm_work *w, double guess, double *dx)
{
    naive n = {m, w, 0};
    int k = (int)lround(guess);
    double fa = neg_stat(k - 1, &n), fm = neg_stat(k, &n), fb = neg_stat(k + 1, &n);
    while (fb < fm) {
        k++;
        fa = fm;
        fm = fb;
        fb = neg_stat(k + 1, &n);
    }
    while (fa < fm) {
        k--;
        fb = fm;
        fm = fa;
        fa = neg_stat(k - 1, &n);
    }
    gsl_min_fminimizer *s = gsl_min_fminimizer_alloc(gsl_min_fminimizer_brent);
    gsl_function F = {neg_stat, &n};
    int gs = gsl_min_fminimizer_set_with_values(s, &F, k, fm, k - 1, fa, k + 1, fb);
    for (int it = 0; !gs && it < 100; it++) {
        gs = gsl_min_fminimizer_iterate(s);
        double a = gsl_min_fminimizer_x_lower(s), b = gsl_min_fminimizer_x_upper(s);
        if (b - a < 1e-7 + 4e-8 * fabs(a))
            break;
    }
    *dx = gsl_min_fminimizer_x_minimum(s);
    gsl_min_fminimizer_free(s);
    return gs || n.failed;
}

static int case_predict(void)
{
    rpiv_ccm_params p = rpiv_ccm_params_default();
    rpiv_ccm_work *w = NULL;
    rpiv_sheet_params sp = rpiv_sheet_params_default();
    rpiv_sheet *s = NULL;
    if (rpiv_ccm_work_new(&p, &w) || rpiv_sheet_new(&sp, &s)) {
        fprintf(stderr, "predict: %s\n", rpiv_errmsg());
        return 1;
    }
    rpiv_ccm_model m = rpiv_ccm_model_default();
    m.camera.zop_star = 0.5;
    static double xs[NPOS], dx[NPOS], ref[NPOS];
    static rpiv_ccm_sheet_at at[NPOS];
    for (int i = 0; i < NPOS; i++) {
        xs[i] = 0.4 + (6.3 - 0.4) * i / (NPOS - 1);
        at[i] = (rpiv_ccm_sheet_at){s, xs[i]};
    }
    double t[7];
    int bad = 0;
    for (int r = 0; r < 7; r++) { /* one warm-up, then 6 timed runs */
        double t0 = now_s();
        for (int i = 0; i < NPOS; i++) {
            m.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at[i]};
            rpiv_ccm_peak pk;
            if (rpiv_ccm_predict(&m, w, &pk)) {
                fprintf(stderr, "predict: %s\n", rpiv_errmsg());
                return 1;
            }
            dx[i] = pk.dx;
        }
        t[r] = now_s() - t0;
    }
    double tr = median(t + 1, 6);
    double t0 = now_s();
    for (int i = 0; i < NPOS; i++) {
        m.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at[i]};
        bad |= naive_peak(&m, w, dx[i], &ref[i]);
    }
    double tn = now_s() - t0;
    double maxdiff = 0, sum = 0;
    for (int i = 0; i < NPOS; i++) {
        maxdiff = fmax(maxdiff, fabs(dx[i] - ref[i]));
        sum += dx[i] * (i + 1);
    }
    bad |= !(maxdiff < 1e-6);
    printf("%-28s %6s %7s %9s %9s %8s %s\n", "case", "size", "threads", "rpiv_ms", "ref_ms",
           "ratio", "checksum");
    printf("%-28s %6d %7d %9.2f %9.2f %8.1f %.10g\n", "predict_rpiv_sections", NPOS, 1, 1e3 * tr,
           1e3 * tn, tn / tr, sum);
    printf("  (rpiv_ccm_predict with the duct's series evaluated at every node)\n");
    printf("  max |peak - naive peak| = %.2e px %s\n", maxdiff, bad ? "FAIL" : "ok");
    /* the library's path for many positions: rpiv_ccm_scenario_run (velocity tabulated) */
    rpiv_ccm_scenario sc = rpiv_ccm_scenario_default(RPIV_CCM_RPIV);
    sc.n = NPOS;
    sc.z0 = 0.4 * 0.5 / 6.3;
    sc.symmetric = 0;
    double tw[5], tc[5];
    rpiv_ccm_table *tab = NULL;
    for (int r = 0; r < 5; r++) {
        rpiv_ccm_table_free(tab);
        tab = NULL;
        double w0 = now_s(), c0 = cpu_s();
        if (rpiv_ccm_scenario_run(&sc, &m, s, &p, 1, NULL, &tab)) {
            fprintf(stderr, "predict: %s\n", rpiv_errmsg());
            return 1;
        }
        tw[r] = now_s() - w0;
        tc[r] = cpu_s() - c0;
    }
    double wall = median(tw, 5), cpu = median(tc, 5), sum2 = 0, md2 = 0;
    for (size_t i = 0; i < tab->n; i++) {
        sum2 += tab->row[i].umodel * (double)(i + 1);
        double zi = tab->row[i].zstar;
        md2 = fmax(md2, fabs(tab->row[i].xstar - zi / (0.5 / 6.3)));
    }
    bad |= !(md2 < 1e-6);
    printf("%-28s %6d %7d %9.2f %9.2f %8.1f %.10g\n", "scenario_rpiv_sections", NPOS, 1, 1e3 * wall,
           1e3 * tn, tn / wall, sum2);
    printf("  target < 100 ms: %.1f %% of the target (wall); cpu time %.2f ms (%.1f %%)\n",
           100 * wall / 0.1, 1e3 * cpu, 100 * cpu / 0.1);
    rpiv_ccm_table_free(tab);
    rpiv_sheet_free(s);
    rpiv_ccm_work_free(w);
    return bad;
}

static int case_mc(void)
{
    rpiv_ccm_params p = rpiv_ccm_params_default();
    rpiv_sheet_params sp = rpiv_sheet_params_default();
    rpiv_sheet *s = NULL;
    rpiv_ccm_work *w = NULL;
    if (rpiv_sheet_new(&sp, &s) || rpiv_ccm_work_new(&p, &w)) {
        fprintf(stderr, "mc: %s\n", rpiv_errmsg());
        return 1;
    }
    rpiv_ccm_model m = rpiv_ccm_model_default();
    rpiv_ccm_sheet_at at = {s, 6.5};
    m.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
    m.camera.zop_star = 0.45;
    rpiv_ccm_peak pk;
    if (rpiv_ccm_predict(&m, w, &pk)) {
        fprintf(stderr, "mc: %s\n", rpiv_errmsg());
        return 1;
    }
    rpiv_ccm_mc_params mc = rpiv_ccm_mc_params_default();
    int maxt = omp_get_max_threads(), bad = 0;
    double *first = NULL, t1 = 0;
    size_t nv = mc.repeats * mc.nnim;
    for (int th = 1; th <= maxt; th = th < maxt ? maxt : maxt + 1) {
        mc.threads = th;
        double t[3], tc[3];
        rpiv_ccm_mc_result *r = NULL;
        for (int k = 0; k < 3; k++) {
            rpiv_ccm_mc_free(r);
            r = NULL;
            double t0 = now_s(), c0 = cpu_s();
            if (rpiv_ccm_mc_run(&m, &p, &mc, NULL, &r)) {
                fprintf(stderr, "mc: %s\n", rpiv_errmsg());
                return 1;
            }
            t[k] = now_s() - t0;
            tc[k] = cpu_s() - c0;
        }
        double tm = median(t, 3), tcpu = median(tc, 3), sum = 0;
        for (size_t i = 0; i < nv; i++)
            sum += r->dx[i] * (double)(i % 13 + 1);
        if (!first) {
            first = malloc(nv * sizeof *first);
            if (!first)
                return 1;
            memcpy(first, r->dx, nv * sizeof *first);
            t1 = tm;
        } else {
            bad |= memcmp(first, r->dx, nv * sizeof *first) != 0;
        }
        size_t kl = r->nnim - 1;
        bad |= !(fabs(r->mean[kl] - pk.dx) < 3 * r->std[kl]);
        printf("%-28s %6zu %7d %9.1f %9.1f %8.2f %.10g\n", "mc_convergence_20x500x15",
               mc.repeats * mc.nim[kl] * mc.nparticles, th, 1e3 * tm, 1e3 * t1, t1 / tm, sum);
        printf("  target < 2000 ms: %.1f %% of the target (wall), cpu time %.1f ms; mean(500) - "
               "integral = %.2e px, std(500) = %.2e px %s\n",
               100 * tm / 2.0, 1e3 * tcpu, r->mean[kl] - pk.dx, r->std[kl], bad ? "FAIL" : "ok");
        rpiv_ccm_mc_free(r);
    }
    free(first);
    rpiv_sheet_free(s);
    rpiv_ccm_work_free(w);
    return bad;
}

int main(void)
{
    rpiv_init();
    printf("# bench_ccm: threads available %d (ref_ms: predict = naive quadrature at every "
           "step; mc = 1 thread)\n",
           omp_get_max_threads());
    int bad = case_predict();
    bad |= case_mc();
    return bad;
}
