/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/tools/unc_vortex_passes.c - where the vortex core's error comes from, pass by pass
 * (docs/uncertainty.md, "Session 9"; diagnostics, not built by CMake). The test flow's
 * Lamb-Oseen vortex, 256 x 256 px pairs (seeds 5000 + k), default passes with refine_max 0;
 * per 32 px bin of distance from the centre (the grid's edge apart), u | v: RMS error, its
 * part common to the pairs (node mean over the pairs, noise of the mean removed), the part
 * that changes from pair to pair, RMS sigma, coverage.
 *   unc_vortex_passes noise d_tau pairs mode     (mode: run, exact, exact1, lin, den, rho)
 * run: the whole run; exact: the final pass alone with the truth on the grid before as its
 * predictor; exact1: the truth on the first pass's grid as the second pass's predictor; lin:
 * the second pass with the first pass's field against with the truth, and the linear map of
 * the first pass's error (spline at the centre minus its window mean); den: the final
 * predictor's error after the refinement's denoiser, against the chain's linear model and the
 * denoiser's tangent at the predictor (finite difference); rho: the final pass's residual
 * against a white-predictor-error model. Env: NPASS, NODENOISE=1, FLOW=uniform.
 * Build (from build/): cc -O2 -fopenmp -std=c11 -D_DEFAULT_SOURCE -I../tests -I../include
 *   -Iinclude -I../src/piv -I../src/base ../tests/tools/unc_vortex_passes.c -o unc_vortex_passes
 *   librpiv.a -lfftw3f -lgsl -lgslcblas -ltiff -lpng16 -lnetcdf -lplplot -lstb -ljpeg -lm
 *   -L/usr/lib/x86_64-linux-gnu/openmpi/lib -lmpi */
#include "piv_impl.h"
#include "piv_testimg.h"
#include "rpiv/deform.h"
#include "rpiv/field.h"
#include "rpiv/piv.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void vortex(void *user, double x, double y, double *u, double *v)
{
    (void)user;
    const double cx = 128.37, cy = 127.81, a = 4, rc = 48, gmax = 0.6381726863;
    double dx = x - cx, dy = y - cy, r = sqrt(dx * dx + dy * dy);
    if (r < 1e-9) {
        *u = *v = 0;
        return;
    }
    double s = r / rc, ut = a * (1 - exp(-s * s)) / s / gmax;
    *u = -ut * dy / r + 0.4;
    *v = ut * dx / r;
}

enum { NB = 6, MAXN = 64 * 64 };
/* per node accumulators over seeds */
static double sum_e[2][MAXN], sum_e2[2][MAXN], sum_s2[2][MAXN], cov[2][MAXN];
static int cnt[MAXN], gnx, gny;
static double gx0, gy0, gdx, gdy;

static void acc(const rpiv_field *f)
{
    const rpiv_quantity *q[2] = {rpiv_field_quantity(f, "sigma_u"),
                                 rpiv_field_quantity(f, "sigma_v")};
    gnx = f->nx;
    gny = f->ny;
    gx0 = f->x0;
    gy0 = f->y0;
    gdx = f->dx;
    gdy = f->dy;
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            size_t k = (size_t)j * f->nx + i;
            if (f->flag[k] != RPIV_FLAG_VALID)
                continue;
            double t[2] = {3.27, -1.61};
            if (!(getenv("FLOW") && !strcmp(getenv("FLOW"), "uniform")))
                vortex(NULL, f->x0 + i * f->dx, f->y0 + j * f->dy, &t[0], &t[1]);
            double m[2] = {f->u[k], f->v[k]};
            for (int c = 0; c < 2; c++) {
                double e = m[c] - t[c], s = q[c] ? q[c]->data[k] : 0;
                sum_e[c][k] += e;
                sum_e2[c][k] += e * e;
                sum_s2[c][k] += s * s;
                cov[c][k] += fabs(e) <= s;
            }
            cnt[k]++;
        }
}

static void report(const char *title)
{
    printf("%s\n  bin      n  | u: rms_err mean_part rand_part rms_sig cov | v: same\n", title);
    double B[NB + 1][2][5];
    int N[NB + 1];
    memset(B, 0, sizeof B);
    memset(N, 0, sizeof N);
    for (int j = 0; j < gny; j++)
        for (int i = 0; i < gnx; i++) {
            size_t k = (size_t)j * gnx + i;
            int n = cnt[k];
            if (n < 2)
                continue;
            double x = gx0 + i * gdx, y = gy0 + j * gdy;
            int edge = i == 0 || j == 0 || i == gnx - 1 || j == gny - 1;
            int b = (int)(hypot(x - 128.37, y - 127.81) / 32);
            if (b > NB - 1)
                b = NB - 1;
            if (edge)
                b = NB;
            for (int c = 0; c < 2; c++) {
                double m = sum_e[c][k] / n, var = (sum_e2[c][k] - n * m * m) / (n - 1);
                B[b][c][0] += sum_e2[c][k];
                B[b][c][1] += n * (m * m - var / n);
                B[b][c][2] += n * var;
                B[b][c][3] += sum_s2[c][k];
                B[b][c][4] += cov[c][k];
            }
            N[b] += n;
        }
    for (int b = 0; b <= NB; b++) {
        if (!N[b])
            continue;
        if (b == NB)
            printf("  edge   ");
        else
            printf("  %3d-%3d", 32 * b, 32 * b + 32);
        printf(" %4d", N[b]);
        for (int c = 0; c < 2; c++)
            printf(" | %.4f %.4f %.4f %.4f %.2f", sqrt(B[b][c][0] / N[b]),
                   sqrt(fmax(0, B[b][c][1]) / N[b]), sqrt(B[b][c][2] / N[b]),
                   sqrt(B[b][c][3] / N[b]), B[b][c][4] / N[b]);
        printf("\n");
    }
    memset(sum_e, 0, sizeof sum_e);
    memset(sum_e2, 0, sizeof sum_e2);
    memset(sum_s2, 0, sizeof sum_s2);
    memset(cov, 0, sizeof cov);
    memset(cnt, 0, sizeof cnt);
}

int main(int argc, char **argv)
{
    double noise = argc > 1 ? atof(argv[1]) : 0.05, tau = argc > 2 ? atof(argv[2]) : 2.0;
    int nseed = argc > 3 ? atoi(argv[3]) : 16;
    const char *mode = argc > 4 ? argv[4] : "run";
    const int size = 256;
    float *a = malloc(sizeof *a * size * size), *b = malloc(sizeof *b * size * size);
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.uncertainty = 1;
    prm.refine_max = 0;
    prm.refine_tol_px = 0;
    if (getenv("NODENOISE"))
        prm.refine_denoise = 0;
    if (getenv("NPASS"))
        prm.npass = atoi(getenv("NPASS"));
    if (getenv("REFINE"))
        prm.refine_max = atoi(getenv("REFINE"));
    rpiv_piv *pv = NULL;
    if (rpiv_piv_new(&prm, size, size, NULL, &pv))
        return 1;
    for (int q = 0; q < nseed; q++) {
        ti_params tp = {size, size, 0.05, tau, 1000, noise, 0, 5000 + (uint64_t)q};
        static double uni[2] = {3.27, -1.61};
        if (getenv("FLOW") && !strcmp(getenv("FLOW"), "uniform"))
            ti_pair(&tp, ti_uniform, uni, a, b);
        else
            ti_pair(&tp, vortex, NULL, a, b);
        rpiv_image ia = {size, size, 16, a}, ib = {size, size, 16, b};
        rpiv_field *f = NULL;
        if (!strcmp(mode, "run")) {
            if (rpiv_piv_run(pv, &ia, &ib, &f))
                return 2;
        } else if (!strcmp(mode,
                           "lin")) { /* pass 1 with pass 0's field vs with the truth; linear G e0 */
            rpiv_field *f0 = NULL, *g = NULL, *fa = NULL, *fb = NULL;
            if (rpiv_piv_load(pv, &ia, &ib) || rpiv_piv_step(pv, 0, NULL, &f0) ||
                rpiv_piv_grid(pv, 0, &g))
                return 3;
            for (int j = 0; j < g->ny; j++)
                for (int i = 0; i < g->nx; i++) {
                    double u, v;
                    vortex(NULL, g->x0 + i * g->dx, g->y0 + j * g->dy, &u, &v);
                    size_t k = (size_t)j * g->nx + i;
                    g->u[k] = (float)u;
                    g->v[k] = (float)v;
                }
            if (rpiv_piv_step(pv, 1, g, &fa) || rpiv_piv_step(pv, 1, f0, &fb))
                return 4;
            /* e0 field */
            for (size_t k = 0; k < (size_t)g->nx * g->ny; k++) {
                g->u[k] = f0->u[k] - g->u[k];
                g->v[k] = f0->v[k] - g->v[k];
            }
            rpiv_deform_pred *pe = NULL;
            if (rpiv_deform_pred_new(g, size, size, 0, &pe))
                return 5;
            const double sh = 0.25;
            int ww = 32;
            static double A[4], n4;
            for (int j = 0; j < fa->ny; j++)
                for (int i = 0; i < fa->nx; i++) {
                    size_t k = (size_t)j * fa->nx + i;
                    double x = fa->x0 + i * fa->dx, y = fa->y0 + j * fa->dy;
                    if (hypot(x - 128.37, y - 127.81) >= 64)
                        continue;
                    double cu, cv, mu = 0, mv = 0, u, v;
                    rpiv_deform_pred_eval(pe, x + sh, y + sh, &cu, &cv);
                    for (int yy = 0; yy < ww; yy++)
                        for (int xx = 0; xx < ww; xx++) {
                            rpiv_deform_pred_eval(pe, x - 15.5 + xx + sh, y - 15.5 + yy + sh, &u,
                                                  &v);
                            mu += u;
                            mv += v;
                        }
                    mu /= ww * ww;
                    mv /= ww * ww;
                    double lin = cu - mu, act = fb->u[k] - fa->u[k];
                    A[0] += act * act;
                    A[1] += lin * lin;
                    A[2] += (act - lin) * (act - lin);
                    A[3] += cu * cu;
                    n4++;
                }
            if (q == nseed - 1)
                printf("core: RMS (pass1 with f0 - with truth) %.4f, linear G e0 %.4f, residual "
                       "%.4f, e0 at centre %.4f\n",
                       sqrt(A[0] / n4), sqrt(A[1] / n4), sqrt(A[2] / n4), sqrt(A[3] / n4));
            f = fb;
            rpiv_field_free(fa);
            rpiv_field_free(f0);
            rpiv_field_free(g);
            rpiv_deform_pred_free(pe);
        } else if (!strcmp(mode, "den")) { /* the final predictor's error: actual D q - t vs the
                                              chain's L(q - t) - (t - D t) */
            rpiv_field *f0 = NULL, *f1 = NULL, *q1 = NULL, *t1 = NULL, *dt = NULL, *lq = NULL;
            if (rpiv_piv_load(pv, &ia, &ib) || rpiv_piv_step(pv, 0, NULL, &f0) ||
                rpiv_piv_step(pv, 1, f0, &f1))
                return 3;
            if (rpiv_field_copy(f1, &q1) || rpiv_field_copy(f1, &t1) || rpiv_field_copy(f1, &lq))
                return 3;
            size_t nn = (size_t)f1->nx * f1->ny;
            for (int j = 0; j < f1->ny; j++)
                for (int i = 0; i < f1->nx; i++) {
                    double u, v;
                    vortex(NULL, f1->x0 + i * f1->dx, f1->y0 + j * f1->dy, &u, &v);
                    size_t k = (size_t)j * f1->nx + i;
                    t1->u[k] = (float)u;
                    t1->v[k] = (float)v;
                    lq->u[k] = f1->u[k] - (float)u;
                    lq->v[k] = f1->v[k] - (float)v;
                }
            if (rpiv_field_copy(t1, &dt) || piv_pred_denoise(pv, q1) || piv_pred_denoise(pv, dt))
                return 4;
            /* the chain's old model of the denoiser on the error, L e (every detail dropped: the
             * weights of piv_pred_denoise_weights all 0), and its model now, A e (the weights
             * the denoiser had on q); row k of a map M is M^T e_k */
            float *wq = NULL, *w0 = NULL;
            rpiv_field *gq = NULL;
            if (rpiv_field_copy(f1, &gq) || piv_pred_denoise_weights(pv, gq, &wq) ||
                !(w0 = calloc((size_t)PIV_DENOISE_STAGES * 2 * nn, sizeof *w0)))
                return 5;
            rpiv_field_free(gq);
            rpiv_field *ae = NULL;
            if (rpiv_field_copy(f1, &ae))
                return 5;
            double *row = malloc(2 * nn * sizeof *row);
            for (size_t k = 0; k < nn; k++)
                for (int w = 0; w < 2; w++) {
                    memset(row, 0, nn * sizeof *row);
                    row[k] = 1;
                    if (piv_pred_denoise_map_t(w ? wq : w0, pv->p.refine_denoise_order, f1->nx,
                                               f1->ny, 0, row, 0, f1->nx, 0, f1->ny, row + nn))
                        return 5;
                    double a = 0;
                    for (size_t m = 0; m < nn; m++)
                        a += row[m] * ((double)f1->u[m] - (double)t1->u[m]);
                    (w ? ae : lq)->u[k] = (float)a;
                }
            free(row);
            free(wq);
            free(w0);
            /* J e_q by a finite difference at q: (D q - D(q - eps e_q)) / eps */
            rpiv_field *qe = NULL, *q2 = NULL;
            if (rpiv_field_copy(f1, &qe) || rpiv_field_copy(f1, &q2))
                return 5;
            const float eps = 0.02f;
            for (size_t k = 0; k < nn; k++) {
                qe->u[k] = f1->u[k] - eps * (f1->u[k] - t1->u[k]);
                qe->v[k] = f1->v[k] - eps * (f1->v[k] - t1->v[k]);
            }
            if (piv_pred_denoise(pv, qe) || piv_pred_denoise(pv, q2))
                return 5;
            /* the nodes at den_r0 <= r < den_r1 px (env DEN_R0, DEN_R1; the core by default) */
            const double den_r0 = getenv("DEN_R0") ? atof(getenv("DEN_R0")) : 0,
                         den_r1 = getenv("DEN_R1") ? atof(getenv("DEN_R1")) : 64;
            static double S2[3], S3[2], S[5], nS;
            for (int j = 0; j < f1->ny; j++)
                for (int i = 0; i < f1->nx; i++) {
                    size_t k = (size_t)j * f1->nx + i;
                    double x = f1->x0 + i * f1->dx, y = f1->y0 + j * f1->dy;
                    const double rr = hypot(x - 128.37, y - 127.81);
                    if (rr < den_r0 || rr >= den_r1)
                        continue;
                    const double dd = q1->u[k] - dt->u[k];
                    S3[0] += (double)ae->u[k] * ae->u[k];
                    S3[1] += (ae->u[k] - dd) * (ae->u[k] - dd);
                    double je = (q2->u[k] - qe->u[k]) / eps;
                    S2[0] += je * je;
                    S2[1] += dd * dd;
                    S2[2] += (je - dd) * (je - dd);
                    double A = q1->u[k] - t1->u[k], B = lq->u[k] - (t1->u[k] - dt->u[k]),
                           E = f1->u[k] - t1->u[k];
                    S[0] += A * A;
                    S[1] += B * B;
                    S[2] += (A - B) * (A - B);
                    S[3] += E * E;
                    nS++;
                }
            rpiv_field_free(ae);
            rpiv_field_free(qe);
            rpiv_field_free(q2);
            (void)nn;
            if (q == nseed - 1)
                printf("nodes at r %g-%g px, u: pass-1 error %.4f; denoised predictor error: "
                       "actual %.4f, "
                       "chain's linear model %.4f, difference %.4f\n",
                       den_r0, den_r1, sqrt(S[3] / nS), sqrt(S[0] / nS), sqrt(S[1] / nS),
                       sqrt(S[2] / nS));
            if (q == nseed - 1)
                printf("  D q - D t %.4f, J_q e_q %.4f, difference %.4f; A e_q (the weights at q) "
                       "%.4f, difference from D q - D t %.4f\n",
                       sqrt(S2[1] / nS), sqrt(S2[0] / nS), sqrt(S2[2] / nS), sqrt(S3[0] / nS),
                       sqrt(S3[1] / nS));
            f = f1;
            rpiv_field_free(f0);
            rpiv_field_free(q1);
            rpiv_field_free(t1);
            rpiv_field_free(dt);
            rpiv_field_free(lq);
        } else if (!strcmp(mode, "rho")) { /* the final pass's residual against its predictor */
            rpiv_field *f0 = NULL, *f1 = NULL;
            if (rpiv_piv_load(pv, &ia, &ib) || rpiv_piv_step(pv, 0, NULL, &f0) ||
                rpiv_piv_step(pv, 1, f0, &f1) || rpiv_piv_step(pv, 2, f1, &f))
                return 3;
            rpiv_deform_pred *p = NULL;
            if (piv_pred_new(pv, f1, 2, 0, NULL, 0, &p))
                return 4;
            static double SA = 0, SH = 0;
            if (SA == 0) { /* white unit noise on the final grid: variance of H e and of (H - A) e
                              at the centre window */
                uint64_t st = 99;
                rpiv_field *w = NULL;
                rpiv_field_copy(f1, &w);
                int ic = f1->nx / 2, jc = f1->ny / 2;
                double xc = f1->x0 + ic * f1->dx, yc = f1->y0 + jc * f1->dy;
                for (int r = 0; r < 400; r++) {
                    for (size_t k = 0; k < (size_t)w->nx * w->ny; k++) {
                        w->u[k] = (float)ti_gauss(&st);
                        w->v[k] = 0;
                    }
                    rpiv_deform_pred *pw = NULL;
                    rpiv_deform_pred_new(w, size, size, 0.25, &pw);
                    double h, m = 0, u, v;
                    rpiv_deform_pred_eval(pw, xc, yc, &h, &v);
                    for (int yy = 0; yy < 32; yy++)
                        for (int xx = 0; xx < 32; xx++) {
                            rpiv_deform_pred_eval(pw, xc - 15.5 + xx, yc - 15.5 + yy, &u, &v);
                            m += u;
                        }
                    m /= 1024;
                    SA += m * m;
                    SH += (h - m) * (h - m);
                    rpiv_deform_pred_free(pw);
                }
                SA /= 400;
                SH /= 400;
                rpiv_field_free(w);
                printf("white predictor error: var of window mean %.3f, of centre minus window "
                       "mean %.3f\n",
                       SA, SH);
            }
            const rpiv_quantity *qs = rpiv_field_quantity(f, "sigma_u");
            size_t nn = (size_t)f->nx * f->ny;
            double *rho = calloc(nn, sizeof *rho);
            for (int j = 0; j < f->ny; j++)
                for (int i = 0; i < f->nx; i++) {
                    size_t k = (size_t)j * f->nx + i;
                    double u, v;
                    rpiv_deform_pred_eval(p, f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
                    rho[k] = f->u[k] - u;
                }
            static double B[4][4];
            static int NBn[4];
            for (int j = 1; j < f->ny - 1; j++)
                for (int i = 1; i < f->nx - 1; i++) {
                    size_t k = (size_t)j * f->nx + i;
                    double m = 0;
                    int c = 0;
                    for (int b = -1; b <= 1; b++)
                        for (int a = -1; a <= 1; a++) {
                            size_t kk = k + b * f->nx + a;
                            m += rho[kk] * rho[kk];
                            c++;
                        }
                    m /= c;
                    double x = f->x0 + i * f->dx, y = f->y0 + j * f->dy, tu, tv;
                    vortex(NULL, x, y, &tu, &tv);
                    double e = f->u[k] - tu, sg = qs->data[k];
                    double sp2 =
                        m / SA *
                        SH; /* predicted predictor-part variance (white), noise not removed */
                    int bin = (int)(hypot(x - 128.37, y - 127.81) / 32);
                    if (bin > 3)
                        bin = 3;
                    B[bin][0] += e * e;
                    B[bin][1] += sg * sg;
                    B[bin][2] += sp2;
                    B[bin][3] += rho[k] * rho[k];
                    NBn[bin]++;
                }
            if (q == nseed - 1)
                for (int b = 0; b < 4; b++)
                    printf("  r %3d+: RMS error %.4f, RMS sigma %.4f, white-model predictor part "
                           "%.4f, RMS rho %.4f\n",
                           32 * b, sqrt(B[b][0] / NBn[b]), sqrt(B[b][1] / NBn[b]),
                           sqrt(B[b][2] / NBn[b]), sqrt(B[b][3] / NBn[b]));
            free(rho);
            rpiv_deform_pred_free(p);
            rpiv_field_free(f0);
            rpiv_field_free(f1);
        } else if (!strcmp(mode, "exact1")) { /* truth at pass 0's grid, then passes 1.. */
            rpiv_field *g = NULL, *f1 = NULL;
            if (rpiv_piv_load(pv, &ia, &ib) || rpiv_piv_grid(pv, 0, &g))
                return 3;
            for (int j = 0; j < g->ny; j++)
                for (int i = 0; i < g->nx; i++) {
                    double u, v;
                    vortex(NULL, g->x0 + i * g->dx, g->y0 + j * g->dy, &u, &v);
                    g->u[(size_t)j * g->nx + i] = (float)u;
                    g->v[(size_t)j * g->nx + i] = (float)v;
                }
            if (rpiv_piv_step(pv, 1, g, &f1))
                return 4;
            if (prm.npass > 2) {
                if (rpiv_piv_step(pv, 2, f1, &f))
                    return 4;
                rpiv_field_free(f1);
            } else
                f = f1;
            rpiv_field_free(g);
        } else { /* exact: final pass with the truth on pass npass-2's grid as predictor */
            rpiv_field *g = NULL;
            if (rpiv_piv_load(pv, &ia, &ib) || rpiv_piv_grid(pv, prm.npass - 2, &g))
                return 3;
            for (int j = 0; j < g->ny; j++)
                for (int i = 0; i < g->nx; i++) {
                    double u, v;
                    vortex(NULL, g->x0 + i * g->dx, g->y0 + j * g->dy, &u, &v);
                    g->u[(size_t)j * g->nx + i] = (float)u;
                    g->v[(size_t)j * g->nx + i] = (float)v;
                }
            if (rpiv_piv_step(pv, prm.npass - 1, g, &f))
                return 4;
            rpiv_field_free(g);
        }
        acc(f);
        rpiv_field_free(f);
    }
    char t[200];
    snprintf(t, sizeof t, "mode %s noise %.2f tau %.1f seeds %d npass %d denoise %d", mode, noise,
             tau, nseed, prm.npass, prm.refine_denoise);
    report(t);
    rpiv_piv_free(pv);
    return 0;
}
