/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/plot.h - PNG figures through PLplot's cairo driver (pngcairo): quiver plots of vector
 * fields, line/point plots with a legend, and scalar maps or images with a colour bar.
 *
 * NOT thread-safe: PLplot keeps global state (its current stream, driver table and error
 * hooks), so make at most one plot at a time in a process, from one thread, and never while
 * other code of the process uses PLplot.
 *
 * Every function writes the PNG atomically (temporary file in the same folder, checked to be
 * a PNG, then renamed over path), returns RPIV_OK, or RPIV_EINVAL (bad argument, named),
 * RPIV_EIO (cannot write path) or RPIV_EFORMAT (PLplot reported an error; its message is
 * passed on). Nothing is printed on stdout or stderr. Text is PLplot text: '#' starts an
 * escape sequence ("#gm" is mu, "#u...#d" superscript), so write '##' for a literal '#'. */
#ifndef RPIV_PLOT_H
#define RPIV_PLOT_H

#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/image.h"

#include <stddef.h>

typedef enum rpiv_plot_cmap {
    RPIV_PLOT_CMAP_VIRIDIS = 0,  /* perceptually uniform, dark blue -> yellow (default) */
    RPIV_PLOT_CMAP_GRAY = 1,     /* black -> white, for camera images                */
    RPIV_PLOT_CMAP_DIVERGING = 2 /* blue -> white -> red, for signed quantities     */
} rpiv_plot_cmap;

enum {
    RPIV_PLOT_AUTO = 0,
    RPIV_PLOT_UP = 1,    /* y_axis */
    RPIV_PLOT_DOWN = 2,  /* y_axis */
    RPIV_PLOT_EQUAL = 1, /* aspect */
    RPIV_PLOT_FREE = 2   /* aspect */
};

/* Options shared by all plots. Start from rpiv_plot_opts_default() and change what you need. */
typedef struct rpiv_plot_opts {
    int width_px, height_px; /* image size (800 x 600)                                     */
    const char *xlabel;      /* axis labels of quiver plots and maps ("x (px)", "y (px)")  */
    const char *ylabel;
    int y_axis; /* RPIV_PLOT_AUTO (0): downward like image rows for quiver
                   plots and maps, upward for line plots; RPIV_PLOT_UP;
                   RPIV_PLOT_DOWN                                              */
    int aspect; /* RPIV_PLOT_AUTO (0): equal for quiver plots and maps (one
                   unit of x as long as one of y), free for line plots;
                   RPIV_PLOT_EQUAL; RPIV_PLOT_FREE                             */
    /* axis limits: used when lo < hi, otherwise the data's range */
    double xmin, xmax, ymin, ymax;
    /* colour scale (maps and quiver backgrounds) */
    rpiv_plot_cmap cmap;
    double zmin, zmax;  /* colour range; automatic (data min/max) unless zmin < zmax  */
    const char *zlabel; /* colour bar label (NULL: none)                               */
    /* quiver */
    int background;     /* 1: colour map of |(u, v)| behind the arrows (1)             */
    double arrow_scale; /* arrow length in axis units per px of displacement; 0: the
                           longest arrow spans one drawn grid step (0)                 */
    int stride;         /* draw every stride-th vector in x and y (1)                  */
} rpiv_plot_opts;

rpiv_plot_opts rpiv_plot_opts_default(void);

/* Arrows (u, v) at the grid points of f, in the field's pixel coordinates; valid vectors in
 * black, replaced ones (RPIV_FLAG_REPLACED) in red, masked ones not drawn. With
 * opts->background, the magnitude of the non-masked vectors is shown as a colour map with a
 * colour bar (label opts->zlabel, default "|u| (px)"). opts may be NULL (defaults). */
RPIV_NODISCARD rpiv_status rpiv_plot_quiver(const rpiv_field *f, const char *path,
                                            const char *title, const rpiv_plot_opts *opts);

/* ---- the figure of a vector field (rpiv plot, rpiv piv --plot) ---------------------------- */

typedef struct rpiv_plot_field_params {
    int width_px, height_px;      /* image size (1000 x 800), 100..10000                       */
    const char *quantity;         /* the colour map: "magnitude" (default), "u", "v",
                                     "peak_ratio", "correlation", any quantity of the field
                                     (rpiv_field_add_quantity), or "none" (no colour map)      */
    int every;                    /* an arrow at every N-th point along x and y; 0: auto, at
                                     most 28 arrows along the longer side (0)                  */
    double arrow_scale;           /* factor on the automatic arrow length, > 0 (1)             */
    const rpiv_image *background; /* image A in grey underneath (NULL: none); the colour
                                map is then drawn half transparent over it                */
} rpiv_plot_field_params;

rpiv_plot_field_params rpiv_plot_field_params_default(void);
/* RPIV_EINVAL unless path ends in .png (any case): "p.jpg: figures are written as PNG only
 * (name it .png)". Every figure function applies it. */
RPIV_NODISCARD rpiv_status rpiv_plot_path_check(const char *path);
/* RPIV_EINVAL naming the bad member; with f (may be NULL), also a quantity f does not have
 * (the message lists those it has). */
RPIV_NODISCARD rpiv_status rpiv_plot_field_params_check(const rpiv_plot_field_params *p,
                                                        const rpiv_field *f);

/* What a field figure shows (for the caller's message and the tests). */
typedef struct rpiv_plot_field_info {
    int every;         /* the arrow stride used                                        */
    double arrow_len;  /* axis units per velocity unit (an arrow's length / its speed) */
    double ref_value;  /* the reference arrow's value, velocity unit (0: no arrows)    */
    double zmin, zmax; /* the colour bar's range, quantity unit                        */
    int physical;      /* 1: mm and m/s (the field has scale and dt), 0: px and px/dt  */
    size_t nvalid, nreplaced, nmasked;
} rpiv_plot_field_info;

/* The figure of f: a colour map of p->quantity (masked points blank; range the 0.5 %..99.5 %
 * quantiles of the unmasked values; a diverging map symmetric about 0 when the range spans
 * 0) with a colour bar labelled with its name and unit; arrows of (u, v) at every p->every
 * point, scaled so that the 95 % quantile of the drawn speeds spans 0.9 arrow step (times
 * p->arrow_scale), valid ones black, replaced ones red, masked points marked by a grey x; a
 * key under the plot with a reference arrow and its value, and the counts of valid,
 * replaced and masked vectors. Axes in px, or mm with u, v in m/s when f has scale and dt;
 * y downward for image coordinates, upward for a y-up field (f->y_up; the background image
 * is flipped to match). title (e.g. the file name) on top. info may be NULL. */
RPIV_NODISCARD rpiv_status rpiv_plot_field(const rpiv_field *f, const char *path, const char *title,
                                           const rpiv_plot_field_params *p,
                                           rpiv_plot_field_info *info);

typedef enum rpiv_plot_style {
    RPIV_PLOT_LINE = 0,   /* a solid line through the points      */
    RPIV_PLOT_POINTS = 1, /* a marker at each point               */
    RPIV_PLOT_BOTH = 2    /* line and markers                     */
} rpiv_plot_style;

/* One curve of a line plot. The arrays are read during the call only. Non-finite points are
 * skipped (and break the line). */
typedef struct rpiv_plot_series {
    const double *x, *y;
    size_t n;
    const char *label; /* legend entry; NULL or "" leaves the series out of the legend */
    rpiv_plot_style style;
} rpiv_plot_series;

/* Curves on common axes, each in its own colour (and marker), with a legend in the top right
 * corner when any series has a label. Axis ranges cover all finite points unless set in opts
 * (opts->xlabel/ylabel are ignored: the labels are arguments here). opts may be NULL.
 * RPIV_EINVAL if nseries is 0 or a series has no finite point at all. */
RPIV_NODISCARD rpiv_status rpiv_plot_lines(const char *path, const char *title, const char *xlabel,
                                           const char *ylabel, const rpiv_plot_series *series,
                                           size_t nseries, const rpiv_plot_opts *opts);

/* A scalar map z[j * nx + i] (row-major, j along y) drawn as cells covering
 * extent = {xmin, xmax, ymin, ymax} (the outer edges: cell (i, j) spans
 * [xmin + i w, xmin + (i+1) w] with w = (xmax - xmin) / nx, likewise in y), with a colour bar
 * labelled opts->zlabel. Large arrays (a camera image) are reduced by block averaging to
 * about the plot's pixel size first. Non-finite cells are left blank and ignored for the
 * automatic colour range. extent NULL means {-0.5, nx - 0.5, -0.5, ny - 0.5} (pixel centres
 * at integers). opts may be NULL. */
RPIV_NODISCARD rpiv_status rpiv_plot_map(const char *path, const char *title, const double *z,
                                         int nx, int ny, const double *extent,
                                         const rpiv_plot_opts *opts);

#endif /* RPIV_PLOT_H */
