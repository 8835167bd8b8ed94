/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/report/plot_field.c - figures of vector fields: the plain quiver plot of the demo
 * (rpiv_plot_quiver) and the figure of `rpiv plot` and `rpiv piv --plot` (rpiv_plot_field):
 * a colour map of a quantity, arrows with a reference arrow, a key of the vector flags, the
 * camera image underneath on request. PLplot is global state: one plot at a time. */
#include "plot_impl.h"

#include <math.h>
#include <plplot/plplot.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* ---- quiver -------------------------------------------------------------------- */

typedef struct quiver_ctx {
    const rpiv_field *f;
    const char *title;
} quiver_ctx;

typedef struct grid_map {
    double x0, y0, dx, dy;
} grid_map;

/* PLplot's plvect draws its default arrow (from -0.5 to +0.5 of its unit shape) scaled by half
 * of scale * (u, v), centred on the grid point: an arrow is 0.5 * scale * |(u, v)| long. Twice
 * the wanted length per unit makes it span arrow_len * |(u, v)|, as the key's reference arrow. */
#define PLVECT_FACTOR 2.0

static void grid_xform(PLFLT i, PLFLT j, PLFLT *x, PLFLT *y, PLPointer data)
{
    const grid_map *g = data;
    *x = g->x0 + i * g->dx;
    *y = g->y0 + j * g->dy;
}

static rpiv_status draw_quiver(const void *vctx, const rpiv_plot_opts *o)
{
    const quiver_ctx *c = vctx;
    const rpiv_field *f = c->f;
    int nx = f->nx, ny = f->ny, s = o->stride;
    size_t n = (size_t)nx * (size_t)ny;
    double x0 = f->x0 - 0.5 * f->dx, x1 = f->x0 + (nx - 0.5) * f->dx;
    double y0 = f->y0 - 0.5 * f->dy, y1 = f->y0 + (ny - 0.5) * f->dy;
    double *mag = malloc(n * sizeof *mag);
    int mx = (nx + s - 1) / s, my = (ny + s - 1) / s;
    PLFLT *ub = calloc(4 * (size_t)mx * (size_t)my, sizeof *ub);
    const PLFLT **cols = malloc(4 * (size_t)mx * sizeof *cols);
    if (!mag || !ub || !cols) {
        free(mag);
        free(ub);
        free(cols);
        return rpiv_fail(RPIV_ENOMEM, "plot: out of memory for a %d x %d quiver", nx, ny);
    }
    double umax = 0;
    for (size_t k = 0; k < n; k++) {
        mag[k] =
            f->flag[k] == RPIV_FLAG_MASKED ? (double)NAN : hypot((double)f->u[k], (double)f->v[k]);
        if (isfinite(mag[k]))
            umax = fmax(umax, mag[k]);
    }
    if (o->xmin < o->xmax) {
        x0 = o->xmin;
        x1 = o->xmax;
    }
    if (o->ymin < o->ymax) {
        y0 = o->ymin;
        y1 = o->ymax;
    }
    plot_frame(o, x0, x1, y0, y1, o->background, o->xlabel, o->ylabel, c->title);
    rpiv_status st = RPIV_OK;
    if (o->background) {
        double zlo, zhi;
        plot_zrange(mag, n, o, &zlo, &zhi);
        st = plot_draw_cells(mag, nx, ny, f->x0 - 0.5 * f->dx, f->x0 + (nx - 0.5) * f->dx,
                             f->y0 - 0.5 * f->dy, f->y0 + (ny - 0.5) * f->dy, zlo, zhi, o->width_px,
                             o->height_px);
        plcol0(COL_FG);
        plbox("bc", 0, 0, "bc", 0, 0);
        plot_colour_bar(zlo, zhi, o->zlabel ? o->zlabel : "|u| (px)");
    }
    /* two layers: valid vectors (black) and replaced ones (red); zero arrows are not drawn */
    size_t m = (size_t)mx * (size_t)my;
    PLFLT *uv[4] = {ub, ub + m, ub + 2 * m, ub + 3 * m}; /* u valid, v valid, u repl, v repl */
    for (int l = 0; l < 4; l++)
        for (int i = 0; i < mx; i++)
            cols[(size_t)l * (size_t)mx + (size_t)i] = uv[l] + (size_t)i * (size_t)my;
    for (int i = 0; i < mx; i++)
        for (int j = 0; j < my; j++) {
            size_t k = (size_t)(j * s) * (size_t)nx + (size_t)(i * s),
                   q = (size_t)i * (size_t)my + (size_t)j;
            int layer = f->flag[k] == RPIV_FLAG_REPLACED ? 2 : 0;
            if (f->flag[k] == RPIV_FLAG_MASKED)
                continue;
            uv[layer][q] = (double)f->u[k];
            uv[layer + 1][q] = (double)f->v[k];
        }
    double scale = o->arrow_scale;
    if (scale <= 0)
        scale = umax > 0 ? 0.9 * s * fmin(f->dx, f->dy) / umax : 1.0;
    grid_map g = {f->x0, f->y0, f->dx * s, f->dy * s};
    if (st == RPIV_OK && umax > 0) {
        plcol0(COL_FG);
        plvect(cols, cols + mx, mx, my, PLVECT_FACTOR * scale, grid_xform, &g);
        plcol0(COL_REPLACED);
        plvect(cols + 2 * mx, cols + 3 * mx, mx, my, PLVECT_FACTOR * scale, grid_xform, &g);
    }
    free(mag);
    free(ub);
    free(cols);
    return st;
}

rpiv_status rpiv_plot_quiver(const rpiv_field *f, const char *path, const char *title,
                             const rpiv_plot_opts *opts)
{
    rpiv_plot_opts o = opts ? *opts : rpiv_plot_opts_default();
    rpiv_status st = plot_opts_check(&o, path);
    if (st)
        return st;
    plot_resolve_auto(&o, RPIV_PLOT_DOWN, RPIV_PLOT_EQUAL);
    quiver_ctx c = {f, title};
    return plot_run(path, &o, draw_quiver, &c);
}

/* ---- the field figure (rpiv plot) ------------------------------------------------- */

rpiv_plot_field_params rpiv_plot_field_params_default(void)
{
    return (rpiv_plot_field_params){
        .width_px = 1000, .height_px = 800, .quantity = "magnitude", .arrow_scale = 1};
}

/* The quantity coloured: none, the magnitude of (u, v), or an array of f with its unit. */
typedef struct qsel {
    int kind; /* 0 none, 1 magnitude, 2 data */
    const float *data;
    int unit; /* rpiv_unit, without RPIV_UNIT_ODD_Y */
} qsel;

static int pick_quantity(const rpiv_field *f, const char *name, qsel *q)
{
    *q = (qsel){2, NULL, RPIV_UNIT_PX_PER_DT};
    if (!strcmp(name, "none"))
        q->kind = 0;
    else if (!strcmp(name, "magnitude"))
        q->kind = 1;
    else if (!strcmp(name, "u"))
        q->data = f->u;
    else if (!strcmp(name, "v"))
        q->data = f->v;
    else if (!strcmp(name, "peak_ratio") || !strcmp(name, "correlation")) {
        q->data = name[0] == 'p' ? f->peak_ratio : f->corr;
        q->unit = RPIV_UNIT_ONE;
    } else {
        const rpiv_quantity *e = rpiv_field_quantity(f, name);
        if (!e)
            return 0;
        q->data = e->data;
        q->unit = e->unit & 0xff;
    }
    return 1;
}

rpiv_status rpiv_plot_field_params_check(const rpiv_plot_field_params *p, const rpiv_field *f)
{
    if (p->width_px < 100 || p->width_px > 10000 || p->height_px < 100 || p->height_px > 10000)
        return rpiv_fail(RPIV_EINVAL, "plot: size %d x %d px outside 100..10000", p->width_px,
                         p->height_px);
    if (p->every < 0)
        return rpiv_fail(RPIV_EINVAL, "plot: every %d must be >= 1 (or 0: automatic)", p->every);
    if (!(p->arrow_scale > 0) || !isfinite(p->arrow_scale))
        return rpiv_fail(RPIV_EINVAL, "plot: arrow scale %g must be > 0", p->arrow_scale);
    if (!p->quantity || !*p->quantity)
        return rpiv_fail(RPIV_EINVAL, "plot: no quantity named");
    qsel q;
    if (f && !pick_quantity(f, p->quantity, &q)) {
        char list[1024] = "magnitude, u, v, peak_ratio, correlation";
        size_t len = strlen(list);
        for (size_t k = 0; k < f->nq && len + RPIV_QUANTITY_NAME_MAX + 3 < sizeof list; k++)
            len += (size_t)snprintf(list + len, sizeof list - len, ", %s", f->q[k].name);
        return rpiv_fail(RPIV_EINVAL, "unknown quantity '%s': the field has %s (or none)",
                         p->quantity, list);
    }
    if (p->background && (p->background->w < 1 || p->background->h < 1 || !p->background->px))
        return rpiv_fail(RPIV_EINVAL, "plot: the background image is empty");
    return RPIV_OK;
}

rpiv_status rpiv_plot_path_check(const char *path)
{
    const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash) || strcasecmp(dot, ".png"))
        return rpiv_fail(RPIV_EINVAL, "%s: figures are written as PNG only (name it .png)", path);
    return RPIV_OK;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The quantiles qlo, qhi of the finite values among z[0], z[step], z[2 step]...; returns
 * how many there were (0: none, *lo and *hi untouched), or -1 out of memory. */
static long quantiles(const double *z, size_t n, size_t step, double qlo, double qhi, double *lo,
                      double *hi)
{
    double *t = malloc((n / step + 1) * sizeof *t);
    if (!t)
        return -1;
    size_t m = 0;
    for (size_t k = 0; k < n; k += step)
        if (isfinite(z[k]))
            t[m++] = z[k];
    if (m) {
        qsort(t, m, sizeof *t, cmp_double);
        *lo = t[(size_t)floor(qlo * (double)(m - 1) + 0.5)];
        *hi = t[(size_t)floor(qhi * (double)(m - 1) + 0.5)];
    }
    free(t);
    return (long)m;
}

/* The largest of 1, 2, 5 times a power of ten not above x > 0. */
static double nice_below(double x)
{
    double e = pow(10, floor(log10(x)));
    double m = x / e * (1 + 1e-9);
    return (m >= 5 ? 5 : m >= 2 ? 2 : 1) * e;
}

typedef struct field_ctx {
    const rpiv_field *f;
    const char *title;
    int every, physical, diverging;
    double lf;                 /* axis unit per px (mm or 1)                  */
    double wx0, wx1, wy0, wy1; /* world window                                 */
    double *z;                 /* quantity, display unit, NaN masked; or NULL */
    double zlo, zhi;
    char zlabel[96];
    const char *vunit;
    double *bg; /* background rows in increasing world y, or NULL */
    int bw, bh;
    double glo, ghi;
    double *uv;         /* 4 layers of mx x my: u, v valid; u, v replaced (display unit) */
    const PLFLT **cols; /* 4 mx columns into uv (PLplot's matrices)                */
    int mx, my;
    double alen, ref;
    size_t nvalid, nreplaced, nmasked;
} field_ctx;

/* An arrow from (x, y) of length len along +x in normalised device coordinates; ry is the
 * page's width / height (a head of equal sides on the page). */
static void key_arrow(double x, double y, double len, double ry)
{
    double hl = fmin(0.35 * len, 0.012), hw = 0.45 * hl * ry;
    PLFLT lx[2] = {x, x + len - 0.5 * hl}, ly[2] = {y, y};
    PLFLT hx[3] = {x + len - hl, x + len, x + len - hl}, hy[3] = {y - hw, y, y + hw};
    plline(2, lx, ly);
    plfill(3, hx, hy);
}

static void draw_key(const field_ctx *c, const rpiv_plot_opts *o)
{
    PLFLT vx0, vx1, vy0, vy1;
    plgvpd(&vx0, &vx1, &vy0, &vy1);
    double ry = (double)o->width_px / o->height_px;
    double ndc_per_world = (vx1 - vx0) / (c->wx1 - c->wx0);
    plvpor(0, 1, 0, 1);
    plwind(0, 1, 0, 1);
    /* one line under the x label, from the page's left margin; the text's width is
     * estimated at 11.5 px a character (PLplot's default font at 0.9 scale on pngcairo) */
    double y = fmax(0.03, vy0 - 0.1), x = 0.06, cw = 11.5 / o->width_px;
    char txt[128];
    plcol0(COL_FG);
    plwidth(1.5);
    if (c->ref > 0) {
        double len = c->alen * c->ref * ndc_per_world;
        key_arrow(x, y, len, ry);
        snprintf(txt, sizeof txt, "reference %g %s", c->ref, c->vunit);
        plptex(x + len + 0.01, y, 1, 0, 0, txt);
        x += len + 0.05 + cw * (double)strlen(txt);
    }
    /* the flags: a short arrow (valid, replaced) or the mark of masked points */
    snprintf(txt, sizeof txt, "valid (%zu)", c->nvalid);
    key_arrow(x, y, 0.02, ry);
    plptex(x + 0.03, y, 1, 0, 0, txt);
    x += 0.06 + cw * (double)strlen(txt);
    plcol0(COL_REPLACED);
    key_arrow(x, y, 0.02, ry);
    plcol0(COL_FG);
    snprintf(txt, sizeof txt, "replaced (%zu)", c->nreplaced);
    plptex(x + 0.03, y, 1, 0, 0, txt);
    x += 0.06 + cw * (double)strlen(txt);
    PLFLT mx = x + 0.015, my = y;
    plcol0(COL_SERIES + 7);
    plstring(1, &mx, &my, "×");
    plcol0(COL_FG);
    snprintf(txt, sizeof txt, "masked (%zu)", c->nmasked);
    plptex(x + 0.03, y, 1, 0, 0, txt);
    plwidth(1);
}

static rpiv_status draw_field(const void *vctx, const rpiv_plot_opts *o)
{
    const field_ctx *c = vctx;
    const rpiv_field *f = c->f;
    rpiv_status st = RPIV_OK;
    plvpas(0.10, c->z ? 0.80 : 0.95, 0.17, 0.92, (c->wy1 - c->wy0) / (c->wx1 - c->wx0));
    if (f->y_up)
        plwind(c->wx0, c->wx1, c->wy0, c->wy1);
    else
        plwind(c->wx0, c->wx1, c->wy1, c->wy0);
    if (c->bg) {
        plot_set_cmap1(RPIV_PLOT_CMAP_GRAY, 1.0);
        st = plot_draw_cells(c->bg, c->bw, c->bh, -0.5 * c->lf, (c->bw - 0.5) * c->lf, -0.5 * c->lf,
                             (c->bh - 0.5) * c->lf, c->glo, c->ghi, o->width_px, o->height_px);
    }
    rpiv_plot_cmap cm = c->diverging ? RPIV_PLOT_CMAP_DIVERGING : RPIV_PLOT_CMAP_VIRIDIS;
    if (!st && c->z) {
        plot_set_cmap1(cm, c->bg ? 0.5 : 1.0);
        st = plot_draw_cells(c->z, f->nx, f->ny, (f->x0 - 0.5 * f->dx) * c->lf,
                             (f->x0 + (f->nx - 0.5) * f->dx) * c->lf, (f->y0 - 0.5 * f->dy) * c->lf,
                             (f->y0 + (f->ny - 0.5) * f->dy) * c->lf, c->zlo, c->zhi, o->width_px,
                             o->height_px);
    }
    if (st)
        return st;
    plcol0(COL_FG);
    plbox("bcnst", 0, 0, "bcnstv", 0, 0);
    char xl[32], yl[32];
    snprintf(xl, sizeof xl, "x (%s)", c->physical ? "mm" : "px");
    snprintf(yl, sizeof yl, "y (%s, %s)", c->physical ? "mm" : "px", f->y_up ? "up" : "down");
    pllab(xl, yl, c->title ? c->title : "");
    /* masked points of the arrow grid */
    plcol0(COL_SERIES + 7);
    plschr(0, 0.6);
    for (int j = 0; j < f->ny; j += c->every)
        for (int i = 0; i < f->nx; i += c->every)
            if (f->flag[(size_t)j * (size_t)f->nx + (size_t)i] == RPIV_FLAG_MASKED) {
                PLFLT x = (f->x0 + i * f->dx) * c->lf, y = (f->y0 + j * f->dy) * c->lf;
                plstring(1, &x, &y, "×");
            }
    plschr(0, 0.9);
    if (c->ref > 0) {
        const PLFLT **cp = c->cols;
        grid_map g = {f->x0 * c->lf, f->y0 * c->lf, f->dx * c->every * c->lf,
                      f->dy * c->every * c->lf};
        plwidth(1.4);
        plcol0(COL_FG);
        plvect(cp, cp + c->mx, c->mx, c->my, PLVECT_FACTOR * c->alen, grid_xform, &g);
        plcol0(COL_REPLACED);
        plvect(cp + 2 * c->mx, cp + 3 * c->mx, c->mx, c->my, PLVECT_FACTOR * c->alen, grid_xform,
               &g);
        plwidth(1);
    }
    plcol0(COL_FG);
    if (c->z) {
        plot_set_cmap1(cm, 1.0);
        plot_colour_bar(c->zlo, c->zhi, c->zlabel);
    }
    draw_key(c, o);
    return RPIV_OK;
}

/* The colour map's values and range, label and kind. */
static rpiv_status field_quantity(field_ctx *c, const qsel *q, const char *name)
{
    const rpiv_field *f = c->f;
    size_t n = (size_t)f->nx * (size_t)f->ny;
    double zf = c->physical ? rpiv_unit_factor(f, q->unit) : 1.0;
    c->z = malloc(n * sizeof *c->z);
    if (!c->z)
        return rpiv_fail(RPIV_ENOMEM, "plot: out of memory for a %d x %d map", f->nx, f->ny);
    for (size_t k = 0; k < n; k++) {
        double v = q->kind == 1 ? hypot((double)f->u[k], (double)f->v[k]) : (double)q->data[k];
        c->z[k] = f->flag[k] == RPIV_FLAG_MASKED ? (double)NAN : v * zf;
    }
    double lo = 0, hi = 1;
    long m = quantiles(c->z, n, 1, 0.005, 0.995, &lo, &hi);
    if (m < 0)
        return rpiv_fail(RPIV_ENOMEM, "plot: out of memory");
    c->diverging = lo < 0 && hi > 0;
    if (c->diverging) {
        hi = fmax(-lo, hi);
        lo = -hi;
    }
    if (hi - lo <= 1e-12 * fmax(1.0, fabs(hi))) {
        double pad = fmax(0.5, 0.05 * fabs(hi));
        lo -= pad;
        hi += pad;
    }
    c->zlo = lo;
    c->zhi = hi;
    static const char *const px_unit[4] = {"", "px", "px/dt", "1/dt"};
    static const char *const ph_unit[4] = {"", "mm", "m/s", "1/s"};
    const char *u = (c->physical ? ph_unit : px_unit)[q->unit & 3];
    const char *what =
        q->kind == 1 ? (c->physical ? "speed |(u, v)|" : "displacement |(u, v)|") : name;
    if (*u)
        snprintf(c->zlabel, sizeof c->zlabel, "%s (%s)", what, u);
    else
        snprintf(c->zlabel, sizeof c->zlabel, "%s", what);
    return RPIV_OK;
}

/* The image in grey, rows in increasing world y, and its 1 %..99.5 % grey range. */
static rpiv_status field_background(field_ctx *c, const rpiv_image *im)
{
    size_t n = (size_t)im->w * (size_t)im->h;
    c->bg = malloc(n * sizeof *c->bg);
    if (!c->bg)
        return rpiv_fail(RPIV_ENOMEM, "plot: out of memory for a %d x %d image", im->w, im->h);
    c->bw = im->w;
    c->bh = im->h;
    for (int r = 0; r < im->h; r++) {
        const float *src = im->px + (size_t)(c->f->y_up ? im->h - 1 - r : r) * (size_t)im->w;
        for (int x = 0; x < im->w; x++)
            c->bg[(size_t)r * (size_t)im->w + (size_t)x] = (double)src[x];
    }
    c->glo = 0;
    c->ghi = 1;
    if (quantiles(c->bg, n, n / 1000000 + 1, 0.01, 0.995, &c->glo, &c->ghi) < 0)
        return rpiv_fail(RPIV_ENOMEM, "plot: out of memory");
    if (!(c->ghi > c->glo))
        c->ghi = c->glo + 1;
    return RPIV_OK;
}

/* The arrows: stride, the drawn (u, v) per flag layer, their length per unit and the
 * reference arrow. */
static rpiv_status field_arrows(field_ctx *c, const rpiv_plot_field_params *p)
{
    const rpiv_field *f = c->f;
    int every = p->every ? p->every : (int)ceil((f->nx > f->ny ? f->nx : f->ny) / 28.0);
    c->every = every < 1 ? 1 : every;
    c->mx = (f->nx + c->every - 1) / c->every;
    c->my = (f->ny + c->every - 1) / c->every;
    size_t m = (size_t)c->mx * (size_t)c->my;
    double vf = c->physical ? rpiv_unit_factor(f, RPIV_UNIT_PX_PER_DT) : 1.0;
    c->uv = calloc(4 * m, sizeof *c->uv);
    double *speed = malloc(m * sizeof *speed);
    c->cols = malloc(4 * (size_t)c->mx * sizeof *c->cols);
    if (!c->uv || !speed || !c->cols) {
        free(speed);
        return rpiv_fail(RPIV_ENOMEM, "plot: out of memory for %zu arrows", m);
    }
    for (size_t l = 0; l < 4; l++)
        for (int i = 0; i < c->mx; i++)
            c->cols[l * (size_t)c->mx + (size_t)i] = c->uv + l * m + (size_t)i * (size_t)c->my;
    for (int i = 0; i < c->mx; i++)
        for (int j = 0; j < c->my; j++) {
            size_t k = (size_t)(j * c->every) * (size_t)f->nx + (size_t)(i * c->every),
                   q = (size_t)i * (size_t)c->my + (size_t)j;
            speed[q] = (double)NAN;
            if (f->flag[k] == RPIV_FLAG_MASKED)
                continue;
            size_t l = f->flag[k] == RPIV_FLAG_REPLACED ? 2 : 0;
            double u = (double)f->u[k] * vf, v = (double)f->v[k] * vf;
            c->uv[l * m + q] = u;
            c->uv[(l + 1) * m + q] = v;
            speed[q] = hypot(u, v);
        }
    double lo = 0, p95 = 0;
    long ns = quantiles(speed, m, 1, 0, 0.95, &lo, &p95);
    free(speed);
    if (ns < 0)
        return rpiv_fail(RPIV_ENOMEM, "plot: out of memory");
    c->alen = 0;
    c->ref = 0;
    if (ns > 0 && p95 > 0 && isfinite(p95)) {
        double step = c->every * fmin(f->dx, f->dy) * c->lf;
        c->alen = p->arrow_scale * 0.9 * step / p95;
        c->ref = nice_below(p95);
        /* the reference arrow stays within a fifth of the plot's width */
        while (c->alen * c->ref > 0.2 * (c->wx1 - c->wx0) && c->ref > 1e-300)
            c->ref = nice_below(c->ref * 0.99);
    }
    return RPIV_OK;
}

rpiv_status rpiv_plot_field(const rpiv_field *f, const char *path, const char *title,
                            const rpiv_plot_field_params *p, rpiv_plot_field_info *info)
{
    rpiv_status st = rpiv_plot_path_check(path);
    if (!st)
        st = rpiv_plot_field_params_check(p, f);
    if (st)
        return st;
    qsel q;
    (void)pick_quantity(f, p->quantity, &q); /* checked above */
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.width_px = p->width_px;
    o.height_px = p->height_px;
    field_ctx c = {.f = f, .title = title};
    c.physical = f->scale_mm_per_px > 0 && f->dt_s > 0;
    c.lf = c.physical ? f->scale_mm_per_px : 1.0;
    c.vunit = c.physical ? "m/s" : "px/dt";
    c.wx0 = (f->x0 - 0.5 * f->dx) * c.lf;
    c.wx1 = (f->x0 + (f->nx - 0.5) * f->dx) * c.lf;
    c.wy0 = (f->y0 - 0.5 * f->dy) * c.lf;
    c.wy1 = (f->y0 + (f->ny - 0.5) * f->dy) * c.lf;
    if (p->background) {
        c.wx0 = fmin(c.wx0, -0.5 * c.lf);
        c.wx1 = fmax(c.wx1, (p->background->w - 0.5) * c.lf);
        c.wy0 = fmin(c.wy0, -0.5 * c.lf);
        c.wy1 = fmax(c.wy1, (p->background->h - 0.5) * c.lf);
    }
    size_t n = (size_t)f->nx * (size_t)f->ny;
    for (size_t k = 0; k < n; k++) {
        c.nvalid += f->flag[k] == RPIV_FLAG_VALID;
        c.nreplaced += f->flag[k] == RPIV_FLAG_REPLACED;
        c.nmasked += f->flag[k] == RPIV_FLAG_MASKED;
    }
    if ((q.kind && (st = field_quantity(&c, &q, p->quantity))) ||
        (p->background && (st = field_background(&c, p->background))) || (st = field_arrows(&c, p)))
        goto cleanup;
    st = plot_run(path, &o, draw_field, &c);
    if (!st && info)
        *info = (rpiv_plot_field_info){c.every,    c.alen,   c.ref,       c.zlo,    c.zhi,
                                       c.physical, c.nvalid, c.nreplaced, c.nmasked};
cleanup:
    free(c.z);
    free(c.bg);
    free(c.uv);
    free(c.cols);
    return st;
}
