/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The Monte-Carlo sum of correlation (the paper's Fig. 17-18 algorithm): N particles per
 * window at random heights, N_im pairs summed, R repetitions. */
#include "ccm_impl.h"

#include "base/atomic.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_interp.h>
#include <gsl/gsl_rng.h>
#include <omp.h>

rpiv_ccm_mc_params rpiv_ccm_mc_params_default(void)
{
    static const size_t nim[] = {1,  2,  3,   5,   7,   10,  15,  20, 30,
                                 50, 70, 100, 150, 200, 300, 400, 500};
    rpiv_ccm_mc_params p;
    memset(&p, 0, sizeof p);
    p.nparticles = 15;
    p.repeats = 20;
    p.nnim = sizeof nim / sizeof nim[0];
    memcpy(p.nim, nim, sizeof nim);
    p.seed = 1;
    p.threads = 0;
    return p;
}

rpiv_status rpiv_ccm_mc_params_check(const rpiv_ccm_mc_params *p)
{
    if (p->nparticles < 1 || p->nparticles > 100000)
        return rpiv_fail(RPIV_EINVAL, "ccm: %zu particles per window outside 1..1e5",
                         p->nparticles);
    if (p->repeats < 2 || p->repeats > 100000)
        return rpiv_fail(RPIV_EINVAL, "ccm: %zu repetitions outside 2..1e5", p->repeats);
    if (p->nnim < 1 || p->nnim > sizeof p->nim / sizeof p->nim[0])
        return rpiv_fail(RPIV_EINVAL, "ccm: %zu values of N_im outside 1..%zu", p->nnim,
                         sizeof p->nim / sizeof p->nim[0]);
    for (size_t k = 0; k < p->nnim; k++) {
        if (p->nim[k] < 1 || p->nim[k] > 10000000)
            return rpiv_fail(RPIV_EINVAL, "ccm: N_im = %zu outside 1..1e7", p->nim[k]);
        if (k && p->nim[k] <= p->nim[k - 1])
            return rpiv_fail(RPIV_EINVAL, "ccm: N_im values not increasing at %zu", p->nim[k]);
    }
    if (p->threads < 0 || p->threads > 1024)
        return rpiv_fail(RPIV_EINVAL, "ccm: %d threads outside 0..1024", p->threads);
    return RPIV_OK;
}

void rpiv_ccm_mc_free(rpiv_ccm_mc_result *r)
{
    if (!r)
        return;
    free(r->nim);
    free(r->dx);
    free(r->dx_sub);
    free(r->mean);
    free(r->std);
    free(r->mean_sub);
    free(r->std_sub);
    free(r);
}

/* Heights drawn from P by inverting its cumulative integral tabulated on a regular grid
 * (exact for a uniform P, which needs no table). */
typedef struct sampler {
    const rpiv_ccm_model *m;
    size_t n;
    double *cdf; /* n values, cdf[n-1] = 1; NULL for uniform */
} sampler;

static rpiv_status sampler_init(sampler *s, const rpiv_ccm_model *m, size_t n)
{
    s->m = m;
    s->n = n;
    s->cdf = NULL;
    if (!m->presence.fn)
        return RPIV_OK;
    s->cdf = malloc(n * sizeof *s->cdf);
    if (!s->cdf)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    double h = (m->zhi - m->zlo) / (double)(n - 1), prev = ccm_presence(m, m->zlo);
    if (!(prev >= 0))
        prev = 0;
    s->cdf[0] = 0;
    for (size_t i = 1; i < n; i++) {
        double v = ccm_presence(m, m->zlo + h * (double)i);
        if (!(v >= 0)) {
            free(s->cdf);
            s->cdf = NULL;
            return rpiv_fail(RPIV_EINVAL, "ccm: the presence law is negative or NaN at z* = %g",
                             m->zlo + h * (double)i);
        }
        s->cdf[i] = s->cdf[i - 1] + 0.5 * h * (prev + v);
        prev = v;
    }
    double tot = s->cdf[n - 1];
    if (!(tot > 0)) {
        free(s->cdf);
        s->cdf = NULL;
        return rpiv_fail(RPIV_EINVAL, "ccm: the presence law is zero on [%g, %g]", m->zlo, m->zhi);
    }
    for (size_t i = 0; i < n; i++)
        s->cdf[i] /= tot;
    return RPIV_OK;
}

static double sampler_draw(const sampler *s, gsl_rng *rng)
{
    double u = gsl_rng_uniform(rng), lo = s->m->zlo, hi = s->m->zhi;
    if (!s->cdf)
        return lo + u * (hi - lo);
    /* the cell by GSL's bisection (the CDF is flat where P = 0, which gsl_interp refuses) */
    size_t a = gsl_interp_bsearch(s->cdf, u, 0, s->n - 1), b = a + 1;
    double da = s->cdf[b] - s->cdf[a], f = da > 0 ? (u - s->cdf[a]) / da : 0;
    return lo + (hi - lo) * ((double)a + f) / (double)(s->n - 1);
}

/* One repetition: pairs summed one after the other, the peak recorded at each N_im. */
static rpiv_status one_repeat(const rpiv_ccm_model *m, const rpiv_ccm_params *p,
                              const rpiv_ccm_mc_params *mc, const sampler *smp, size_t r,
                              double *dx, double *dx_sub)
{
    rpiv_status st = RPIV_OK;
    size_t npart = mc->nparticles, nmax = mc->nim[mc->nnim - 1];
    rpiv_ccm_corr *c = NULL;
    gsl_rng *rng = gsl_rng_alloc(gsl_rng_mt19937);
    if (!rng)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    gsl_rng_set(rng, ccm_seed(mc->seed, r));
    if ((st = rpiv_ccm_corr_new(npart * nmax, &c)))
        goto out_free;
    ccm_frame f;
    ccm_frame_init(&f, m);
    size_t k = 0;
    for (size_t pair = 1; pair <= nmax; pair++) {
        for (size_t i = 0; i < npart; i++)
            if ((st = rpiv_ccm_corr_add(c, ccm_simp_term(&f, sampler_draw(smp, rng)))))
                goto out_free;
        if (pair != mc->nim[k])
            continue;
        rpiv_ccm_peak pk;
        st = rpiv_ccm_corr_peak(c, p, &pk);
        if (st) {
            char why[256];
            snprintf(why, sizeof why, "%s", rpiv_errmsg());
            st = rpiv_fail(st, "repetition %zu, N_im = %zu: %s", r, pair, why);
            goto out_free;
        }
        dx[k] = pk.dx;
        dx_sub[k] = pk.dx_sub;
        k++;
    }
out_free:
    rpiv_ccm_corr_free(c);
    gsl_rng_free(rng);
    return st;
}

static void mean_std(const double *v, size_t stride, size_t n, double *mean, double *std)
{
    double s = 0, q = 0;
    for (size_t i = 0; i < n; i++)
        s += v[i * stride];
    s /= (double)n;
    for (size_t i = 0; i < n; i++)
        q += (v[i * stride] - s) * (v[i * stride] - s);
    *mean = s;
    *std = sqrt(q / (double)(n - 1));
}

rpiv_status rpiv_ccm_mc_run(const rpiv_ccm_model *m, const rpiv_ccm_params *p,
                            const rpiv_ccm_mc_params *mc, const rpiv_progress *progress,
                            rpiv_ccm_mc_result **out)
{
    *out = NULL;
    rpiv_status st;
    if ((st = rpiv_ccm_model_check(m)) || (st = rpiv_ccm_params_check(p)) ||
        (st = rpiv_ccm_mc_params_check(mc)))
        return st;
    size_t R = mc->repeats, K = mc->nnim;
    ccm_utab tab;
    rpiv_ccm_model tm;
    if ((st = ccm_utab_init(&tab, m, p, &tm)))
        return st;
    m = &tm; /* the velocity from the table from here on */
    sampler smp;
    if ((st = sampler_init(&smp, m, p->scan))) {
        ccm_utab_free(&tab);
        return st;
    }
    rpiv_ccm_mc_result *res = calloc(1, sizeof *res);
    rpiv_status *sts = calloc(R, sizeof *sts);
    char(*msg)[256] = calloc(R, sizeof *msg);
    if (res) {
        res->nnim = K;
        res->repeats = R;
        res->nim = malloc(K * sizeof *res->nim);
        res->dx = malloc(R * K * sizeof *res->dx);
        res->dx_sub = malloc(R * K * sizeof *res->dx_sub);
        res->mean = malloc(K * sizeof *res->mean);
        res->std = malloc(K * sizeof *res->std);
        res->mean_sub = malloc(K * sizeof *res->mean_sub);
        res->std_sub = malloc(K * sizeof *res->std_sub);
    }
    if (!res || !sts || !msg || !res->nim || !res->dx || !res->dx_sub || !res->mean || !res->std ||
        !res->mean_sub || !res->std_sub) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu x %zu results", R, K);
        goto out_free;
    }
    memcpy(res->nim, mc->nim, K * sizeof *res->nim);
    int nth = mc->threads > 0 ? mc->threads : omp_get_max_threads();
    /* batches of nth repetitions, so that progress is reported from this thread */
    for (size_t b = 0; b < R && !st; b += (size_t)nth) {
        size_t e = b + (size_t)nth < R ? b + (size_t)nth : R;
#pragma omp parallel for num_threads(nth) schedule(dynamic, 1)
        for (long r = (long)b; r < (long)e; r++) {
            sts[r] = one_repeat(m, p, mc, &smp, (size_t)r, res->dx + (size_t)r * K,
                                res->dx_sub + (size_t)r * K);
            if (sts[r])
                snprintf(msg[r], sizeof msg[r], "%s", rpiv_errmsg());
        }
        for (size_t r = b; r < e; r++)
            if (sts[r]) {
                st = rpiv_fail(sts[r], "%s", msg[r]);
                break;
            }
        if (!st && rpiv_progress_report(progress, e, R))
            st = rpiv_fail(RPIV_EINTR,
                           "ccm: Monte-Carlo interrupted after %zu of %zu "
                           "repetitions",
                           e, R);
    }
    if (st)
        goto out_free;
    for (size_t k = 0; k < K; k++) {
        mean_std(res->dx + k, K, R, &res->mean[k], &res->std[k]);
        mean_std(res->dx_sub + k, K, R, &res->mean_sub[k], &res->std_sub[k]);
    }
    *out = res;
    res = NULL;
out_free:
    rpiv_ccm_mc_free(res);
    free(sts);
    free(msg);
    free(smp.cdf);
    ccm_utab_free(&tab);
    return st;
}

rpiv_status rpiv_ccm_mc_save(const rpiv_ccm_mc_result *r, double scale_px, double dx_int,
                             double dx_sub_int, const char *hdr, const char *path)
{
    if (!(fabs(scale_px) > 0))
        return rpiv_fail(RPIV_EINVAL, "ccm: displacement scale is zero");
    atomic_file af; /* unique temporary name, fsync, rename, fsync of the folder */
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    FILE *fp = af.fp;
    fprintf(fp, "# rpiv-ccm-mc 1\n");
    ccm_file_header(fp, hdr);
    fprintf(fp, "# repetitions = %zu\n", r->repeats);
    fprintf(fp, "# integral U* = %.10g (continuous peak), %.10g (sub-pixel estimator)\n",
            dx_int / scale_px, dx_sub_int / scale_px);
    fprintf(fp, "# columns: N_im mean_U* std_U* mean_U*_subpixel std_U*_subpixel\n");
    for (size_t k = 0; k < r->nnim; k++)
        fprintf(fp, "%zu %.10g %.6e %.10g %.6e\n", r->nim[k], r->mean[k] / scale_px,
                r->std[k] / fabs(scale_px), r->mean_sub[k] / scale_px,
                r->std_sub[k] / fabs(scale_px));
    return atomic_commit(&af);
}
