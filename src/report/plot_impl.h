/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/report/plot_impl.h - the PLplot frame that plot.c gives the other plot files
 * (plot_field.c): one stream per figure, written atomically, and its drawing helpers. Call
 * them only from inside a draw function run by plot_run (PLplot's stream is open then). */
#ifndef RPIV_SRC_PLOT_IMPL_H
#define RPIV_SRC_PLOT_IMPL_H

#include "rpiv/plot.h"

#include <stddef.h>

/* colour map 0 entries */
enum { COL_BG = 0, COL_FG = 1, COL_SERIES = 2, NSERIES_COL = 10, COL_REPLACED = 12, NCOL0 = 16 };

typedef rpiv_status (*draw_fn)(const void *ctx, const rpiv_plot_opts *o);

/* RPIV_EINVAL naming path for options out of range. */
RPIV_NODISCARD rpiv_status plot_opts_check(const rpiv_plot_opts *o, const char *path);
/* Replace RPIV_PLOT_AUTO by what suits the kind of plot. */
void plot_resolve_auto(rpiv_plot_opts *o, int y_axis, int aspect);
/* Colour map 1 (the continuous one) as cm, with opacity alpha (0..1). */
void plot_set_cmap1(rpiv_plot_cmap cm, double alpha);
/* Open a pngcairo stream of o's size on a temporary file next to path, run draw(ctx, o),
 * close, check the PNG is whole, publish it at path. */
RPIV_NODISCARD rpiv_status plot_run(const char *path, const rpiv_plot_opts *o, draw_fn draw,
                                    const void *ctx);
/* The viewport (room for a colour bar on the right when cbar), world window, box and labels. */
void plot_frame(const rpiv_plot_opts *o, double x0, double x1, double y0, double y1, int cbar,
                const char *xl, const char *yl, const char *title);
/* A colour bar of colour map 1 over zmin..zmax right of the viewport. */
void plot_colour_bar(double zmin, double zmax, const char *label);
/* o's colour range, else the finite range of z[0..n-1] (widened when flat). */
void plot_zrange(const double *z, size_t n, const rpiv_plot_opts *o, double *lo, double *hi);
/* z (nx x ny, row-major) as cells of colour map 1 over [x0,x1] x [y0,y1], block-averaged to
 * at most max_x x max_y cells; non-finite cells blank. */
RPIV_NODISCARD rpiv_status plot_draw_cells(const double *z, int nx, int ny, double x0, double x1,
                                           double y0, double y1, double zlo, double zhi, int max_x,
                                           int max_y);

#endif /* RPIV_SRC_PLOT_IMPL_H */
