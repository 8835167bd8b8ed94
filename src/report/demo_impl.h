/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/report/demo_impl.h - the demo's state, shared by its steps (demo*.c). */
#ifndef RPIV_SRC_DEMO_IMPL_H
#define RPIV_SRC_DEMO_IMPL_H

#include "rpiv/demo.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/optics.h"
#include "rpiv/pairs.h"
#include "rpiv/sheet.h"
#include "rpiv/synth.h"

#include <stddef.h>

typedef struct demo_ctx {
    rpiv_experiment e;  /* the experiment (copied)                              */
    rpiv_demo_params p; /* the parameters, snapshots normalised                 */
    const rpiv_progress *prog;
    const rpiv_demo_log *log;
    size_t done, total;      /* work units                                           */
    char dir[RPIV_PATH_MAX]; /* output folder                                        */
    rpiv_demo_result *res;

    /* 1. optics */
    rpiv_optics_result *trace;          /* traced stations                                      */
    size_t kfig11;                      /* station of x* = 4.455                                 */
    double *mzinf, *mzmax, *mzsup, *me; /* [trace->nx] metrics, NaN where missing       */
    rpiv_optics_selfsim *fit;           /* self-similar fit (NULL if it failed)                 */
    size_t nsweep;                      /* beta1 sweep at x* = 4.455 (fig 11)                    */
    double sweep_beta[8];
    double *sweep_prof;        /* [nsweep * nz] normalised profiles                    */
    rpiv_sheet_params sheet_p; /* the R-PIV sheet the synthesis uses                   */
    rpiv_sheet *sheet;

    /* the image band and the PIV grid (shared by every series) */
    int w, h;
    double spp, x0s, y0s; /* x* per px, x* and y* of the band's left and top edges */
    double bulk_px;
    rpiv_image *mask;          /* 0 outside the fluid rows                             */
    int nx, ny;                /* grid                                                 */
    double gx0, gy0, gdx, gdy; /* grid centres, px                                     */
    double *xs, *ys;           /* [nx], [ny] x*, y* of the grid centres                */
    unsigned char *fluid;      /* [nx*ny] 1 where the vector is not masked             */

    /* 3. P-PIV: planes at zk[1..nz], walls zk[0] = 0 and zk[nz+1] = 1 (U* = 0) */
    size_t nz;
    double *zk;           /* [nz + 2]                                             */
    double *uvol;         /* [(nz + 2) * ny * nx] U* (0 at the walls)             */
    double *plane_e1;     /* [nz] vs the synthetic truth                           */
    rpiv_field *ppiv_mid; /* the plane nearest z* = 0.5 (for the quiver plot)      */
    double zmid;          /* its height                                            */

    /* 4. R-PIV */
    rpiv_field *rfield; /* after all pairs                                      */
    size_t nsnap;
    int snap[RPIV_DEMO_MAX_SNAP];
    rpiv_field *snapf[RPIV_DEMO_MAX_SNAP]; /* ensemble after snap[k] pairs              */
    rpiv_image *sample; /* frame A of the first R-PIV pair (plot)               */

    /* 5. comparisons, per grid column */
    unsigned char *col_ok;         /* [nx] sheet lit over the whole window                  */
    double *czinf, *czmax, *czsup; /* [nx] sheet metrics at the column                   */
    double *e1inf, *e1max, *e1sup; /* [nx] E1 along y*, NaN where not compared           */
    double *ur_mid, *up_mid;       /* [nx] R-PIV and P-PIV(z*_max) U* at y* = 0.5            */
    double *umodel;                /* [nx] CCM prediction at y* = 0.5                      */
    double *usnap_mid;             /* [nsnap * nx] R-PIV U* at y* = 0.5 after snap[k] pairs */
    int icol24;                    /* the fig 24 column                                    */
    size_t ninv;                   /* inversion output                                     */
    double *inv_z, *inv_u, *inv_sd;
    size_t ninvm;
    double *inv_zm, *inv_um; /* the association: measured U* at z*_max                */
    rpiv_field *bfield;      /* the R-PIV field with bias_u, u_corrected, z_ref (sheet bias) */
} demo_ctx;

/* Steps (demo_optics.c, demo_series.c, demo_compare.c, demo_report.c), in this order. Each
 * sets its own message on failure, naming the step. demo_geometry: the image band (before the
 * optics, whose fit covers the band); demo_flow: the duct, the mask and the PIV grid. */
RPIV_NODISCARD rpiv_status demo_geometry(demo_ctx *c);
RPIV_NODISCARD rpiv_status demo_optics(demo_ctx *c);
RPIV_NODISCARD rpiv_status demo_flow(demo_ctx *c);
RPIV_NODISCARD rpiv_status demo_ppiv(demo_ctx *c);
RPIV_NODISCARD rpiv_status demo_rpiv(demo_ctx *c);
RPIV_NODISCARD rpiv_status demo_compare(demo_ctx *c);
RPIV_NODISCARD rpiv_status demo_report(demo_ctx *c);
/* The plots of step 6 (demo_plots.c), before the report. */
RPIV_NODISCARD rpiv_status demo_plots(demo_ctx *c);

/* Helpers (demo.c). */
void demo_note(demo_ctx *c, const char *fmt, ...) RPIV_PRINTF(2, 3);
/* Count n work units done; RPIV_EINTR if the progress callback asks to stop. */
RPIV_NODISCARD rpiv_status demo_tick(demo_ctx *c, size_t n);
/* dir/name into buf (RPIV_EINVAL if too long). */
RPIV_NODISCARD rpiv_status demo_path(const demo_ctx *c, const char *name, char *buf, size_t size);
/* Record a plot file name (relative to dir) in the result. */
void demo_add_plot(demo_ctx *c, const char *name);

/* U* of the P-PIV volume at grid point (i, j), height z (cubic spline across z, natural end
 * conditions, knots zk with the wall zeros). NaN if the point is not fluid. */
double demo_vol_eval(const demo_ctx *c, int i, int j, double z);
/* U* of a field at column i, y* = ystar (linear between rows; NaN if a neighbour is masked or
 * ystar is outside the grid). */
double demo_field_at_y(const demo_ctx *c, const rpiv_field *f, int i, double ystar);

#endif /* RPIV_SRC_DEMO_IMPL_H */
