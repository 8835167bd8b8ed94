/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/sheet.h - the illumination I0(x*, z*) of the light sheet, its profile files and metrics.
 *
 * Kinds:
 *  - GAUSS: P-PIV sheet, I0 = exp(-4 ln4 (z* - z*_B)^2 / e*^2), so that I0 = 0.25 at
 *    z*_B +- e* / 2 (the paper's thickness e* is the width at a quarter of the maximum);
 *  - SELFSIM: the R-PIV sheet, self-similar along x*: I0 = S((z* - z*_max(x*)) / e*(x*)), with
 *    e*(x*) = e0 + e1 x*, z*_max(x*) = zm0 + zm1 x*, and a shape S with S(0) = 1 = max S given
 *    either as a table (profile file) or by the default skewed shape (two half-Gaussians whose
 *    quarter-height half-widths are skew/(1+skew) (below the peak) and 1/(1+skew) (above),
 *    so that the width at 0.25 is e*);
 *  - UNIFORM: I0 = 1 everywhere (volume illumination).
 * Outside the channel (z* < 0 or z* > 1) I0 = 0. */
#ifndef RPIV_SHEET_H
#define RPIV_SHEET_H

#include "rpiv/error.h"

#include <stddef.h>

typedef enum rpiv_sheet_kind {
    RPIV_SHEET_GAUSS = 0,
    RPIV_SHEET_SELFSIM = 1,
    RPIV_SHEET_UNIFORM = 2
} rpiv_sheet_kind;

/* The kinds' names in enum order (NULL-terminated): "gauss", "selfsim", "uniform". */
extern const char *const rpiv_sheet_kind_names[];

#define RPIV_PATH_MAX 512

typedef struct rpiv_sheet_params {
    rpiv_sheet_kind kind;
    double zb_star;  /* GAUSS: centre z*_B (0.5)                                   */
    double e_star;   /* GAUSS: thickness at 0.25 max (0.05)                        */
    double e0, e1;   /* SELFSIM: e*(x*) = e0 + e1 x* (0, 0.0646: e* = 0.42 at x* = 6.5) */
    double zm0, zm1; /* SELFSIM: z*_max(x*) = zm0 + zm1 x* (0, 0.0794: 0.5 at x* = 6.3) */
    double skew;     /* SELFSIM default shape: lower/upper half-width ratio (2)      */
    char profile[RPIV_PATH_MAX]; /* SELFSIM: shape table file ("" = default shape)   */
} rpiv_sheet_params;

rpiv_sheet_params rpiv_sheet_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_sheet_params_check(const rpiv_sheet_params *p);

/* A ready-to-evaluate sheet (tables loaded). Read-only once made: thread-safe to evaluate. */
typedef struct rpiv_sheet rpiv_sheet;
RPIV_NODISCARD rpiv_status rpiv_sheet_new(const rpiv_sheet_params *p, rpiv_sheet **out);
void rpiv_sheet_free(rpiv_sheet *s);

/* The sheet coordinate z+ = (z* - z*_max) / e*: the height above the sheet's maximum in units
 * of its thickness, the abscissa of a self-similar shape (SELFSIM, profile files). For the
 * SELFSIM lines, z*_max = zm0 + zm1 x* and e* = e0 + e1 x*. No check: e = 0 gives +-inf or NaN.
 * The one place this coordinate is computed. */
double rpiv_sheet_zplus(double zstar, double zmax, double e);

/* The sheet's inclination in degrees, from the slope of its z*_max line against x*. */
double rpiv_sheet_incl_deg(double slope);

/* I0(x*, z*) normalised so that the maximum over z* at any x* is 1. */
double rpiv_sheet_eval(const rpiv_sheet *s, double xstar, double zstar);

/* Profile file (text): header lines "# rpiv-sheet 1", "# e0 E0", "# e1 E1", "# zm0 Z0",
 * "# zm1 Z1", then rows "zplus I" with zplus = (z* - z*_max)/e* increasing and I in [0, 1],
 * at least 3 rows. The shape is interpolated linearly and is 0 outside the table. */
RPIV_NODISCARD rpiv_status rpiv_sheet_save_profile(const char *path, double e0, double e1,
                                                   double zm0, double zm1, const double *zplus,
                                                   const double *inten, size_t n);

/* Metrics of a sampled profile I(z*) (z increasing, n >= 3): z*_max (argmax, refined by
 * parabola), z*_inf and z*_sup where I crosses 0.25 max below and above it (linear
 * interpolation), e* = z_sup - z_inf. RPIV_ENUMERIC if a crossing is missing. */
typedef struct rpiv_sheet_metrics {
    double zmax, zinf, zsup, e;
    double imax;
} rpiv_sheet_metrics;
RPIV_NODISCARD rpiv_status rpiv_sheet_metrics_of(const double *z, const double *inten, size_t n,
                                                 rpiv_sheet_metrics *m);

#endif /* RPIV_SHEET_H */
