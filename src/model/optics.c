/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Ray tracing of the refracted laser sheet (paper: "Ray tracing model", Eq. "Desc").
 * Geometry and every choice: docs/optics.md. */
#include "rpiv/optics.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_cdf.h>
#include <omp.h>

#define DEG (M_PI / 180.0)

/* Power reflectance from the cosines of the incidence and refraction angles. These are the
 * Fresnel amplitudes in cosine form; r_p equals tan(theta_t - theta_i) / tan(theta_t + theta_i)
 * of Eq. "Desc" and r_s the sine form, but stay finite at normal incidence. */
static double reflectance(double n1, double n2, double ci, double ct, rpiv_polar pol)
{
    double rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    double rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    switch (pol) {
    case RPIV_POLAR_S:
        return rs * rs;
    case RPIV_POLAR_UNPOLARISED:
        return 0.5 * (rs * rs + rp * rp);
    case RPIV_POLAR_P:
        break;
    }
    return rp * rp;
}

int rpiv_optics_refract(double n1, double n2, double theta_i, rpiv_polar pol, double *theta_t,
                        double *T)
{
    double st = n1 / n2 * sin(theta_i);
    if (!(st < 1.0)) {
        if (theta_t)
            *theta_t = M_PI / 2;
        if (T)
            *T = 0;
        return 0;
    }
    double ci = cos(theta_i), ct = sqrt(1.0 - st * st);
    if (theta_t)
        *theta_t = asin(st);
    if (T)
        *T = 1.0 - reflectance(n1, n2, ci, ct, pol);
    return 1;
}

/* ---- geometry ------------------------------------------------------------------------------ */

/* The divergence: ray i's angle is the quantile q(i) = (i * DIV_STEP) mod DIV_LEVELS of a
 * Gaussian. DIV_STEP / DIV_LEVELS is close to the golden ratio's fraction 0.618 and DIV_STEP is
 * odd, so q visits every level once per DIV_LEVELS consecutive rays and the (height, angle)
 * pairs form a rank-1 (Fibonacci-like) lattice: even coverage, no random numbers. */
#define DIV_LEVELS 4096
#define DIV_STEP   2531

typedef struct vec2 {
    double x, z;
} vec2;

static double dot(vec2 a, vec2 b)
{
    return a.x * b.x + a.z * b.z;
}

/* z-component of a x b: the signed sine from a to b for unit vectors. */
static double cross(vec2 a, vec2 b)
{
    return a.x * b.z - a.z * b.x;
}

/* Everything a ray needs, fixed for a trace. */
typedef struct setup {
    vec2 n, np;  /* face inward normal (into the PMMA) and its +90 deg rotation     */
    vec2 P;      /* axis entry point on the face                                   */
    vec2 d0, u;  /* axis direction in air, and the lens plane direction (+90 deg)   */
    vec2 L;      /* lens centre                                                    */
    double eta1; /* n_air / n_pmma                                                 */
    double eta2; /* n_pmma / n_water                                               */
    double n_air, n_pmma, n_water;
    double W;      /* 1/e^2 radius of the beam at the lens                           */
    double div_sd; /* standard deviation of the ray angles from the beam's divergence    */
    double div_tab[DIV_LEVELS]; /* its quantiles at (q + 1/2) / DIV_LEVELS               */
    double inv_f;               /* 1 / focal length                                               */
    double bundle;              /* full width of the ray bundle                                   */
    double wnorm;               /* Gaussian weight normalisation                                  */
    rpiv_polar pol;
} setup;

static rpiv_status make_setup(const rpiv_laser *l, const rpiv_prism *p, setup *s,
                              rpiv_optics_axis *ax)
{
    rpiv_status st;
    if ((st = rpiv_laser_check(l)) || (st = rpiv_prism_check(p)))
        return st;
    double tp = p->theta_p_deg * DEG, b = l->beta1_deg * DEG, b_air, b_in;
    if (l->beta1_side == RPIV_BETA1_AIR) {
        b_air = b;
        b_in = asin(p->n_air * sin(b) / p->n_pmma);
    } else {
        double sa = p->n_pmma * sin(b) / p->n_air;
        if (!(fabs(sa) < 1))
            return rpiv_fail(RPIV_EINVAL,
                             "laser.beta1_deg: %g deg in the PMMA cannot come from the air "
                             "(n_pmma sin(beta1) / n_air = %g >= 1)",
                             l->beta1_deg, sa);
        b_in = b;
        b_air = asin(sa);
    }
    memset(s, 0, sizeof *s);
    s->n = (vec2){sin(tp), cos(tp)};
    s->np = (vec2){-cos(tp), sin(tp)};
    s->P = (vec2){-p->thickness_m * s->n.x, -p->thickness_m * s->n.z};
    /* positive beta1 turns the axis from the normal towards the vertical (counter-clockwise) */
    s->d0 = (vec2){cos(b_air) * s->n.x + sin(b_air) * s->np.x,
                   cos(b_air) * s->n.z + sin(b_air) * s->np.z};
    s->u = (vec2){-s->d0.z, s->d0.x};
    s->L = (vec2){s->P.x - l->lens_dist_m * s->d0.x, s->P.z - l->lens_dist_m * s->d0.z};
    s->n_air = p->n_air;
    s->n_pmma = p->n_pmma;
    s->n_water = p->n_water;
    s->eta1 = p->n_air / p->n_pmma;
    s->eta2 = p->n_pmma / p->n_water;
    s->W = 0.5 * l->beam_d_m * l->expander;
    /* intensity exp(-2 a^2 / a_w^2) with a_w the 1/e^2 half-angle after the expander */
    s->div_sd = 0.25 * l->divergence_rad / l->expander;
    for (int q = 0; q < DIV_LEVELS; q++)
        s->div_tab[q] = s->div_sd * gsl_cdf_ugaussian_Pinv((q + 0.5) / DIV_LEVELS);
    s->inv_f = 1.0 / l->lens_f_m;
    s->bundle = l->bundle_m;
    s->pol = l->polar;
    /* weights sum to about 1 for a complete bundle; the exact sum Ig is accumulated */
    s->wnorm = l->bundle_m / (double)l->nrays / (s->W * sqrt(M_PI / 2));

    /* the axis, inside the PMMA, in closed form */
    vec2 d1 = {cos(b_in) * s->n.x + sin(b_in) * s->np.x, cos(b_in) * s->n.z + sin(b_in) * s->np.z};
    if (!(d1.z > 0))
        return rpiv_fail(RPIV_EINVAL,
                         "laser.beta1_deg: the axis goes down in the prism (beta1 %g deg, "
                         "inclination %g deg)",
                         l->beta1_deg, p->theta_p_deg);
    memset(ax, 0, sizeof *ax);
    ax->beta1_air = b_air;
    ax->beta1_pmma = b_in;
    ax->theta_i = acos(d1.z);
    ax->theta_c = p->n_water < p->n_pmma ? asin(p->n_water / p->n_pmma) : M_PI / 2;
    ax->path_air_m = l->lens_dist_m;
    ax->depth_m = -s->P.z;
    ax->path_pmma_m = -s->P.z / d1.z;
    double xe = s->P.x + ax->path_pmma_m * d1.x;
    ax->x_apex_m = -p->thickness_m / sin(tp) - xe;
    rpiv_optics_refract(p->n_air, p->n_pmma, fabs(b_air), l->polar, NULL, &ax->T_face);
    ax->transmitted = rpiv_optics_refract(p->n_pmma, p->n_water, ax->theta_i, l->polar,
                                          &ax->theta_t, &ax->T_floor);
    ax->elevation = M_PI / 2 - ax->theta_t;
    return RPIV_OK;
}

rpiv_status rpiv_optics_axis_of(const rpiv_laser *l, const rpiv_prism *p, rpiv_optics_axis *out)
{
    setup s;
    return make_setup(l, p, &s, out);
}

/* What happened to one ray. */
enum fate { F_WATER, F_TIR, F_MISSED };

typedef struct ray_out {
    double w;      /* Gaussian weight                          */
    double T1, T2; /* face and floor transmissions             */
    double xf;     /* floor crossing, m                        */
    vec2 dw;       /* unit direction in the water              */
} ray_out;

/* Trace ray i, launched at height h (m) across the lens. */
static enum fate trace_ray(const setup *s, long i, double h, ray_out *r)
{
    r->w = s->wnorm * exp(-2.0 * h * h / (s->W * s->W));
    r->T1 = r->T2 = 0;
    /* thin lens on slopes: tan(alpha') = tan(alpha) - h / f; the divergence angles (about
     * 1 mrad) are taken as slopes */
    double slope = s->div_tab[(unsigned long)i * DIV_STEP % DIV_LEVELS] - h * s->inv_f,
           k = 1.0 / sqrt(1.0 + slope * slope);
    vec2 d = {(s->d0.x + slope * s->u.x) * k, (s->d0.z + slope * s->u.z) * k};
    vec2 S = {s->L.x + h * s->u.x, s->L.z + h * s->u.z};
    /* free flight to the inclined face */
    double ci = dot(d, s->n);
    if (!(ci > 0))
        return F_MISSED;
    double t = ((s->P.x - S.x) * s->n.x + (s->P.z - S.z) * s->n.z) / ci;
    vec2 H = {S.x + t * d.x, S.z + t * d.z};
    if (!(t >= 0) || !(H.z < 0))
        return F_MISSED; /* the lens is past the face, or the ray enters above the floor */
    /* air -> PMMA */
    double sn = s->eta1 * cross(s->n, d), ct2 = 1.0 - sn * sn;
    if (!(ct2 > 0)) {
        r->T1 = 1; /* nothing reflected by Fresnel: all of it lost by TIR (n_air > n_pmma) */
        return F_TIR;
    }
    double ct = sqrt(ct2);
    r->T1 = 1.0 - reflectance(s->n_air, s->n_pmma, ci, ct, s->pol);
    vec2 d1 = {ct * s->n.x + sn * s->np.x, ct * s->n.z + sn * s->np.z};
    /* flight in the prism to the floor z = 0 */
    if (!(d1.z > 0))
        return F_MISSED;
    r->xf = H.x - H.z / d1.z * d1.x;
    /* PMMA -> water: floor normal (0, 1), its +90 deg rotation (-1, 0) */
    double sw = -s->eta2 * d1.x, cw2 = 1.0 - sw * sw;
    if (!(cw2 > 0))
        return F_TIR;
    double cw = sqrt(cw2);
    r->T2 = 1.0 - reflectance(s->n_pmma, s->n_water, d1.z, cw, s->pol);
    r->dw = (vec2){-sw, cw};
    return F_WATER;
}

/* ---- the trace ----------------------------------------------------------------------------- */

rpiv_optics_opts rpiv_optics_opts_default(void)
{
    return (rpiv_optics_opts){.dz_star = 0.005, .smooth_star = 0, .threads = 0};
}

rpiv_status rpiv_optics_opts_check(const rpiv_optics_opts *o)
{
    if (!(o->dz_star >= 1e-5 && o->dz_star <= 0.5))
        return rpiv_fail(RPIV_EINVAL, "raytrace: bin width dz* %g outside 1e-5..0.5", o->dz_star);
    if (!(o->smooth_star >= 0 && o->smooth_star <= 1))
        return rpiv_fail(RPIV_EINVAL, "raytrace: smoothing sigma %g outside 0..1 (z*)",
                         o->smooth_star);
    if (o->threads < 0 || o->threads > 4096)
        return rpiv_fail(RPIV_EINVAL, "raytrace: threads %d outside 0..4096", o->threads);
    return RPIV_OK;
}

size_t rpiv_optics_nbins(const rpiv_optics_opts *o)
{
    return (size_t)ceil(1.0 / o->dz_star - 1e-9);
}

void rpiv_optics_result_free(rpiv_optics_result *r)
{
    if (!r)
        return;
    free(r->xstar);
    free(r->zstar);
    free(r->inten);
    free(r);
}

/* Per-chunk sums: incident, refl_face, refl_floor, tir, missed, transmitted. */
enum { S_INC, S_RFACE, S_RFLOOR, S_TIR, S_MISS, S_TRANS, S_N };

/* Trace rays [i0, i1) into one chunk's histogram and sums, in ray order. */
static void trace_chunk(const setup *s, long nrays, long i0, long i1, const double *X, size_t nx,
                        double h, size_t nz, double dz, double *hist, double *sum_out,
                        long *cnt_out)
{
    /* local sums: the chunks' output slots share cache lines */
    double sum[S_N] = {0}, inv_dz = 1.0 / dz;
    long cnt[3] = {0};
    for (long i = i0; i < i1; i++) {
        double hh = s->bundle * (((double)i + 0.5) / (double)nrays - 0.5);
        ray_out r;
        enum fate f = trace_ray(s, i, hh, &r);
        double w = r.w, a = w * r.T1, b = a * r.T2;
        sum[S_INC] += w;
        if (f == F_MISSED) {
            sum[S_MISS] += w;
            cnt[2]++;
            continue;
        }
        sum[S_RFACE] += w - a;
        if (f == F_TIR) {
            sum[S_TIR] += a;
            cnt[1]++;
            continue;
        }
        sum[S_RFLOOR] += a - b;
        sum[S_TRANS] += b;
        cnt[0]++;
        /* fluence rate: a tube crossing a vertical line at angle phi spans dz = width / cos phi */
        double wz = b / fabs(r.dw.x), slope = r.dw.z / (r.dw.x * h), fwd = r.dw.x;
        for (size_t k = 0; k < nx; k++) {
            double dx = X[k] - r.xf, zs = dx * slope; /* z* of the crossing */
            if (!(dx * fwd >= 0) || !(zs < 1.0))
                continue; /* behind the ray's start, or absorbed by the ceiling before */
            size_t j = (size_t)(zs * inv_dz);
            if (j < nz)
                hist[k * nz + j] += wz;
        }
    }
    memcpy(sum_out, sum, sizeof sum);
    memcpy(cnt_out, cnt, sizeof cnt);
}

/* Gaussian smoothing with the kernel renormalised over the bins inside the channel. */
static rpiv_status smooth_profiles(rpiv_optics_result *r, double sigma)
{
    size_t nz = r->nz, half = (size_t)ceil(4 * sigma / r->dz_star);
    if (half == 0)
        return RPIV_OK;
    double *ker = malloc((half + 1) * sizeof *ker), *tmp = malloc(nz * sizeof *tmp);
    if (!ker || !tmp) {
        free(ker);
        free(tmp);
        return rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory (smoothing)");
    }
    for (size_t m = 0; m <= half; m++) {
        double d = (double)m * r->dz_star / sigma;
        ker[m] = exp(-0.5 * d * d);
    }
    for (size_t k = 0; k < r->nx; k++) {
        double *p = r->inten + k * nz;
        for (size_t j = 0; j < nz; j++) {
            double acc = 0, wsum = 0;
            size_t lo = j > half ? j - half : 0, hi = j + half < nz - 1 ? j + half : nz - 1;
            for (size_t q = lo; q <= hi; q++) {
                double kk = ker[q > j ? q - j : j - q];
                acc += kk * p[q];
                wsum += kk;
            }
            tmp[j] = acc / wsum;
        }
        memcpy(p, tmp, nz * sizeof *p);
    }
    free(ker);
    free(tmp);
    return RPIV_OK;
}

/* Chunks are fixed by the ray count (not the thread count), each summed in ray order, and the
 * chunks summed in chunk order: the result is the same for any number of threads. */
#define CHUNK_MIN       4096L
#define CHUNK_MAX_COUNT 256L
#define CHUNK_MEM_MAX   (256.0 * 1024 * 1024)

rpiv_status rpiv_optics_trace(const rpiv_laser *l, const rpiv_prism *p, double h_m,
                              const double *xstar, size_t nx, const rpiv_optics_opts *o,
                              const rpiv_progress *prog, rpiv_optics_result **out)
{
    rpiv_status st;
    setup s;
    rpiv_optics_axis ax;
    *out = NULL;
    if ((st = rpiv_optics_opts_check(o)))
        return st;
    if (!(h_m > 0 && h_m < 1e3))
        return rpiv_fail(RPIV_EINVAL, "raytrace: channel height %g m outside (0, 1000)", h_m);
    if (nx < 1 || nx > 100000)
        return rpiv_fail(RPIV_EINVAL, "raytrace: %zu stations outside 1..100000", nx);
    for (size_t k = 0; k < nx; k++)
        if (!isfinite(xstar[k]) || fabs(xstar[k]) > 1e6)
            return rpiv_fail(RPIV_EINVAL, "raytrace: station x* = %g is not a finite position",
                             xstar[k]);
    if ((st = make_setup(l, p, &s, &ax)))
        return st;

    size_t nz = rpiv_optics_nbins(o), nb = nx * nz;
    long N = l->nrays;
    long nchunk = (N + CHUNK_MIN - 1) / CHUNK_MIN;
    if (nchunk > CHUNK_MAX_COUNT)
        nchunk = CHUNK_MAX_COUNT;
    while (nchunk > 1 && (double)nchunk * (double)nb * 8.0 > CHUNK_MEM_MAX)
        nchunk /= 2;
    long csize = (N + nchunk - 1) / nchunk;
    nchunk = (N + csize - 1) / csize;

    rpiv_optics_result *r = calloc(1, sizeof *r);
    double *hist = NULL, *sums = NULL;
    long *cnts = NULL;
    if (!r)
        return rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory");
    r->nx = nx;
    r->nz = nz;
    r->dz_star = 1.0 / (double)nz;
    r->smooth_star = o->smooth_star;
    r->laser = *l;
    r->prism = *p;
    r->axis = ax;
    r->h_m = h_m;
    r->xstar = malloc(nx * sizeof *r->xstar);
    r->zstar = malloc(nz * sizeof *r->zstar);
    r->inten = calloc(nb, sizeof *r->inten);
    hist = calloc((size_t)nchunk * nb, sizeof *hist);
    sums = calloc((size_t)nchunk * S_N, sizeof *sums);
    cnts = calloc((size_t)nchunk * 3, sizeof *cnts);
    double *X = malloc(nx * sizeof *X);
    if (!r->xstar || !r->zstar || !r->inten || !hist || !sums || !cnts || !X) {
        st = rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory (%ld chunks of %zu bins)", nchunk, nb);
        goto out_free;
    }
    memcpy(r->xstar, xstar, nx * sizeof *xstar);
    for (size_t j = 0; j < nz; j++)
        r->zstar[j] = ((double)j + 0.5) * r->dz_star;
    /* stations in metres, from the axis's emerging point */
    double xe = s.P.x + ax.path_pmma_m * sin(ax.theta_i);
    for (size_t k = 0; k < nx; k++)
        X[k] = xe + xstar[k] * h_m;

    int nthr = o->threads > 0 ? o->threads : omp_get_max_threads();
    long batch = (prog && prog->fn) ? (nchunk + 19) / 20 : nchunk;
    for (long c0 = 0; c0 < nchunk; c0 += batch) {
        long c1 = c0 + batch < nchunk ? c0 + batch : nchunk;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthr)
        for (long c = c0; c < c1; c++) {
            long i0 = c * csize, i1 = i0 + csize < N ? i0 + csize : N;
            trace_chunk(&s, N, i0, i1, X, nx, h_m, nz, r->dz_star, hist + (size_t)c * nb,
                        sums + (size_t)c * S_N, cnts + (size_t)c * 3);
        }
        long done = c1 * csize < N ? c1 * csize : N;
        if (rpiv_progress_report(prog, (size_t)done, (size_t)N)) {
            st = rpiv_fail(RPIV_EINTR, "raytrace: interrupted after %ld of %ld rays", done, N);
            goto out_free;
        }
    }

    double tot[S_N] = {0};
    long tc[3] = {0};
    for (long c = 0; c < nchunk; c++) {
        for (int q = 0; q < S_N; q++)
            tot[q] += sums[c * S_N + q];
        for (int q = 0; q < 3; q++)
            tc[q] += cnts[c * 3 + q];
    }
    if (!(tot[S_INC] > 0)) {
        st = rpiv_fail(RPIV_ENUMERIC, "raytrace: the beam carries no power (bundle %g mm)",
                       l->bundle_m * 1e3);
        goto out_free;
    }
    double scale = 1.0 / (tot[S_INC] * r->dz_star);
#pragma omp parallel for schedule(static) num_threads(nthr)
    for (size_t b = 0; b < nb; b++) {
        double acc = 0;
        for (long c = 0; c < nchunk; c++)
            acc += hist[(size_t)c * nb + b];
        r->inten[b] = acc * scale;
    }
    r->stats.incident = 1.0;
    r->stats.refl_face = tot[S_RFACE] / tot[S_INC];
    r->stats.refl_floor = tot[S_RFLOOR] / tot[S_INC];
    r->stats.tir = tot[S_TIR] / tot[S_INC];
    r->stats.missed = tot[S_MISS] / tot[S_INC];
    r->stats.transmitted = tot[S_TRANS] / tot[S_INC];
    r->stats.n_rays = N;
    r->stats.n_transmitted = tc[0];
    r->stats.n_tir = tc[1];
    r->stats.n_missed = tc[2];
    if (o->smooth_star > 0 && (st = smooth_profiles(r, o->smooth_star)))
        goto out_free;
    *out = r;
    r = NULL;
out_free:
    free(X);
    free(hist);
    free(sums);
    free(cnts);
    rpiv_optics_result_free(r);
    return st;
}

double rpiv_optics_profile_norm(const rpiv_optics_result *r, size_t k, double *out)
{
    const double *p = r->inten + k * r->nz;
    double mx = 0;
    for (size_t j = 0; j < r->nz; j++)
        if (p[j] > mx)
            mx = p[j];
    for (size_t j = 0; j < r->nz; j++)
        out[j] = mx > 0 ? p[j] / mx : 0;
    return mx;
}

rpiv_status rpiv_optics_metrics(const rpiv_optics_result *r, size_t k, rpiv_sheet_metrics *m)
{
    rpiv_status st = rpiv_sheet_metrics_of(r->zstar, r->inten + k * r->nz, r->nz, m);
    if (st) {
        char why[256];
        snprintf(why, sizeof why, "%s", rpiv_errmsg());
        return rpiv_fail(st, "raytrace: x* = %g: %s", r->xstar[k], why);
    }
    return RPIV_OK;
}

void rpiv_optics_metrics_all(const rpiv_optics_result *r, double *zinf, double *zmax, double *zsup,
                             double *e)
{
    for (size_t k = 0; k < r->nx; k++) {
        rpiv_sheet_metrics m;
        if (rpiv_optics_metrics(r, k, &m) == RPIV_OK) {
            zinf[k] = m.zinf;
            zmax[k] = m.zmax;
            zsup[k] = m.zsup;
            e[k] = m.e;
        } else {
            rpiv_errclear(); /* a dark station or one that does not fall to a quarter */
            zinf[k] = zmax[k] = zsup[k] = e[k] = (double)NAN;
        }
    }
}
