/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/report/plot.c - PNG figures through PLplot's pngcairo device. PLplot is global state: one
 * plot at a time (see plot.h). Its fatal errors (plexit) would call exit(); the exit hook
 * jumps back into the running rpiv_plot_* call instead, and its non-fatal errors (plabort)
 * go into a buffer (plsError) rather than to stderr. */
#include "rpiv/plot.h"

#include "plot_impl.h"

#include "base/atomic.h"

#include <errno.h>
#include <math.h>
#include <plplot/plplot.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/statvfs.h>

/* The call in progress, for the exit hook (PLplot's hook has no user pointer). */
typedef struct plot_call {
    jmp_buf env;
    char exit_msg[256];
    char err_msg[1024]; /* plsError buffer */
    PLINT err_code;
} plot_call;

static plot_call *current;

static int exit_hook(PLCHAR_VECTOR msg)
{
    snprintf(current->exit_msg, sizeof current->exit_msg, "%s", msg ? msg : "");
    longjmp(current->env, 1);
}

rpiv_plot_opts rpiv_plot_opts_default(void)
{
    return (rpiv_plot_opts){.width_px = 800,
                            .height_px = 600,
                            .xlabel = "x (px)",
                            .ylabel = "y (px)",
                            .cmap = RPIV_PLOT_CMAP_VIRIDIS,
                            .background = 1,
                            .stride = 1};
}

rpiv_status plot_opts_check(const rpiv_plot_opts *o, const char *path)
{
    if (o->width_px < 100 || o->width_px > 10000 || o->height_px < 100 || o->height_px > 10000)
        return rpiv_fail(RPIV_EINVAL, "%s: plot size %d x %d px outside 100..10000", path,
                         o->width_px, o->height_px);
    if (o->stride < 1)
        return rpiv_fail(RPIV_EINVAL, "%s: plot stride %d must be >= 1", path, o->stride);
    if (!(o->arrow_scale >= 0) || !isfinite(o->arrow_scale))
        return rpiv_fail(RPIV_EINVAL, "%s: arrow scale %g must be >= 0", path, o->arrow_scale);
    if (o->y_axis < 0 || o->y_axis > RPIV_PLOT_DOWN || o->aspect < 0 || o->aspect > RPIV_PLOT_FREE)
        return rpiv_fail(RPIV_EINVAL, "%s: y_axis %d / aspect %d not AUTO, 1 or 2", path, o->y_axis,
                         o->aspect);
    if ((unsigned)o->cmap > RPIV_PLOT_CMAP_DIVERGING)
        return rpiv_fail(RPIV_EINVAL, "%s: unknown colour map %d", path, (int)o->cmap);
    return RPIV_OK;
}

/* Replace RPIV_PLOT_AUTO by what suits the kind of plot. */
void plot_resolve_auto(rpiv_plot_opts *o, int y_axis, int aspect)
{
    if (o->y_axis == RPIV_PLOT_AUTO)
        o->y_axis = y_axis;
    if (o->aspect == RPIV_PLOT_AUTO)
        o->aspect = aspect;
}

/* ---- colours ---------------------------------------------------------------- */

static void set_cmap0(void)
{
    /* a qualitative palette of ten distinguishable colours for curves */
    static const PLINT rgb[NSERIES_COL][3] = {
        {31, 119, 180}, {255, 127, 14},  {44, 160, 44},   {214, 39, 40},  {148, 103, 189},
        {140, 86, 75},  {227, 119, 194}, {127, 127, 127}, {188, 189, 34}, {23, 190, 207}};
    plscmap0n(NCOL0);
    plscol0(COL_BG, 255, 255, 255);
    plscol0(COL_FG, 0, 0, 0);
    for (int k = 0; k < NSERIES_COL; k++)
        plscol0(COL_SERIES + k, rgb[k][0], rgb[k][1], rgb[k][2]);
    plscol0(COL_REPLACED, 220, 20, 20);
}

void plot_set_cmap1(rpiv_plot_cmap cm, double alpha)
{
    /* viridis sampled at five points; linear RGB interpolation between them */
    static const PLFLT vi[5] = {0, 0.25, 0.5, 0.75, 1};
    static const PLFLT vr[5] = {68 / 255., 59 / 255., 33 / 255., 94 / 255., 253 / 255.};
    static const PLFLT vg[5] = {1 / 255., 82 / 255., 145 / 255., 201 / 255., 231 / 255.};
    static const PLFLT vb[5] = {84 / 255., 139 / 255., 140 / 255., 98 / 255., 37 / 255.};
    static const PLFLT gi[2] = {0, 1}, gv0[2] = {0, 1};
    static const PLFLT di[3] = {0, 0.5, 1};
    static const PLFLT dr[3] = {0.23, 1, 0.71}, dg[3] = {0.30, 1, 0.02}, db[3] = {0.75, 1, 0.15};
    const PLFLT al[5] = {alpha, alpha, alpha, alpha, alpha};
    plscmap1n(256);
    if (cm == RPIV_PLOT_CMAP_GRAY)
        plscmap1la(1, 2, gi, gv0, gv0, gv0, al, NULL);
    else if (cm == RPIV_PLOT_CMAP_DIVERGING)
        plscmap1la(1, 3, di, dr, dg, db, al, NULL);
    else
        plscmap1la(1, 5, vi, vr, vg, vb, al, NULL);
}

/* ---- the frame around every plot ------------------------------------------- */

/* 1 if path holds a whole PNG: the signature, then chunks whose lengths walk exactly to the
 * end of the file, the last one IEND. cairo does not report a failed write (a full disk), so
 * a truncated file is found here, before it could replace a good one. */
static int png_complete(const char *path)
{
    static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    unsigned char buf[8];
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return 0;
    int ok = fread(buf, 1, 8, fp) == 8 && memcmp(buf, sig, 8) == 0, iend = 0;
    while (ok && !iend) {
        if (fread(buf, 1, 8, fp) != 8) {
            ok = 0;
            break;
        }
        unsigned long len = (unsigned long)buf[0] << 24 | (unsigned long)buf[1] << 16 |
                            (unsigned long)buf[2] << 8 | buf[3];
        iend = memcmp(buf + 4, "IEND", 4) == 0;
        /* data and CRC */
        ok = len <= 0x7fffffffUL && fseek(fp, (long)len + 4, SEEK_CUR) == 0;
    }
    if (ok) { /* the seek may pass the end: the position must be the file's size */
        long at = ftell(fp);
        ok = at > 0 && fseek(fp, 0, SEEK_END) == 0 && ftell(fp) == at;
    }
    fclose(fp);
    return ok && iend;
}

/* Why a PNG came out incomplete: a (nearly) full file system, or something else. */
static rpiv_status png_incomplete(const char *path, const char *tmp)
{
    struct statvfs sv;
    if (statvfs(tmp, &sv) == 0 && (double)sv.f_bavail * (double)sv.f_frsize < 1048576.0)
        return rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(ENOSPC));
    return rpiv_fail(RPIV_EIO, "%s: PLplot's pngcairo device wrote no complete PNG", path);
}

/* Open a pngcairo stream on a temporary file next to path, run draw, close, check, publish. */
rpiv_status plot_run(const char *path, const rpiv_plot_opts *o, draw_fn draw, const void *ctx)
{
    atomic_file af;
    rpiv_status st = atomic_begin(&af, path, 0);
    if (st)
        return st;
    plot_call call;
    memset(&call, 0, sizeof call);
    current = &call;
    if (setjmp(call.env)) {
        plend1();
        plsexit(NULL);
        current = NULL;
        atomic_abort(&af);
        return rpiv_fail(RPIV_EFORMAT, "%s: PLplot: %s", path,
                         call.exit_msg[0] ? call.exit_msg : "fatal error");
    }
    plsexit(exit_hook);
    plsError(&call.err_code, call.err_msg);
    plsdev("pngcairo");
    plsfnam(af.tmp);
    plspage(0, 0, o->width_px, o->height_px, 0, 0);
    set_cmap0();
    plinit();
    plsError(&call.err_code, call.err_msg);
    plot_set_cmap1(o->cmap, 1.0);
    pladv(0);
    plschr(0, 0.9);
    plcol0(COL_FG);
    rpiv_status dst = draw(ctx, o);
    /* plend1, not plend: the stream closes (the file is complete) but the driver stays
     * loaded for the next plot; plend would dlopen it again each time and leak the handle */
    plend1();
    plsexit(NULL);
    current = NULL;
    if (dst) {
        atomic_abort(&af);
        return dst;
    }
    if (call.err_code) {
        char *m = call.err_msg;
        m += strspn(m, "\n");
        for (char *p = m; *p; p++)
            if (*p == '\n')
                *p = ' ';
        atomic_abort(&af);
        return rpiv_fail(RPIV_EFORMAT, "%s: PLplot: %s", path, m);
    }
    if (!png_complete(af.tmp)) {
        st = png_incomplete(path, af.tmp);
        atomic_abort(&af);
        return st;
    }
    return atomic_commit(&af);
}

/* The viewport (leaving room for a colour bar on the right when cbar) and world window. */
void plot_frame(const rpiv_plot_opts *o, double x0, double x1, double y0, double y1, int cbar,
                const char *xl, const char *yl, const char *title)
{
    double right = cbar ? 0.80 : 0.95;
    if (o->aspect == RPIV_PLOT_EQUAL)
        plvpas(0.10, right, 0.11, 0.92, (y1 - y0) / (x1 - x0));
    else
        plvpor(0.10, right, 0.11, 0.92);
    if (o->y_axis == RPIV_PLOT_DOWN)
        plwind(x0, x1, y1, y0);
    else
        plwind(x0, x1, y0, y1);
    plcol0(COL_FG);
    plbox("bcnst", 0, 0, "bcnstv", 0, 0);
    pllab(xl ? xl : "", yl ? yl : "", title ? title : "");
}

void plot_colour_bar(double zmin, double zmax, const char *label)
{
    PLFLT w, h;
    PLINT label_opts[1] = {PL_COLORBAR_LABEL_RIGHT};
    PLCHAR_VECTOR labels[1] = {label ? label : ""};
    PLCHAR_VECTOR axis_opts[1] = {"bcvtm"};
    PLFLT ticks[1] = {0};
    PLINT sub_ticks[1] = {0};
    enum { NV = 128 };
    PLINT n_values[1] = {NV};
    PLFLT v[NV];
    for (int k = 0; k < NV; k++)
        v[k] = zmin + (zmax - zmin) * k / (NV - 1);
    const PLFLT *values[1] = {v};
    plcol0(COL_FG);
    /* an image bar: PLplot's cairo gradient (PL_COLORBAR_GRADIENT) leaks its pattern */
    plcolorbar(&w, &h, PL_COLORBAR_IMAGE, PL_POSITION_RIGHT | PL_POSITION_OUTSIDE, 0.02, 0, 0.03,
               0.9, COL_BG, COL_FG, 1, 0, 0, 0, 0, 1, label_opts, labels, 1, axis_opts, ticks,
               sub_ticks, n_values, values);
}

void plot_zrange(const double *z, size_t n, const rpiv_plot_opts *o, double *lo, double *hi)
{
    if (o->zmin < o->zmax) {
        *lo = o->zmin;
        *hi = o->zmax;
        return;
    }
    *lo = (double)INFINITY;
    *hi = -(double)INFINITY;
    for (size_t k = 0; k < n; k++)
        if (isfinite(z[k])) {
            *lo = fmin(*lo, z[k]);
            *hi = fmax(*hi, z[k]);
        }
    if (!isfinite(*lo)) {
        *lo = 0;
        *hi = 1;
    }
    if (*hi - *lo <= 1e-12 * fmax(1.0, fabs(*hi))) {
        double pad = fmax(0.5, 0.05 * fabs(*hi));
        *lo -= pad;
        *hi += pad;
    }
}

/* Draw z (nx x ny, row-major) as cells over [x0,x1] x [y0,y1]; reduce by block averages to
 * at most max_cells per axis first (PLplot fills one polygon per cell). */
rpiv_status plot_draw_cells(const double *z, int nx, int ny, double x0, double x1, double y0,
                            double y1, double zlo, double zhi, int max_x, int max_y)
{
    int bx = (nx + max_x - 1) / max_x, by = (ny + max_y - 1) / max_y;
    int mx = (nx + bx - 1) / bx, my = (ny + by - 1) / by;
    /* PLplot's plimagefr (no transform) spreads nx cells over [xmin, xmax] at a step of
     * (xmax - xmin) / (nx - 1), cell k covering [xmin + k step, xmin + (k + 1) step]: the
     * last cell falls outside. So it gets the extent shortened by one cell, and at least two
     * cells each way (a single row or column is doubled). */
    int px = mx < 2 ? 2 : mx, py = my < 2 ? 2 : my;
    PLFLT *buf = malloc((size_t)px * (size_t)py * sizeof *buf);
    const PLFLT **cols = malloc((size_t)px * sizeof *cols);
    if (!buf || !cols) {
        free(buf);
        free(cols);
        return rpiv_fail(RPIV_ENOMEM, "plot: out of memory for a %d x %d map", mx, my);
    }
    /* PLplot's matrices are indexed [i][j] with i along x */
    for (int i = 0; i < px; i++) {
        cols[i] = buf + (size_t)i * (size_t)py;
        for (int j = 0; j < py; j++) {
            int si = i * mx / px, sj = j * my / py;
            double s = 0;
            int c = 0;
            for (int jj = sj * by; jj < (sj + 1) * by && jj < ny; jj++)
                for (int ii = si * bx; ii < (si + 1) * bx && ii < nx; ii++) {
                    double val = z[(size_t)jj * (size_t)nx + (size_t)ii];
                    if (isfinite(val)) {
                        s += val;
                        c++;
                    }
                }
            buf[(size_t)i * (size_t)py + (size_t)j] = c ? s / c : (double)NAN;
        }
    }
    /* the edge cells of a reduced map are partly empty: its extent shrinks accordingly */
    double ex1 = x0 + (x1 - x0) * (double)(mx * bx) / nx;
    double ey1 = y0 + (y1 - y0) * (double)(my * by) / ny;
    /* values outside [zlo, zhi] saturate; blank cells go below zlo, which plimage skips */
    double blank = zlo - (zhi - zlo) - 1;
    for (size_t k = 0; k < (size_t)px * (size_t)py; k++)
        buf[k] = isnan(buf[k]) ? blank : fmin(fmax(buf[k], zlo), zhi);
    /* plimagefr, not plimage: plimage stretches the colours over the data's own range, so a
     * map narrower than [zlo, zhi] (a flat field) came out in the wrong colours */
    plimagefr(cols, px, py, x0, x0 + (ex1 - x0) * (px - 1) / px, y0,
              y0 + (ey1 - y0) * (py - 1) / py, zlo, zhi, zlo, zhi, NULL, NULL);
    free(cols);
    free(buf);
    return RPIV_OK;
}

/* ---- maps --------------------------------------------------------------------- */

typedef struct map_ctx {
    const double *z;
    int nx, ny;
    double ext[4];
    const char *title;
} map_ctx;

static rpiv_status draw_map(const void *vctx, const rpiv_plot_opts *o)
{
    const map_ctx *c = vctx;
    double zlo, zhi;
    plot_zrange(c->z, (size_t)c->nx * (size_t)c->ny, o, &zlo, &zhi);
    double x0 = c->ext[0], x1 = c->ext[1], y0 = c->ext[2], y1 = c->ext[3];
    if (o->xmin < o->xmax) {
        x0 = o->xmin;
        x1 = o->xmax;
    }
    if (o->ymin < o->ymax) {
        y0 = o->ymin;
        y1 = o->ymax;
    }
    plot_frame(o, x0, x1, y0, y1, 1, o->xlabel, o->ylabel, c->title);
    rpiv_status st = plot_draw_cells(c->z, c->nx, c->ny, c->ext[0], c->ext[1], c->ext[2], c->ext[3],
                                     zlo, zhi, o->width_px, o->height_px);
    if (st)
        return st;
    plcol0(COL_FG);
    plbox("bc", 0, 0, "bc", 0, 0); /* the image covers the frame: redraw it */
    plot_colour_bar(zlo, zhi, o->zlabel);
    return RPIV_OK;
}

rpiv_status rpiv_plot_map(const char *path, const char *title, const double *z, int nx, int ny,
                          const double *extent, const rpiv_plot_opts *opts)
{
    rpiv_plot_opts o = opts ? *opts : rpiv_plot_opts_default();
    rpiv_status st = plot_opts_check(&o, path);
    if (st)
        return st;
    plot_resolve_auto(&o, RPIV_PLOT_DOWN, RPIV_PLOT_EQUAL);
    if (nx < 1 || ny < 1)
        return rpiv_fail(RPIV_EINVAL, "%s: map size %d x %d is empty", path, nx, ny);
    map_ctx c = {z, nx, ny, {-0.5, nx - 0.5, -0.5, ny - 0.5}, title};
    if (extent) {
        if (!(extent[1] > extent[0]) || !(extent[3] > extent[2]) || !isfinite(extent[0]) ||
            !isfinite(extent[1]) || !isfinite(extent[2]) || !isfinite(extent[3]))
            return rpiv_fail(RPIV_EINVAL, "%s: map extent [%g, %g] x [%g, %g] is empty", path,
                             extent[0], extent[1], extent[2], extent[3]);
        memcpy(c.ext, extent, sizeof c.ext);
    }
    return plot_run(path, &o, draw_map, &c);
}

/* ---- lines --------------------------------------------------------------------- */

typedef struct lines_ctx {
    const rpiv_plot_series *s;
    size_t ns;
    const char *title, *xl, *yl;
    double x0, x1, y0, y1;
} lines_ctx;

/* markers, chosen to be told apart in black and white too */
static const char *const marker[] = {"●", "■", "▲", "◆", "▼", "✚", "✖", "★"};
#define NMARKER (sizeof marker / sizeof marker[0])

static rpiv_status draw_lines(const void *vctx, const rpiv_plot_opts *o)
{
    const lines_ctx *c = vctx;
    plot_frame(o, c->x0, c->x1, c->y0, c->y1, 0, c->xl, c->yl, c->title);
    size_t nleg = 0;
    for (size_t k = 0; k < c->ns; k++) {
        const rpiv_plot_series *s = &c->s[k];
        plcol0(COL_SERIES + (PLINT)(k % NSERIES_COL));
        plwidth(1.5);
        if (s->style != RPIV_PLOT_POINTS) {
            /* a line through each run of finite points */
            size_t a = 0;
            while (a < s->n) {
                while (a < s->n && !(isfinite(s->x[a]) && isfinite(s->y[a])))
                    a++;
                size_t b = a;
                while (b < s->n && isfinite(s->x[b]) && isfinite(s->y[b]))
                    b++;
                if (b - a >= 2)
                    plline((PLINT)(b - a), s->x + a, s->y + a);
                a = b;
            }
        }
        if (s->style != RPIV_PLOT_LINE) {
            plschr(0, 0.6);
            for (size_t q = 0; q < s->n; q++)
                if (isfinite(s->x[q]) && isfinite(s->y[q]))
                    plstring(1, s->x + q, s->y + q, marker[k % NMARKER]);
            plschr(0, 0.9);
        }
        if (s->label && *s->label)
            nleg++;
    }
    plwidth(1);
    if (nleg) {
        PLINT *opt = calloc(nleg, sizeof *opt), *col = calloc(nleg, sizeof *col);
        PLINT *lsty = calloc(nleg, sizeof *lsty), *tcol = calloc(nleg, sizeof *tcol);
        PLINT *nsym = calloc(nleg, sizeof *nsym);
        PLFLT *lw = calloc(nleg, sizeof *lw), *ssc = calloc(nleg, sizeof *ssc);
        PLCHAR_VECTOR *text = calloc(nleg, sizeof *text), *sym = calloc(nleg, sizeof *sym);
        if (!opt || !col || !lsty || !tcol || !nsym || !lw || !ssc || !text || !sym) {
            free(opt), free(col), free(lsty), free(tcol), free(nsym), free(lw), free(ssc);
            free(text), free(sym);
            return rpiv_fail(RPIV_ENOMEM, "plot: out of memory for the legend");
        }
        size_t e = 0;
        for (size_t k = 0; k < c->ns; k++) {
            const rpiv_plot_series *s = &c->s[k];
            if (!s->label || !*s->label)
                continue;
            opt[e] = (s->style != RPIV_PLOT_POINTS ? PL_LEGEND_LINE : 0) |
                     (s->style != RPIV_PLOT_LINE ? PL_LEGEND_SYMBOL : 0);
            col[e] = COL_SERIES + (PLINT)(k % NSERIES_COL);
            tcol[e] = COL_FG;
            lsty[e] = 1;
            lw[e] = 1.5;
            nsym[e] = 1;
            ssc[e] = 0.6;
            text[e] = s->label;
            sym[e] = marker[k % NMARKER];
            e++;
        }
        PLFLT w, h;
        plcol0(COL_FG);
        pllegend(&w, &h, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
                 PL_POSITION_TOP | PL_POSITION_RIGHT | PL_POSITION_INSIDE, 0.02, 0.02, 0.08, COL_BG,
                 COL_FG, 1, 0, 0, (PLINT)nleg, opt, 0.8, 0.8, 2.0, 0, tcol, text, NULL, NULL, NULL,
                 NULL, col, lsty, lw, col, ssc, nsym, sym);
        free(opt), free(col), free(lsty), free(tcol), free(nsym), free(lw), free(ssc);
        free(text), free(sym);
    }
    return RPIV_OK;
}

rpiv_status rpiv_plot_lines(const char *path, const char *title, const char *xlabel,
                            const char *ylabel, const rpiv_plot_series *series, size_t nseries,
                            const rpiv_plot_opts *opts)
{
    rpiv_plot_opts o = opts ? *opts : rpiv_plot_opts_default();
    rpiv_status st = plot_opts_check(&o, path);
    if (st)
        return st;
    plot_resolve_auto(&o, RPIV_PLOT_UP, RPIV_PLOT_FREE);
    if (nseries == 0)
        return rpiv_fail(RPIV_EINVAL, "%s: no series to plot", path);
    double x0 = (double)INFINITY, x1 = -(double)INFINITY, y0 = (double)INFINITY,
           y1 = -(double)INFINITY;
    for (size_t k = 0; k < nseries; k++) {
        size_t good = 0;
        for (size_t q = 0; q < series[k].n; q++) {
            double x = series[k].x[q], y = series[k].y[q];
            if (!isfinite(x) || !isfinite(y))
                continue;
            good++;
            x0 = fmin(x0, x);
            x1 = fmax(x1, x);
            y0 = fmin(y0, y);
            y1 = fmax(y1, y);
        }
        if (!good)
            return rpiv_fail(RPIV_EINVAL, "%s: series %zu (%s) has no finite point", path, k,
                             series[k].label ? series[k].label : "unlabelled");
    }
    /* a little room around the data; degenerate ranges get a unit width */
    double px = x1 > x0 ? 0.02 * (x1 - x0) : fmax(0.5, 0.05 * fabs(x0));
    double py = y1 > y0 ? 0.05 * (y1 - y0) : fmax(0.5, 0.05 * fabs(y0));
    lines_ctx c = {series, nseries, title, xlabel, ylabel, x0 - px, x1 + px, y0 - py, y1 + py};
    if (o.xmin < o.xmax) {
        c.x0 = o.xmin;
        c.x1 = o.xmax;
    }
    if (o.ymin < o.ymax) {
        c.y0 = o.ymin;
        c.y1 = o.ymax;
    }
    return plot_run(path, &o, draw_lines, &c);
}
