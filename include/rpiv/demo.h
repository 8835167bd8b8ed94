/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/demo.h - the paper's R-PIV study end to end, on images rpiv makes from an experiment
 * (by default the embedded one), processed like real images, judged against the analytic flow
 * and the cross-correlation model, with a report and plots.
 *
 * The demo composes the other modules' library calls and holds no algorithm of its own:
 *   1. optics   (optics.h)  trace the refracted sheet, profiles and metrics along x*, fit the
 *                           self-similar sheet the synthesis then uses (figs 7, 8, 11);
 *   2. flow     (flow.h)    the square duct at the experiment's Reynolds number;
 *   3. P-PIV    (synth.h, piv.h) a z-scan of thin horizontal Gaussian sheets with the object
 *                           plane on the sheet, each plane processed by sum of correlation, and
 *                           the volume U*(x*, y*, z*) rebuilt by cubic splines across z (fig 23);
 *   4. R-PIV    (synth.h, piv.h) the refracted-sheet pairs with the object plane at z*_OP,
 *                           sum of correlation, snapshots of the ensemble as pairs are added;
 *   5. compare  (field.h, flow.h, ccm.h) R-PIV against P-PIV at z*_inf, z*_max, z*_sup along y*
 *                           at every x* (figs 24, 25); against the CCM's integral prediction at
 *                           y* = 0.5 along x* (fig 26), as pairs are added (fig 27); the
 *                           CCM inversion (bias-corrected U*(z*)) against the truth;
 *   6. report   (plot.h)    DIR/report.md and DIR/report.html, the PNG plots, the key figures.
 * docs/demo.md describes every step, its equivalent CLI commands and a default run's figures.
 *
 * Region of interest: the camera's sensor is 2560 x 2160 px but the channel (0 <= y* <= 1)
 * covers about 480 of its rows. The demo makes and processes only a band of rows centred on
 * the field of view that holds the channel plus margin_px on each side (synth.h: an image size
 * other than the sensor's is a window of the sensor centred on the field of view), and masks
 * the rows outside the fluid.
 *
 * Threads: the demo runs the modules' OpenMP loops (threads from the params, 0 = default);
 * it makes plots (plot.h is not thread-safe), so at most one demo runs in a process at a time.
 * Its numbers do not depend on the thread count. */
#ifndef RPIV_DEMO_H
#define RPIV_DEMO_H

#include "rpiv/config.h"
#include "rpiv/error.h"
#include "rpiv/progress.h"

#include <stddef.h>

#define RPIV_DEMO_MAX_SNAP  24
#define RPIV_DEMO_MAX_PLOTS 32

typedef struct rpiv_demo_params {
    int width_px;       /* image width, px (centred on the field of view); 0 = sensor (0) */
    int margin_px;      /* image rows kept beyond each channel wall, px (32)              */
    int rpiv_pairs;     /* R-PIV pairs N (100)                                            */
    int ppiv_pairs;     /* pairs per P-PIV plane (12)                                     */
    double ppiv_e_star; /* P-PIV sheet thickness at a quarter of the maximum (0.05)       */
    double ppiv_z0;     /* first plane z*_B = z*_OP (0.0625)                              */
    double ppiv_dz;     /* plane step (0.0625)                                            */
    int ppiv_planes;    /* number of planes (15: 0.0625 ... 0.9375)                       */
    double ppiv_slab;   /* P-PIV particles are seeded within z*_B +- ppiv_slab e* (1.5):
                           the rest would get I0 < 1e-6 and not be drawn; this is the same
                           as seeding 1 / (2 ppiv_slab e*) times denser                   */
    double optics_x0;   /* traced stations from x* = optics_x0 (0.5) ...                  */
    double optics_x1;   /* ... to optics_x1 (9) ...                                       */
    double optics_dx;   /* ... every optics_dx (0.25), plus x* = 4.455 (fig 11)            */
    double profile_x;   /* x* of the profile comparison of fig 24 (5; the nearest column) */
    double wall_z;      /* columns with z*_max < wall_z are "near the floor" (0.12)       */
    double core_z;      /* columns with core_z <= z*_max <= z*_OP are "core" (0.2)        */
    size_t nsnap;       /* snapshots of the R-PIV ensemble (fig 27) ...                   */
    int snap[RPIV_DEMO_MAX_SNAP]; /* ... after these numbers of pairs, increasing; values
                              above rpiv_pairs are dropped and rpiv_pairs is always added
                              (1 2 5 10 20 50 100 200 500)                                   */
    int save_images;              /* 1: write the first pair of the R-PIV series and of the P-PIV
                                     plane nearest z* = 0.5 as 16-bit TIFF into DIR/images (1)      */
    double cache_mb;              /* a series whose pairs fit in this many MB (16-bit) is kept in
                                     memory between passes; otherwise each pass synthesises its
                                     pairs again (identical: a pair depends on its index only) (1024) */
    int threads; /* OpenMP threads, 0 = default (0)                                */
} rpiv_demo_params;

/* The default run (a few minutes on 2 cores) and the quick one (--quick: a 512 px wide band,
 * 3 pairs per P-PIV plane, 16 R-PIV pairs; seconds). */
rpiv_demo_params rpiv_demo_params_default(void);
rpiv_demo_params rpiv_demo_params_quick(void);
/* RPIV_EINVAL naming the field and its range. */
RPIV_NODISCARD rpiv_status rpiv_demo_params_check(const rpiv_demo_params *p);

/* Lines describing the run as it goes (a step starting, what it found), for a log. */
typedef struct rpiv_demo_log {
    void (*fn)(void *user, const char *line); /* NULL: none */
    void *user;
} rpiv_demo_log;

/* What a run measured. Every number is computed in the run. E1 values are fractions (Eq.
 * "E1": RMS difference over the mean reference). NaN where a figure could not be computed
 * (e.g. no column in the range). */
#define RPIV_DEMO_BIAS_BANDS 4

typedef struct rpiv_demo_result {
    /* the run */
    double seconds;          /* wall-clock time of the whole run                     */
    double step_seconds[6];  /* of each step                                         */
    int threads;             /* OpenMP threads used                                  */
    int width_px, height_px; /* image band synthesised and processed                 */
    double x0_star, x1_star; /* x* of the band's left and right edges                */
    double y0_star, y1_star; /* y* of its top and bottom edges                       */
    int grid_nx, grid_ny;    /* PIV grid                                             */
    double bulk_px;          /* U_b dt M / pixel: displacement of U* = 1, px         */
    /* 1. optics */
    int sheet_traced;      /* 1: the synthesis used the traced self-similar sheet;
                              0: the configuration's [sheet]                       */
    char sheet_note[256];  /* which sheet, and why                                 */
    double trace_it_ig;    /* power transmitted into the water / incident           */
    double trace_elev_deg; /* elevation of the beam axis in the water               */
    double trace_e_65;     /* traced e* at x* = 6.5 (NaN if no metrics there)       */
    double sheet_incl_deg; /* inclination of z*_max(x*) of the sheet used            */
    double sheet_de_dx;    /* growth of e* along x*, d e* / d x*, of the sheet used */
    double sheet_x_zop;    /* x* where the sheet's z*_max = z*_OP (NaN if none)     */
    /* 2. flow */
    double reynolds;  /* Re of the channel                                    */
    double umax_star; /* U*(0.5, 0.5) of the duct                              */
    /* 3. P-PIV */
    int ppiv_planes, ppiv_pairs;
    double ppiv_e1_mean; /* P-PIV field vs analytic truth, mean over planes       */
    double ppiv_e1_max;  /* ... and the largest                                  */
    double ppiv_e1_mid;  /* ... of the plane nearest z* = 0.5                     */
    double ppiv_e1_z;    /* P-PIV U*(z*) at y* = 0.5 (the planes) vs analytic, E1
                            along z*, mean over the compared columns (cf. fig 19) */
    /* 4. R-PIV */
    int rpiv_pairs;
    double rpiv_replaced; /* fraction of fluid vectors replaced by validation      */
    double rpiv_e1_truth; /* R-PIV field vs analytic U at z*_max(x*) (synth truth) */
    /* 5. comparisons */
    int ncols;                        /* grid columns compared (sheet lit over the window)     */
    double profile_x;                 /* x* of the fig 24 column                               */
    double e1_zinf, e1_zmax, e1_zsup; /* E1 along y*, R-PIV vs P-PIV at z*_inf, z*_max,
                                         z*_sup, mean over the compared columns          */
    double e1_zmax_core;              /* ... at z*_max, columns with core_z <= z*_max <= z*_OP */
    double e1_zmax_wall;              /* ... at z*_max, columns with z*_max < wall_z           */
    double e1_zmax_above;             /* ... at z*_max, columns with z*_max > z*_OP            */
    int ncols_core, ncols_wall, ncols_above;
    double e1_model;      /* E1 along x*, R-PIV vs CCM prediction at y* = 0.5      */
    double e1_model_ppiv; /* E1 along x*, R-PIV vs P-PIV(z*_max) at y* = 0.5       */
    size_t nconv;         /* fig 27: E1 vs CCM after conv_n[k] pairs               */
    int conv_n[RPIV_DEMO_MAX_SNAP];
    double conv_e1[RPIV_DEMO_MAX_SNAP];
    double e1_assoc; /* inversion: the paper's association (U at z*_max) vs truth */
    double e1_corr;  /* inversion: the bias-corrected profile vs truth        */
    /* the per-vector sheet bias (rpiv_ccm_bias_field: duct variation, against z*_max) and the
     * corrected field vs the analytic U at z*_max(x*), over the compared vectors: the whole
     * field and RPIV_DEMO_BIAS_BANDS equal bands of x* */
    double bias_e1_raw, bias_e1_corr;
    int nbias_bands;
    double bias_x0[RPIV_DEMO_BIAS_BANDS], bias_x1[RPIV_DEMO_BIAS_BANDS];
    double bias_raw[RPIV_DEMO_BIAS_BANDS], bias_corr[RPIV_DEMO_BIAS_BANDS]; /* E1 */
    double bias_err[RPIV_DEMO_BIAS_BANDS];  /* mean U*_measured - U*_truth            */
    double bias_mean[RPIV_DEMO_BIAS_BANDS]; /* mean predicted bias, U*                */
    double bias_e[RPIV_DEMO_BIAS_BANDS];    /* mean z*_sup - z*_inf of the band's columns */
    /* the R-PIV ensemble's random uncertainty (sigma_u, --uncertainty) against its error at
     * the compared vectors, in U*: the share within sigma of the raw error and of the error
     * left after the sheet-bias correction, the median sigma and the RMS errors */
    size_t unc_n;
    double unc_cov_raw, unc_cov_corr, unc_med_sigma, unc_rms_raw, unc_rms_corr;
    /* 6. report */
    size_t nplots; /* PNG files written in DIR                             */
    char plots[RPIV_DEMO_MAX_PLOTS][64];
} rpiv_demo_result;

/* Run the study on experiment e with parameters p into folder dir (made if missing, with
 * DIR/data for the tables and fields, DIR/images for the sample pairs): report.md,
 * report.html, the plots, and *out with the figures (out may be NULL). Progress is reported
 * in work units (traces, synthesised pairs, processed pair-passes, model evaluations) from
 * the calling thread; log (may be NULL) gets a line per step. Errors: those of the modules
 * (their message names the step), RPIV_EIO naming a file, RPIV_EINTR if progress asks to
 * stop (the files written so far stay). */
RPIV_NODISCARD rpiv_status rpiv_demo_run(const rpiv_experiment *e, const rpiv_demo_params *p,
                                         const char *dir, const rpiv_progress *prog,
                                         const rpiv_demo_log *log, rpiv_demo_result *out);

#endif /* RPIV_DEMO_H */
