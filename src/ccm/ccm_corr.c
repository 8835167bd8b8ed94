/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The correlation as a sum of Gaussians (rpiv_ccm_corr) and its peak: the integer-sampled
 * maximum, the PIV sub-pixel estimator on it, and the continuous maximum (Brent on a line,
 * Nelder-Mead on the plane, a Newton polish). */
#include "ccm_impl.h"
#include "rpiv/peak.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_math.h>
#include <gsl/gsl_min.h>
#include <gsl/gsl_multimin.h>

/* ---- the sum of Gaussians ------------------------------------------------------------- */

rpiv_status rpiv_ccm_corr_new(size_t cap, rpiv_ccm_corr **out)
{
    *out = NULL;
    rpiv_ccm_corr *c = calloc(1, sizeof *c);
    if (!c)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    if (cap) {
        c->g = malloc(cap * sizeof *c->g);
        if (!c->g) {
            free(c);
            return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu terms", cap);
        }
        c->cap = cap;
    }
    *out = c;
    return RPIV_OK;
}

void rpiv_ccm_corr_free(rpiv_ccm_corr *c)
{
    if (!c)
        return;
    free(c->g);
    free(c);
}

rpiv_status rpiv_ccm_corr_add(rpiv_ccm_corr *c, rpiv_ccm_gauss g)
{
    if (c->n == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 64;
        rpiv_ccm_gauss *ng = realloc(c->g, cap * sizeof *ng);
        if (!ng)
            return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu terms", cap);
        c->g = ng;
        c->cap = cap;
    }
    c->g[c->n++] = g;
    return RPIV_OK;
}

/* Along one axis, the Gaussian exp(-c e^2) convolved with the triangle (b - |t|)/b^2 of unit
 * area: its value, first and second derivatives at offset e. The triangle is the second
 * difference of the ramp max(t, 0) with step b, over b^2, and the ramp convolved with the
 * normal density of variance s^2 = 1/(2c) is Q(x) = x Phi(x/s) + s phi(x/s), so
 *   f(e) = sqrt(pi/c)/b^2 [Q(e+b) - 2Q(e) + Q(e-b)],
 *   f'(e) = sqrt(pi/c)/b^2 [Phi((e+b)/s) - 2Phi(e/s) + Phi((e-b)/s)],
 *   f''(e) = [E(e+b) - 2E(e) + E(e-b)]/b^2, E(x) = exp(-c x^2).
 * f is even: it is evaluated at -|e| (arguments <= b, no cancellation against a growing
 * ramp); 0 where even its nearest point is more than 10 s away (exp(-50)). Where c b^2 < 1e-6
 * the second differences lose digits and the triangle is replaced
 * by the Gaussian of its variance b^2/6 (error O((c b^2)^2) < 1e-12 relative). b = 0: the
 * Gaussian. */
/* ccm_axis and the third derivative f3 = [E'(e+b) - 2E'(e) + E'(e-b)]/b^2, E' = -2cxE (odd,
 * like f': evaluated at -|e|, its sign flipped for e > 0). */
static void axis_d3(double e, double c, double b, double *f, double *fd, double *fdd, double *f3)
{
    if (!(b > 0) || c * b * b < 1e-6) {
        double cc = b > 0 ? c / (1 + c * b * b / 3) : c, a = b > 0 ? sqrt(cc / c) : 1;
        double E = a * exp(-cc * e * e);
        *f = E;
        *fd = -2 * cc * e * E;
        *fdd = (4 * cc * cc * e * e - 2 * cc) * E;
        *f3 = (12 * cc * cc * e - 8 * cc * cc * cc * e * e * e) * E;
        return;
    }
    double x = -fabs(e);
    if (c * (x + b) * (x + b) > 50 && x + b < 0) { /* all three points beyond 10 s: < 2e-22 */
        *f = *fd = *fdd = *f3 = 0;
        return;
    }
    double s = 1 / sqrt(2 * c), k = sqrt(M_PI / c) / (b * b);
    double xs[3] = {x + b, x, x - b}, w[3] = {1, -2, 1}, q = 0, p = 0, h = 0, h3 = 0;
    for (int i = 0; i < 3; i++) {
        double E = exp(-c * xs[i] * xs[i]), P = 0.5 * erfc(-xs[i] / (M_SQRT2 * s));
        q += w[i] * (xs[i] * P + s * E / sqrt(2 * M_PI));
        p += w[i] * P;
        h += w[i] * E;
        h3 += w[i] * xs[i] * E;
    }
    *f = k * q;
    *fd = e > 0 ? -k * p : k * p;
    *fdd = h / (b * b);
    *f3 = (e > 0 ? 2 * c : -2 * c) * h3 / (b * b);
}

void ccm_axis(double e, double c, double b, double *f, double *fd, double *fdd)
{
    double f3;
    axis_d3(e, c, b, f, fd, fdd, &f3);
}

double ccm_term_eval(const rpiv_ccm_gauss *g, double ex, double ey)
{
    if (!(g->box > 0))
        return g->amp * exp(-g->c * (ex * ex + ey * ey));
    double fx, fy, d1, d2;
    ccm_axis(ex, g->c, g->box, &fx, &d1, &d2);
    ccm_axis(ey, g->c, g->box, &fy, &d1, &d2);
    return g->amp * fx * fy;
}

double rpiv_ccm_corr_eval(const rpiv_ccm_corr *c, double dx, double dy)
{
    double s = 0;
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *g = &c->g[k];
        s += ccm_term_eval(g, dx - g->dx, dy - g->dy);
    }
    return s;
}

/* R and its first and second derivatives at (x, y). */
static void corr_d2(const rpiv_ccm_corr *c, double x, double y, double *r, double g[2], double h[3])
{
    double s = 0, gx = 0, gy = 0, hxx = 0, hyy = 0, hxy = 0;
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *t = &c->g[k];
        double ex = x - t->dx, ey = y - t->dy, cc = t->c;
        if (t->box > 0) {
            double fx, fxd, fxdd, fy, fyd, fydd;
            ccm_axis(ex, cc, t->box, &fx, &fxd, &fxdd);
            ccm_axis(ey, cc, t->box, &fy, &fyd, &fydd);
            s += t->amp * fx * fy;
            gx += t->amp * fxd * fy;
            gy += t->amp * fx * fyd;
            hxx += t->amp * fxdd * fy;
            hyy += t->amp * fx * fydd;
            hxy += t->amp * fxd * fyd;
            continue;
        }
        double e = t->amp * exp(-cc * (ex * ex + ey * ey));
        s += e;
        gx -= 2 * cc * ex * e;
        gy -= 2 * cc * ey * e;
        hxx += (4 * cc * cc * ex * ex - 2 * cc) * e;
        hyy += (4 * cc * cc * ey * ey - 2 * cc) * e;
        hxy += 4 * cc * cc * ex * ey * e;
    }
    *r = s;
    g[0] = gx;
    g[1] = gy;
    h[0] = hxx;
    h[1] = hxy;
    h[2] = hyy;
}

typedef struct span {
    int mode;           /* 0 general, 1 all DY equal, 2 all DX equal, 3 all equal */
    double dx0, dy0;    /* the common DX / DY */
    int x0, x1, y0, y1; /* integer box */
} span;

static rpiv_status corr_span(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, span *s)
{
    double xmin = HUGE_VAL, xmax = -HUGE_VAL, ymin = HUGE_VAL, ymax = -HUGE_VAL;
    size_t nact = 0;
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *g = &c->g[k];
        if (!(g->amp > 0))
            continue;
        if (!isfinite(g->amp) || !isfinite(g->dx) || !isfinite(g->dy) || !(g->c > 0) ||
            !isfinite(g->c) || !(g->box >= 0 && g->box <= 64))
            return rpiv_fail(RPIV_ENUMERIC, "ccm: correlation term %zu is not finite", k);
        nact++;
        xmin = fmin(xmin, g->dx);
        xmax = fmax(xmax, g->dx);
        ymin = fmin(ymin, g->dy);
        ymax = fmax(ymax, g->dy);
    }
    if (!nact)
        return rpiv_fail(RPIV_ENUMERIC,
                         "ccm: the correlation is zero everywhere (no illuminated particle)");
    if (xmax - xmin > p->max_range_px || ymax - ymin > p->max_range_px)
        return rpiv_fail(RPIV_ELIMIT,
                         "ccm: displacements span %.4g x %.4g px, more than max_range_px = %d",
                         xmax - xmin, ymax - ymin, p->max_range_px);
    s->mode = (ymin == ymax ? 1 : 0) | (xmin == xmax ? 2 : 0);
    s->dx0 = xmin;
    s->dy0 = ymin;
    s->x0 = (int)floor(xmin) - 1;
    s->x1 = (int)ceil(xmax) + 1;
    s->y0 = (int)floor(ymin) - 1;
    s->y1 = (int)ceil(ymax) + 1;
    return RPIV_OK;
}

/* A line of the plane: along x at y = at (axis 0) or along y at x = at (axis 1). wq[k] is
 * term k's amplitude times its factor across the line (the box makes each term a product of
 * one factor per axis), computed once; NULL: evaluate the whole terms. */
typedef struct pkline {
    const rpiv_ccm_corr *c;
    int axis;
    double at;
    const double *wq;
} pkline;

/* The factors across the line of every term into wq (c->n values). */
static void line_factors(const rpiv_ccm_corr *c, int axis, double at, double *wq)
{
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *g = &c->g[k];
        double e = at - (axis ? g->dx : g->dy), f, d1, d2;
        if (g->box > 0)
            ccm_axis(e, g->c, g->box, &f, &d1, &d2);
        else
            f = exp(-g->c * e * e);
        wq[k] = g->amp * f;
    }
}

/* R along the line at t and its first three derivatives along it (d3: NULL, not wanted).
 * Terms of factor 0 across the line are skipped. */
static void line_d3(const pkline *l, double t, double *r, double *d1, double *d2, double *d3)
{
    const rpiv_ccm_corr *c = l->c;
    double s = 0, a = 0, b = 0, b3 = 0;
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *g = &c->g[k];
        double e = t - (l->axis ? g->dy : g->dx), f, fd, fdd, f3, cc = g->c;
        if (l->wq[k] == 0)
            continue;
        if (g->box > 0) {
            axis_d3(e, cc, g->box, &f, &fd, &fdd, &f3);
        } else {
            f = exp(-cc * e * e);
            fd = -2 * cc * e * f;
            fdd = (4 * cc * cc * e * e - 2 * cc) * f;
            f3 = (12 * cc * cc * e - 8 * cc * cc * cc * e * e * e) * f;
        }
        s += l->wq[k] * f;
        a += l->wq[k] * fd;
        b += l->wq[k] * fdd;
        b3 += l->wq[k] * f3;
    }
    *r = s;
    *d1 = a;
    *d2 = b;
    if (d3)
        *d3 = b3;
}

static void line_d2(const pkline *l, double t, double *r, double *d1, double *d2)
{
    line_d3(l, t, r, d1, d2, NULL);
}

/* Q(-a) for a >= 0, Q the ramp convolved with the normal density of standard deviation s
 * (ccm_axis): -a Phi(-a/s) + s phi(a/s), >= 0 and small. */
static double qneg(double a, double c, double s)
{
    return -a * 0.5 * erfc(a * sqrt(c)) + s * exp(-c * a * a) / sqrt(2 * M_PI);
}

/* One term's factor along an axis at the integer points x0 .. x0 + n - 1 (d: the term's
 * displacement along the axis, the factor at x is f(x - d)) into f; [*lo, *hi]: the indices
 * inside its support, beyond which every factor is below exp(-50) of the term's peak (all
 * three points of the box's second difference beyond 10 standard deviations, ccm_axis) and
 * f is left unset; *lo > *hi when none is. A box of 1 px is sqrt(pi/c) [(1 - |e|)+ + q(|e+1|) -
 * 2 q(|e|) + q(|e-1|)] with q(a) = Q(-a) (Q(u) is u+ + Q(-|u|)): unit-spaced points share
 * their q values, one erfc and one exp per point plus two, where ccm_axis takes three of
 * each. */
static void axis_lattice(const rpiv_ccm_gauss *g, double d, int x0, int n, double *f, int *lo,
                         int *hi)
{
    double b = g->box > 0 ? g->box : 0, far = b + 10 / sqrt(2 * g->c);
    double a = fmax(0, ceil(d - far - x0)), z = fmin(n - 1, floor(d + far - x0));
    *lo = 0;
    *hi = -1;
    if (!(a <= z))
        return;
    *lo = (int)a;
    *hi = (int)z;
    if (g->box != 1 || g->c < 1e-6) { /* (a broad term: the q differences cancel) */
        for (int i = *lo; i <= *hi; i++) {
            double fd, fdd, e = x0 + i - d;
            if (g->box > 0)
                ccm_axis(e, g->c, g->box, &f[i], &fd, &fdd);
            else
                f[i] = exp(-g->c * e * e);
        }
        return;
    }
    double s = 1 / sqrt(2 * g->c), kk = sqrt(M_PI / g->c), e = x0 + *lo - d, c = g->c;
    double q0 = qneg(fabs(e - 1), c, s), q1 = qneg(fabs(e), c, s), is = s / sqrt(2 * M_PI);
    /* E(u) = exp(-c u^2) at u = e + 1 by E(u + 1) = E(u) rho(u), rho(u + 1) = rho(u) exp(-2c),
     * both recomputed every 16 points (relative error below 16^2 2^-53 = 3e-14), where rho
     * stays below exp(600) */
    int rec = 20 * s * c + c < 600;
    double u = e + 1, E = exp(-c * u * u), rho = exp(-c * (2 * u + 1)), g2 = exp(-2 * c);
    for (int i = *lo; i <= *hi; i++, e += 1, u += 1) {
        if (((i - *lo) & 15) == 15) {
            E = exp(-c * u * u);
            rho = exp(-c * (2 * u + 1));
        }
        double au = fabs(u), ea = rec ? E : exp(-c * au * au);
        double q2 = -au * 0.5 * erfc(au * sqrt(c)) + is * ea;
        f[i] = kk * (fmax(0, 1 - fabs(e)) + q2 - 2 * q1 + q0);
        q0 = q1;
        q1 = q2;
        E *= rho;
        rho *= g2;
    }
}

/* R at the integer points (xa + i, ya + j), i < nx, j < ny, into r[j nx + i]: each term is a
 * product of an x factor and a y factor, so a term costs nx + ny factors (axis_lattice) and
 * an outer product over its support, not nx ny whole evaluations. fx, fy: scratch of nx and
 * ny values. wq (or NULL): every term's amplitude times its factor on the row ya + wrow (the
 * line_factors of that row). Terms of amplitude <= 0 add nothing. */
static void lattice(const rpiv_ccm_corr *c, int xa, int nx, int ya, int ny, double *r, double *fx,
                    double *fy, double *wq, int wrow)
{
    for (size_t i = 0; i < (size_t)nx * (size_t)ny; i++)
        r[i] = 0;
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *g = &c->g[k];
        int ia, ib, ja = 0, jb = -1;
        if (wq)
            wq[k] = 0;
        if (!(g->amp > 0))
            continue;
        axis_lattice(g, g->dx, xa, nx, fx, &ia, &ib);
        if (ia <= ib || wq)
            axis_lattice(g, g->dy, ya, ny, fy, &ja, &jb);
        if (wq && wrow >= ja && wrow <= jb)
            wq[k] = g->amp * fy[wrow];
        for (int j = ja; j <= jb && ia <= ib; j++) {
            double w = g->amp * fy[j], *row = r + (size_t)j * (size_t)nx;
            for (int i = ia; i <= ib; i++)
                row[i] += w * fx[i];
        }
    }
}

void ccm_lattice(const rpiv_ccm_corr *c, int xa, int nx, int ya, int ny, double *r, double *fx,
                 double *fy)
{
    lattice(c, xa, nx, ya, ny, r, fx, fy, NULL, 0);
}

/* Lattices up to this many points are sampled in one pass; larger boxes (a general sum with
 * DX and DY spread over many pixels) row by row. */
#define LATTICE_MAX (1 << 18)

/* The integer-sampled maximum (mx, my): over the span's box, y outer and x inner, the first
 * of equal values; along the row nearest DY when all DY are equal (every term decreases with
 * |y - DY|), along the column nearest DX when all DX are equal. With rows (rad > 0): R at
 * (mx + i, my + j), |i|, |j| <= rad into rows[j + rad][i + rad]. With wq: when all DY equal
 * the integer my, DX not all equal and rad >= 1, every term's amplitude times its factor on that
 * row, followed by R on the row at x0 - 1 .. x1 + 1, and *wq_set = 1 (wq holds n + x1 - x0 + 3
 * values). */
static rpiv_status sample_plane(const rpiv_ccm_corr *c, const span *s, int rad, double rows[7][7],
                                double *wq, int *wq_set, int *mx, int *my)
{
    int ax0 = s->x0, ax1 = s->x1, ay0 = s->y0, ay1 = s->y1;
    if (s->mode & 2)
        ax0 = ax1 = (int)lround(s->dx0);
    if (s->mode & 1)
        ay0 = ay1 = (int)lround(s->dy0);
    /* every term is even about its DY: with all DY equal to the row ay0, rows ay0 -+ j agree */
    int mirror = (s->mode & 1) && s->dy0 == ay0;
    int xa = ax0 - rad, nx = ax1 - ax0 + 1 + 2 * rad, ya = mirror ? ay0 : ay0 - rad;
    int ny = mirror ? rad + 1 : ay1 - ay0 + 1 + 2 * rad;
    int one = (double)nx * ny <= LATTICE_MAX;
    if (!one) { /* row by row, then the plane around the maximum */
        xa = ax0;
        nx = ax1 - ax0 + 1;
        ny = 1;
    }
    size_t nbuf = (size_t)nx * (size_t)ny + (size_t)nx + (size_t)ny + 4 * (size_t)rad + 2;
    double *buf = malloc(nbuf * sizeof *buf);
    if (!buf)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %d x %d correlation samples", nx, ny);
    double *r = buf, *fx = r + (size_t)nx * (size_t)ny, *fy = fx + nx, best = -1;
    *wq_set = 0;
    if (one) {
        lattice(c, xa, nx, ya, ny, r, fx, fy, mirror ? wq : NULL, 0);
        *wq_set = mirror && wq && rad >= 1 && !(s->mode & 2);
        for (int x = s->x0 - 1; *wq_set && x <= s->x1 + 1; x++) /* the line's samples */
            wq[c->n + (size_t)(x - s->x0 + 1)] = r[x - xa];
    }
    *mx = ax0;
    *my = ay0;
    for (int y = ay0; y <= ay1; y++) {
        const double *row = r + (one ? (size_t)(y - ya) * (size_t)nx : 0);
        if (!one)
            lattice(c, xa, nx, y, 1, r, fx, fy, NULL, 0);
        for (int x = ax0; x <= ax1; x++)
            if (row[x - xa] > best) {
                best = row[x - xa];
                *mx = x;
                *my = y;
            }
    }
    if (rad > 0 && !one) { /* the plane around the maximum, on its own lattice */
        xa = *mx - rad;
        ya = *my - rad;
        nx = ny = 2 * rad + 1;
        double *pf = malloc(((size_t)nx * (size_t)ny + 2 * (size_t)nx) * sizeof *pf);
        if (!pf) {
            free(buf);
            return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for the sampled plane");
        }
        free(buf);
        buf = r = pf;
        lattice(c, xa, nx, ya, ny, r, r + nx * ny, r + nx * ny + nx, NULL, 0);
    }
    for (int j = -rad; j <= rad && rad > 0; j++) {
        int yj = mirror ? abs(j) : *my + j - ya;
        for (int i = -rad; i <= rad; i++)
            rows[j + rad][i + rad] = r[(size_t)yj * (size_t)nx + (size_t)(*mx + i - xa)];
    }
    free(buf);
    return RPIV_OK;
}

rpiv_status ccm_sampled_max(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, int *mx, int *my)
{
    span s;
    rpiv_status st = corr_span(c, p, &s);
    int wq_set = 0;
    if (!st)
        st = sample_plane(c, &s, 0, NULL, NULL, &wq_set, mx, my);
    return st;
}

static double line_r(const pkline *l, double t)
{
    if (l->wq) {
        double r, d1, d2;
        line_d2(l, t, &r, &d1, &d2);
        return r;
    }
    return l->axis ? rpiv_ccm_corr_eval(l->c, l->at, t) : rpiv_ccm_corr_eval(l->c, t, l->at);
}

static double line_neg(double t, void *u)
{
    return -line_r(u, t);
}

/* The maximum of R on the line in (lo, hi), which holds one (R(t) above R(lo) and R(hi)),
 * from t: Halley's method on R' with the analytic R'' and R''' (cubic convergence; Newton's
 * step where Halley's denominator 2 R''^2 - R' R''' is not positive), kept inside a bracket
 * that every evaluation narrows (a bisection step where the step would leave it or
 * R'' >= 0). It stops where a step h (R'' < 0) is below 1e-12 px, or where the convergence
 * puts the point after it within 1e-13 px: the error after h following a step h' is about
 * h^4 / h'^3 after two Halley steps (e_{k+1} = K e_k^3, K from the two steps; |h| <= 1e-4),
 * |h|^3 / h'^2 after Newton steps (|h| <= 1e-6). *rmax: R there, from the last evaluation's
 * Taylor series (to h^3). 0 (a bracket that collapses without a maximum, no convergence):
 * Brent's method instead. */
static int newton_line(const pkline *l, double lo, double hi, double t, double *tmax, double *rmax)
{
    double r, d1, d2, d3, prev = 0;
    int halley_prev = 0;
    if (!(t > lo && t < hi))
        t = 0.5 * (lo + hi);
    for (int it = 0; it < 60; it++) {
        line_d3(l, t, &r, &d1, &d2, &d3);
        double h = 0;
        int halley = 0;
        if (d2 < 0) {
            double den = 2 * d2 * d2 - d1 * d3;
            halley = den > 0;
            h = halley ? -2 * d1 * d2 / den : -d1 / d2;
            double ah = fabs(h), tol = 1e-12 * (1 + fabs(t));
            int conv = ah <= tol;
            if (halley && halley_prev)
                conv |= ah <= 1e-4 && ah * ah * ah * ah <= 1e-13 * fabs(prev * prev * prev);
            else
                conv |= ah <= 1e-6 && ah * ah * ah <= 1e-13 * prev * prev;
            if (conv) {
                *tmax = t + h;
                *rmax = r + h * (d1 + h * (0.5 * d2 + h * d3 / 6));
                return 1;
            }
        }
        if (d1 > 0)
            lo = t;
        else
            hi = t;
        double tn = d2 < 0 ? t + h : 0.5 * (lo + hi);
        prev = d2 < 0 ? h : 0;
        halley_prev = halley;
        if (!(tn > lo && tn < hi)) {
            tn = 0.5 * (lo + hi);
            prev = 0;
            halley_prev = 0;
        }
        if (hi - lo <= 1e-12 * (1 + fabs(t)))
            return 0;
        t = tn;
    }
    return 0;
}

/* Brent's method on -R along the line, bracketed by the integer samples around m, to
 * BRENT_TOL, then a Newton polish on the analytic derivatives to the rounding (Brent alone
 * stops near sqrt(eps) |t|, since R is flat at its maximum; from 1e-4 px Newton's quadratic
 * convergence needs two or three steps where Brent needs many more evaluations). */
#define BRENT_TOL 1e-4
/* R on the line at the integer t: from lv (the lattice's samples at lo - 1 .. hi + 1; NULL:
 * none) or evaluated. */
static double line_int(const pkline *l, const double *lv, int lo, int hi, int t)
{
    return lv && t >= lo - 1 && t <= hi + 1 ? lv[t - lo + 1] : line_r(l, t);
}

static rpiv_status line_max(const pkline *l, const double *lv, int m, int lo, int hi, double guess,
                            const rpiv_ccm_params *p, double *tmax, double *rmax)
{
    *rmax = (double)NAN;
    double fm = line_int(l, lv, lo, hi, m), fa = line_int(l, lv, lo, hi, m - 1);
    double fb = line_int(l, lv, lo, hi, m + 1);
    /* walk to a local maximum of the samples on this line */
    for (int step = 0; step < hi - lo + 2; step++) {
        if (fb > fm && m + 1 <= hi + 1) {
            m++;
            fa = fm;
            fm = fb;
            fb = line_int(l, lv, lo, hi, m + 1);
        } else if (fa > fm && m - 1 >= lo - 1) {
            m--;
            fb = fm;
            fm = fa;
            fa = line_int(l, lv, lo, hi, m - 1);
        } else {
            break;
        }
    }
    double t0 = m, f0 = fm;
    if (!(f0 > fa) || !(f0 > fb)) {
        double tm = fa == fm ? m - 0.5 : m + 0.5, fmid = line_r(l, tm);
        if (fmid > fa && fmid > fb) {
            t0 = tm;
            f0 = fmid;
        } else {
            return rpiv_fail(RPIV_ENUMERIC, "ccm: flat correlation around shift %d", m);
        }
    }
    /* Newton's start: the sub-pixel estimate where it lies within a pixel of m */
    double tn = guess > m - 1 && guess < m + 1 ? guess : t0;
    if (l->wq && newton_line(l, m - 1.0, m + 1.0, tn, tmax, rmax))
        return RPIV_OK;
    gsl_min_fminimizer *s = gsl_min_fminimizer_alloc(gsl_min_fminimizer_brent);
    if (!s)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    gsl_function F = {line_neg, (void *)l};
    int gs = gsl_min_fminimizer_set_with_values(s, &F, t0, -f0, m - 1.0, -fa, m + 1.0, -fb);
    int it = 0;
    while (gs == GSL_SUCCESS && it++ < p->max_iter) {
        gs = gsl_min_fminimizer_iterate(s);
        if (gs)
            break;
        double a = gsl_min_fminimizer_x_lower(s), b = gsl_min_fminimizer_x_upper(s);
        double x = gsl_min_fminimizer_x_minimum(s);
        if (b - a < fmax(p->xtol_px, BRENT_TOL) + 4 * GSL_SQRT_DBL_EPSILON * fabs(x)) {
            gs = GSL_SUCCESS;
            break;
        }
        gs = GSL_SUCCESS;
        if (it == p->max_iter)
            gs = GSL_EMAXITER;
    }
    double t = gsl_min_fminimizer_x_minimum(s);
    gsl_min_fminimizer_free(s);
    if (gs)
        return ccm_gsl_fail(gs, "Brent's peak search");
    for (int k = 0; k < 8; k++) {
        double r, d1, d2;
        if (l->wq) {
            line_d2(l, t, &r, &d1, &d2);
        } else {
            double g[2], h[3];
            if (l->axis)
                corr_d2(l->c, l->at, t, &r, g, h);
            else
                corr_d2(l->c, t, l->at, &r, g, h);
            d1 = l->axis ? g[1] : g[0];
            d2 = l->axis ? h[2] : h[0];
        }
        if (!(d2 < 0))
            break;
        double dt = -d1 / d2;
        if (!(fabs(dt) < 1e-3))
            break;
        t += dt;
        if (fabs(dt) < 4 * DBL_EPSILON * (1 + fabs(t)))
            break;
    }
    *tmax = t;
    return RPIV_OK;
}

static double simplex_neg(const gsl_vector *v, void *u)
{
    return -rpiv_ccm_corr_eval(u, gsl_vector_get(v, 0), gsl_vector_get(v, 1));
}

/* General 2-D case: Nelder-Mead on -R from the sub-pixel estimate, then Newton polish. */
static rpiv_status plane_max(const rpiv_ccm_corr *c, double x0, double y0, const rpiv_ccm_params *p,
                             double *xm, double *ym)
{
    rpiv_status st = RPIV_OK;
    gsl_multimin_fminimizer *s =
        gsl_multimin_fminimizer_alloc(gsl_multimin_fminimizer_nmsimplex2, 2);
    gsl_vector *x = gsl_vector_alloc(2), *step = gsl_vector_alloc(2);
    if (!s || !x || !step) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
        goto out_free;
    }
    gsl_vector_set(x, 0, x0);
    gsl_vector_set(x, 1, y0);
    gsl_vector_set_all(step, 0.25);
    gsl_multimin_function F = {simplex_neg, 2, (void *)c};
    int gs = gsl_multimin_fminimizer_set(s, &F, x, step);
    int it = 0;
    while (gs == GSL_SUCCESS) {
        gs = gsl_multimin_fminimizer_iterate(s);
        if (gs)
            break;
        if (gsl_multimin_test_size(gsl_multimin_fminimizer_size(s), p->xtol_px) == GSL_SUCCESS)
            break;
        if (++it >= p->max_iter)
            gs = GSL_EMAXITER;
    }
    if (gs) {
        st = ccm_gsl_fail(gs, "simplex peak search");
        goto out_free;
    }
    double px = gsl_vector_get(s->x, 0), py = gsl_vector_get(s->x, 1);
    for (int k = 0; k < 8; k++) {
        double r, g[2], h[3];
        corr_d2(c, px, py, &r, g, h);
        double det = h[0] * h[2] - h[1] * h[1];
        if (!(h[0] < 0 && det > 0))
            break;
        double sx = -(h[2] * g[0] - h[1] * g[1]) / det, sy = -(h[0] * g[1] - h[1] * g[0]) / det;
        if (!(fabs(sx) < 1e-3 && fabs(sy) < 1e-3))
            break;
        px += sx;
        py += sy;
        if (fabs(sx) + fabs(sy) < 4 * DBL_EPSILON * (1 + fabs(px) + fabs(py)))
            break;
    }
    *xm = px;
    *ym = py;
out_free:
    gsl_vector_free(step);
    gsl_vector_free(x);
    gsl_multimin_fminimizer_free(s);
    return st;
}

int ccm_subpixel_rad(const rpiv_ccm_params *p)
{
    return rpiv_subpixel_resolve(p->subpixel, 1) == RPIV_SUBPIXEL_SPLINE ? 3 : 1;
}

/* The sampled plane around the maximum (mx, my), plus base everywhere, handed to the PIV
 * engine's estimator for a sum of correlation (peak.h, rpiv_subpixel_resolve) as the 8 x 8
 * float plane in circular order that it reads after an FFT: shifts -4..3, the search over
 * -1..1, normalised by the centre; the samples the estimator reads (the 3-point fits: the row
 * and the column through the centre; the centroid: 3 x 3; the spline: 7 x 7). */
void ccm_subpixel(double rows[7][7], const rpiv_ccm_params *p, double base, int mx, int my,
                  double *dx_sub, double *dy_sub, uint64_t *sig)
{
    enum { PW = 8 };
    float plane[PW * PW] = {0};
    rpiv_subpixel method = rpiv_subpixel_resolve(p->subpixel, 1);
    int rad = ccm_subpixel_rad(p), bit = 0, spline = method == RPIV_SUBPIXEL_SPLINE;
    double r0 = rows[rad][rad] + base;
    uint64_t mask = 0, pos7 = 1, pos5 = 1, pos3 = 1;
    for (int j = -rad; j <= rad; j++)
        for (int i = -rad; i <= rad; i++) {
            if (i && j && method != RPIV_SUBPIXEL_CENTROID && !spline)
                continue;
            double v = i || j ? (rows[j + rad][i + rad] + base) / r0 : 1.0;
            plane[((j + PW) % PW) * PW + (i + PW) % PW] = (float)v;
            /* the estimator's path: which samples its logarithms accept (the spline's 7 x 7,
             * else its 5 x 5, else the 3-point fit's row and column) */
            uint64_t pos = (float)v > 0;
            mask |= spline ? 0 : pos << bit++;
            pos7 &= pos;
            pos5 &= pos || abs(i) > 2 || abs(j) > 2;
            pos3 &= pos || abs(i) + abs(j) > 1;
        }
    if (spline)
        mask = pos7 | pos5 << 1 | pos3 << 2;
    rpiv_peak fit;
    rpiv_peak_find(plane, PW, PW, 1, method, &fit);
    *dx_sub = mx + fit.dx;
    *dy_sub = my + fit.dy;
    if (sig) {
        /* the spline falls back to the 3-point Gaussian when its Newton search fails */
        rpiv_peak g = fit;
        if (method == RPIV_SUBPIXEL_SPLINE)
            rpiv_peak_find(plane, PW, PW, 1, RPIV_SUBPIXEL_GAUSS, &g);
        int fallback = method == RPIV_SUBPIXEL_SPLINE && g.dx == fit.dx && g.dy == fit.dy;
        *sig = mask | (uint64_t)fallback << 62 | (uint64_t)fit.fit_ok << 63;
    }
}

rpiv_status ccm_sampled_rows(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, double rows[7][7],
                             int *mx, int *my)
{
    span s;
    int wq_set = 0;
    rpiv_status st = corr_span(c, p, &s);
    if (!st)
        st = sample_plane(c, &s, ccm_subpixel_rad(p), rows, NULL, &wq_set, mx, my);
    return st;
}

rpiv_status rpiv_ccm_corr_peak(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, rpiv_ccm_peak *out)
{
    span s;
    rpiv_status st = corr_span(c, p, &s);
    if (st)
        return st;
    /* every term is a product of a factor along x and one along y: along a line the factors
     * across it are computed once (wq), and each evaluation costs one factor per term */
    size_t nw = c->n + (size_t)(s.x1 - s.x0) + 3;
    double *wq = malloc(nw * sizeof *wq);
    if (!wq)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu terms", c->n);
    int rad = ccm_subpixel_rad(p), mx = 0, my = 0, wq_set = 0;
    double rows[2 * 3 + 1][2 * 3 + 1] = {{0}};
    if ((st = sample_plane(c, &s, rad, rows, wq, &wq_set, &mx, &my))) {
        free(wq);
        return st;
    }
    out->mx = mx;
    out->my = my;
    ccm_subpixel(rows, p, 0, mx, my, &out->dx_sub, &out->dy_sub, NULL);
    /* the continuous maximum; its value along the line (one factor per term) */
    pkline l = {c, s.mode & 1 ? 0 : 1, s.mode & 1 ? s.dy0 : s.dx0, wq};
    double rmax = (double)NAN;
    if (s.mode == 3) {
        out->dx = s.dx0;
        out->dy = s.dy0;
        l.wq = NULL;
    } else if (s.mode & 1) {
        if (!wq_set) /* (else the lattice's row my = DY gave them) */
            line_factors(c, 0, s.dy0, wq);
        out->dy = s.dy0;
        st = line_max(&l, wq_set ? wq + c->n : NULL, mx, s.x0, s.x1, out->dx_sub, p, &out->dx,
                      &rmax);
    } else if (s.mode & 2) {
        line_factors(c, 1, s.dx0, wq);
        out->dx = s.dx0;
        st = line_max(&l, NULL, my, s.y0, s.y1, out->dy_sub, p, &out->dy, &rmax);
    } else {
        double x0 = isfinite(out->dx_sub) ? out->dx_sub : mx;
        double y0 = isfinite(out->dy_sub) ? out->dy_sub : my;
        st = plane_max(c, x0, y0, p, &out->dx, &out->dy);
        l.wq = NULL;
    }
    if (!st)
        out->value =
            l.wq ? line_r(&l, l.axis ? out->dy : out->dx) : rpiv_ccm_corr_eval(c, out->dx, out->dy);
    free(wq);
    return st;
}
