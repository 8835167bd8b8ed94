/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/ccm.h - the cross-correlation model (CCM) of the paper: the displacement component R_D
 * of the correlation as a sum of Gaussians, one per particle (Eq. "CCM_gen", Eq. "CCM_simp"),
 * its statistical (integral) form (Eq. "statform"), the Monte-Carlo sum of correlation, the
 * paper's P-PIV and R-PIV scenarios, and the inverse problem: undo the R-PIV bias.
 *
 * Units and conventions (docs/ccm.md):
 *  - heights z* are normalised by the channel height h; the defocus distance is
 *    z' = h |z* - z*_OP| in metres (imaging.h);
 *  - correlation shifts (dx, dy) and image displacements (DX, DY) are in sensor pixels;
 *  - velocities U*, V* are normalised by the bulk velocity U_b; a velocity becomes a
 *    displacement through scale_px = U_b dt M / pixel: DX = U* scale_px (rpiv_ccm_scale_px);
 *  - correlation values are relative: 1 is the R_D peak of one in-focus particle of the
 *    model's diameter with I0 = 1 in both frames (the constant factor drops out of every peak).
 *
 * Threads: every function is reentrant. A rpiv_ccm_work is used by one thread at a time;
 * the model's callbacks must be safe to call concurrently (all of those in this header are). */
#ifndef RPIV_CCM_H
#define RPIV_CCM_H

#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/flow.h"
#include "rpiv/imaging.h"
#include "rpiv/piv.h"
#include "rpiv/progress.h"
#include "rpiv/sheet.h"

#include <stddef.h>

/* ---- numerical parameters ---------------------------------------------------------------- */

typedef struct rpiv_ccm_params {
    double epsrel;          /* relative tolerance of the adaptive quadrature (1e-9)             */
    size_t limit;           /* subintervals of the adaptive quadrature (1000)                   */
    size_t gl_points;       /* Gauss-Legendre points per subinterval of a cached rule (20)      */
    double max_width;       /* longest subinterval of a cached rule, z* (1/64)                  */
    size_t scan;            /* samples of I0 and P over [zlo, zhi] to find their features (4001) */
    double xtol_px;         /* Brent's bracket tolerance, px (1e-7); a Newton polish follows    */
    int max_iter;           /* iterations of the peak minimiser (500)                           */
    int max_range_px;       /* widest integer-sampled correlation plane per axis, px (4096)     */
    rpiv_subpixel subpixel; /* sub-pixel estimator on the sampled plane; auto: the engine's
                               for a sum of correlation, spline (auto)                      */
    size_t utab;            /* runs over many windows (scenarios, Monte-Carlo) tabulate U*, V*
                               on this many nodes of [zlo, zhi] (Akima spline; 3e-11 for the
                               duct); 0 = evaluate the profile every time (4097)               */
} rpiv_ccm_params;

rpiv_ccm_params rpiv_ccm_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_ccm_params_check(const rpiv_ccm_params *p);

/* ---- the correlation as a sum of Gaussians ------------------------------------------------ */

/* One term amp * exp(-c ((dx - DX)^2 + (dy - DY)^2)) of R_D; with box = b > 0 the same
 * Gaussian convolved along each axis with the triangle (b - |t|)/b^2 (the autocorrelation of
 * a pixel's box of side b: pixel-integrated images), same volume (docs/ccm.md). */
typedef struct rpiv_ccm_gauss {
    double amp; /* peak value of the Gaussian (relative, see above) */
    double c;   /* 4 beta^2 / (d_e1^2 + d_e2^2), 1/px^2              */
    double dx;  /* displacement DX of the particle image, px        */
    double dy;  /* displacement DY, px                               */
    double box; /* side of the pixels' box, px; 0: the Gaussian     */
} rpiv_ccm_gauss;

/* A growable list of terms. Owned by the caller: rpiv_ccm_corr_new / rpiv_ccm_corr_free. */
typedef struct rpiv_ccm_corr {
    size_t n, cap;
    rpiv_ccm_gauss *g;
} rpiv_ccm_corr;

RPIV_NODISCARD rpiv_status rpiv_ccm_corr_new(size_t cap, rpiv_ccm_corr **out);
void rpiv_ccm_corr_free(rpiv_ccm_corr *c); /* NULL is a no-op */
/* Append one term (grows the list; RPIV_ENOMEM). */
RPIV_NODISCARD rpiv_status rpiv_ccm_corr_add(rpiv_ccm_corr *c, rpiv_ccm_gauss g);
/* R(dx, dy) = sum of the terms, summed in list order. */
double rpiv_ccm_corr_eval(const rpiv_ccm_corr *c, double dx, double dy);

/* The measured displacement: the location of the correlation peak. */
typedef struct rpiv_ccm_peak {
    double dx, dy;         /* continuous maximum of R (GSL minimiser on -R), px           */
    double dx_sub, dy_sub; /* the PIV sub-pixel estimator on R sampled at integer shifts  */
    int mx, my;            /* integer shift of the sampled maximum                       */
    double value;          /* R at the continuous maximum                                */
} rpiv_ccm_peak;

/* Find the peak of c: sample R on the integer plane spanning the terms' displacements (plus
 * one pixel), take the sampled maximum, apply the sub-pixel estimator p->subpixel there (as the
 * engine does on an ensemble's sum: rpiv_subpixel_resolve(p->subpixel, 1)), and
 * refine to the continuous maximum: Brent's method (gsl_min_fminimizer_brent) bracketed by
 * the neighbouring samples when all terms share one DY (or one DX; the maximum is then exactly
 * on that line), the Nelder-Mead simplex (gsl_multimin) otherwise. Errors: RPIV_ENUMERIC when
 * R is zero everywhere (no illuminated particle) or the minimiser fails, RPIV_ELIMIT when the
 * plane would exceed p->max_range_px. */
RPIV_NODISCARD rpiv_status rpiv_ccm_corr_peak(const rpiv_ccm_corr *c, const rpiv_ccm_params *p,
                                              rpiv_ccm_peak *out);

/* The same peak with the sub-pixel estimate (dx_sub, dy_sub) of the engine's plane for a
 * win_w x win_h top-hat window (docs/ccm.md, "The engine's window"): every term weighted by the
 * share of its pairs that stay inside the window, (1 - |DX - px|/W)+ (1 - |DY - py|/H)+ for
 * residual shifts about the predictor (px, py); the whole plane lowered by the mean removal's
 * constant baseline -V/(W H), V = sum amp pi / c of the weighted terms (the circular plane of
 * mean-removed windows sums to zero); with deform = 1 the plane sampled at integer shifts about
 * the predictor (the deformed frames' residual shifts), with 0 at integer shifts (whole-pixel
 * window offsets); with deform = 2 (opt-in, [bias] window_interp) the deformed pass's plane
 * through the cubic-spline interpolation kernel of its frames' sampling offsets, its pairs lost
 * per shift of the plane (docs/ccm.md, "The planes' skew"). The predictor starts at the infinite
 * window's estimate and is the estimate itself at convergence (the passes repeated to 1e-5 px;
 * passes that alternate between two estimates: the 20th pass's; with deform = 2 after 8
 * passes the predictor moves by 1/2, 1/3, ... of each pass's change, at most 40 passes). This
 * entry point models a noise-free plane (rpiv_ccm_model.window_pairs = 0). dx, dy, value, mx, my:
 * the infinite window's, as rpiv_ccm_corr_peak. win_w = win_h = 0: rpiv_ccm_corr_peak. RPIV_EINVAL
 * for a window outside 4..4096 px. */
RPIV_NODISCARD rpiv_status rpiv_ccm_corr_peak_window(const rpiv_ccm_corr *c,
                                                     const rpiv_ccm_params *p, int win_w, int win_h,
                                                     int deform, rpiv_ccm_peak *out);

/* ---- inputs of the model ------------------------------------------------------------------ */

/* A function of the height z*; user is passed back unchanged. */
typedef double (*rpiv_ccm_fn)(const void *user, double zstar);
typedef struct rpiv_ccm_func {
    rpiv_ccm_fn fn;
    const void *user;
} rpiv_ccm_func;

#define RPIV_CCM_MAX_BREAKS 16

/* Everything the paper's model needs for one interrogation window (its list of inputs):
 * the illumination I0(z*), the receiving optics, the velocity profile, the particle diameter,
 * and the presence law P(z*) of the statistical form. Plain data: the callbacks' user data
 * are not owned. */
typedef struct rpiv_ccm_model {
    rpiv_camera camera;     /* f, M, s0, z*_OP, f#, lambda_p, beta^2, pixel pitch           */
    double h_m;             /* channel height h, m (for z' = h |z* - z*_OP|)                 */
    double dp_m;            /* particle diameter d_p, m                                      */
    double scale_px;        /* px of displacement per unit U*: U_b dt M / pixel              */
    rpiv_ccm_func illum;    /* I0(z*) >= 0                                                   */
    rpiv_ccm_func u;        /* U*(z*)                                                        */
    rpiv_ccm_func v;        /* V*(z*); fn NULL: 0                                            */
    rpiv_ccm_func presence; /* P(z*) >= 0, any normalisation; fn NULL: uniform               */
    double zlo, zhi;        /* heights the particles occupy (0, 1)                           */
    double breaks[RPIV_CCM_MAX_BREAKS]; /* known kinks or narrow peaks of I0 or P (a thin  */
    size_t nbreaks;                     /* sheet's centre), where quadrature intervals split */
    double pixel_box;       /* side of the square each pixel integrates the image over, px: 1 (a
                             * full-fill sensor, as rpiv synth renders), 0 (point samples: the
                             * paper's continuous images); every term is convolved with the box's
                             * autocorrelation, per axis the triangle of half-width pixel_box, at
                             * constant volume (rpiv_ccm_gauss.box; docs/ccm.md, "Pixel
                             * integration") */
    int window_w, window_h; /* the engine's interrogation window, px, for the prediction of
                             * what the engine measures (rpiv_ccm_peak.dx_sub; 4..4096 each):
                             * rpiv_ccm_corr_peak_window; 0 (both): an infinite window, the
                             * paper's. The continuous peak (dx, dy) never depends on it */
    int window_deform;      /* 1: the engine deforms its final pass by the predictor (the
                             * plane is sampled about it), 0: whole-pixel window offsets;
                             * 2: deformed, the plane through the deformation's cubic-spline
                             * interpolation kernel, its pairs lost per shift of the plane
                             * ([bias] window_interp; docs/ccm.md, "The planes' skew") */
    double window_pairs;    /* with window_deform = 2: the ensemble's pairs N whose noise the
                             * plane's samples carry (the random pairs': sigma^2 = |baseline| /
                             * (2 N) of the peak), so that the estimator's path (7 x 7, 5 x 5,
                             * 3-point) is weighted by its probability ([bias] window_pairs;
                             * docs/ccm.md, "Session 10"); 0: the expected plane's own path,
                             * noise-free */
} rpiv_ccm_model;

/* The paper's channel defaults: the camera of imaging.h, h = 8 mm, d_p = 10 um, scale_px of
 * dt = 1 ms at Re = 465 (3.50 px per U_b), I0 = 1 (volume illumination), U* = the duct at
 * y* = 0.5, uniform P on [0, 1], pixel_box = 1 (pixel-integrated images). */
rpiv_ccm_model rpiv_ccm_model_default(void);
RPIV_NODISCARD rpiv_status rpiv_ccm_model_check(const rpiv_ccm_model *m);

/* Displacement scale U_b dt M / pixel, px per unit U*. */
double rpiv_ccm_scale_px(const rpiv_camera *cam, const rpiv_channel *ch, double dt_s);

/* Callbacks. rpiv_ccm_duct_fn: U*(y*, z*) of the square duct at y* = *(const double *)user
 * (NULL: y* = 0.5). rpiv_ccm_const_fn: *(const double *)user. rpiv_ccm_sheet_fn: the sheet
 * at one section, user = const rpiv_ccm_sheet_at *. */
double rpiv_ccm_duct_fn(const void *user, double zstar);
double rpiv_ccm_const_fn(const void *user, double zstar);
typedef struct rpiv_ccm_sheet_at {
    const rpiv_sheet *sheet;
    double xstar;
} rpiv_ccm_sheet_at;
double rpiv_ccm_sheet_fn(const void *user, double zstar);

/* Height z*_max(x*) of the sheet's maximum at section x* (sampled on p->scan points of [0, 1],
 * refined by Brent's method). RPIV_ENUMERIC if the sheet is zero there. */
RPIV_NODISCARD rpiv_status rpiv_ccm_sheet_zmax(const rpiv_sheet *s, double xstar,
                                               const rpiv_ccm_params *p, double *zmax);
/* The section x* in [xlo, xhi] where z*_max(x*) = target (Brent root finder); RPIV_EINVAL if
 * z*_max - target does not change sign over [xlo, xhi]. */
RPIV_NODISCARD rpiv_status rpiv_ccm_sheet_x_of_zmax(const rpiv_sheet *s, double target, double xlo,
                                                    double xhi, const rpiv_ccm_params *p,
                                                    double *xstar);

/* A tabulated curve y(x) (x increasing, linear interpolation, 0 outside [x0, x_{n-1}]), with
 * an optional third column w (e.g. the uncertainty of a measured profile; NULL if absent). */
typedef struct rpiv_ccm_curve {
    size_t n;
    double *x, *y, *w;
    void *interp; /* the linear interpolation (a gsl_interp), built by _new and _load */
} rpiv_ccm_curve;
RPIV_NODISCARD rpiv_status rpiv_ccm_curve_new(const double *x, const double *y, size_t n,
                                              rpiv_ccm_curve **out);
/* Text file: '#' comments, rows "x y [w]" (w on every row or none), x increasing, n >= 2.
 * Errors: RPIV_EIO (open), RPIV_EFORMAT naming file:line. */
RPIV_NODISCARD rpiv_status rpiv_ccm_curve_load(const char *path, rpiv_ccm_curve **out);
void rpiv_ccm_curve_free(rpiv_ccm_curve *c);
double rpiv_ccm_curve_eval(const rpiv_ccm_curve *c, double x);
double rpiv_ccm_curve_fn(const void *user, double x); /* user = const rpiv_ccm_curve * */

/* Where an image sits in the channel: x* = x0_star + (x + 0.5) star_per_px for the pixel
 * column x (centres at integers), likewise y* (rpiv_synth_get_info gives these). */
typedef struct rpiv_ccm_geometry {
    double x0_star, y0_star; /* x*, y* of the image's left and top edges */
    double star_per_px;      /* pixel / (M h)                             */
} rpiv_ccm_geometry;

/* The streamwise profile along x* of a vector field (rpiv piv output) at the grid row nearest
 * y* = ystar: (x*, U* = u / scale_px) of the valid vectors, as a curve. RPIV_EINVAL if ystar
 * is more than one grid step outside the field, RPIV_ENUMERIC if that row has fewer than 3
 * valid vectors. */
RPIV_NODISCARD rpiv_status rpiv_ccm_profile_of_field(const rpiv_field *f,
                                                     const rpiv_ccm_geometry *g, double scale_px,
                                                     double ystar, rpiv_ccm_curve **out);

/* ---- Eq. "CCM_gen" and Eq. "CCM_simp" ---------------------------------------------------- */

/* One particle of Eq. "CCM_gen": its own height and illumination in each frame. */
typedef struct rpiv_ccm_particle {
    double z1, z2; /* heights z* in frames 1 and 2                     */
    double i1, i2; /* incident intensities I0 in frames 1 and 2         */
    double dp_m;   /* geometric diameter, m                             */
    double dx, dy; /* displacement mu2 - mu1 of its image, px           */
} rpiv_ccm_particle;

/* Append one term per particle (Eq. "CCM_gen"): the exact correlation of the two images of
 * Eq. "int", amplitude Ip1 Ip2 D_a^4 beta^2 / (64 pi (d_e1^2 + d_e2^2)(s0+z1')^2(s0+z2')^2)
 * (the paper's Eq. "CCM_gen" times the constant D_a^2 / 4, see docs/ccm.md), relative to the
 * model's reference particle. Only m->camera, h_m and dp_m are used. */
RPIV_NODISCARD rpiv_status rpiv_ccm_gen(const rpiv_ccm_model *m, const rpiv_ccm_particle *pt,
                                        size_t n, rpiv_ccm_corr *out);

/* Eq. "CCM_simp" (the three hypotheses: I0 depends on z* only, the same in both frames, W = 0):
 * append one term per height z[i] with I0, d_e, DX = U* scale_px and DY = V* scale_px from the
 * model, each amplitude multiplied by weight. */
RPIV_NODISCARD rpiv_status rpiv_ccm_simp(const rpiv_ccm_model *m, const double *z, size_t n,
                                         double weight, rpiv_ccm_corr *out);

/* ---- Eq. "statform" ---------------------------------------------------------------------- */

/* Scratch space for the integral form (GSL integration workspace, Gauss-Legendre table, the
 * cached rule), made for one set of numerical parameters, which the functions taking a work
 * use. One per thread. */
typedef struct rpiv_ccm_work rpiv_ccm_work;
RPIV_NODISCARD rpiv_status rpiv_ccm_work_new(const rpiv_ccm_params *p, rpiv_ccm_work **out);
void rpiv_ccm_work_free(rpiv_ccm_work *w);

/* <R_D>(dx, dy) = int P(z) R_Dz(z) dz over [zlo, zhi] by adaptive quadrature
 * (gsl_integration_qagp split at z*_OP, the model's breaks and the features of I0 and P), with
 * P normalised to unit integral. The reference evaluation; RPIV_ENUMERIC if GSL fails. */
RPIV_NODISCARD rpiv_status rpiv_ccm_stat_eval(const rpiv_ccm_model *m, rpiv_ccm_work *w, double dx,
                                              double dy, double *value);

/* The integral as a cached quadrature rule: the subintervals chosen by gsl_integration_qagp on
 * the integrand at the sampled correlation peak (after a first pass on the amplitude alone),
 * each split to p->max_width and carrying p->gl_points Gauss-Legendre nodes; every node is one
 * Gaussian term. *out is cleared and refilled. */
RPIV_NODISCARD rpiv_status rpiv_ccm_stat_corr(const rpiv_ccm_model *m, rpiv_ccm_work *w,
                                              rpiv_ccm_corr *out);

/* The same rule built from the amplitude alone (P I0^2 / d_e^2 ...), so that its nodes do not
 * depend on the velocity profile (used by the inverse problem). */
RPIV_NODISCARD rpiv_status rpiv_ccm_stat_corr_fixed(const rpiv_ccm_model *m, rpiv_ccm_work *w,
                                                    rpiv_ccm_corr *out);

/* The measured displacement predicted by Eq. "statform": the peak of <R_D> (with the model's
 * window: rpiv_ccm_corr_peak_window). */
RPIV_NODISCARD rpiv_status rpiv_ccm_predict(const rpiv_ccm_model *m, rpiv_ccm_work *w,
                                            rpiv_ccm_peak *out);

/* How the engine's deformation follows the flow across a window (rpiv_ccm_predict_area). */
typedef struct rpiv_ccm_area_opts {
    int quadratic; /* 1: the deformation follows the field's quadratic variation across the
                      window (the engine's predictor, the cubic B-spline through its vectors,
                      reproduces quadratics); 0: only its linear part (the least-squares plane,
                      the model before issue 15's session 7)                                  */
    int nx, ny;    /* the engine's grid of vectors (0: an unbounded grid, the window interior)  */
    int i, j;      /* the window's place in it (0 <= i < nx, 0 <= j < ny)                       */
    double step_x, step_y; /* its spacing, px (> 0 with a grid)                                 */
    const double *def_u, *def_v; /* NULL, or the deformation's variation at each sub-position
                                    (px, less its value at the window's centre) when it is known
                                    (the engine's own predictor): used instead of the fit     */
} rpiv_ccm_area_opts;
rpiv_ccm_area_opts rpiv_ccm_area_opts_default(void); /* quadratic 1, no grid, no def_u/v */

/* What the engine measures over a window across which the flow varies (the window's area
 * average, docs/ccm.md, "The engine's window"): models[k] is the model at the k-th of n
 * sub-positions of equal area (offsets ox, oy from the window's centre, px; >= 3, not
 * collinear; >= 6 and not on one conic for o->quadratic), every one with the same window. The
 * deformation follows the field as the engine's predictor does (o; NULL: the defaults): the
 * least-squares plane (o->quadratic = 0) or quadratic through what the engine measures at each
 * sub-position (rpiv_ccm_predict's dx_sub, dy_sub). With a grid (o->nx > 0) the deformation
 * there is the engine's own predictor (rpiv_deform_pred: the cubic B-spline through that fit's
 * values at the grid's vectors within 8 steps, continued beyond the grid's edges by the
 * engine's ghost vectors, 2 g_0 - g_k), which departs from the fit near the images' border;
 * without one, the fit itself. Every sub-position's correlation, amplitude / n, is moved by
 * minus that deformation at it less its value at the window's centre, and the sum's peak is taken
 * as rpiv_ccm_corr_peak_window. out->dx_sub, dy_sub: the prediction; out->dx, dy: the continuous
 * maximum of the averaged correlation (the centre's ideal is rpiv_ccm_predict of the centre's
 * model). Uses w's rule (w->corr is left with the last sub-position's). */
RPIV_NODISCARD rpiv_status rpiv_ccm_predict_area(const rpiv_ccm_model *models, const double *ox,
                                                 const double *oy, size_t n,
                                                 const rpiv_ccm_area_opts *o, rpiv_ccm_work *w,
                                                 rpiv_ccm_peak *out);

/* ---- Monte-Carlo sum of correlation ------------------------------------------------------ */

typedef struct rpiv_ccm_mc_params {
    size_t nparticles;  /* N particles per window and pair (15)                          */
    size_t repeats;     /* R independent repetitions (20)                                */
    size_t nnim;        /* number of N_im values                                         */
    size_t nim[64];     /* N_im values, increasing, >= 1 (1 2 3 5 7 10 ... 500)            */
    unsigned long seed; /* repetition r draws from the stream (seed, r) (1)              */
    int threads;        /* OpenMP threads over repetitions; 0 = default (0)              */
} rpiv_ccm_mc_params;

rpiv_ccm_mc_params rpiv_ccm_mc_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_ccm_mc_params_check(const rpiv_ccm_mc_params *p);

typedef struct rpiv_ccm_mc_result {
    size_t nnim, repeats;
    size_t *nim;                /* [nnim]                                                */
    double *dx, *dx_sub;        /* [repeats * nnim]: peak of the sum over the first nim[k] pairs */
    double *mean, *std;         /* [nnim] over the repetitions (std with R - 1), px       */
    double *mean_sub, *std_sub; /* the same for the sub-pixel estimator                  */
} rpiv_ccm_mc_result;

/* Each repetition draws N_im_max pairs of N particles at heights drawn from P(z) (inverse of
 * its tabulated CDF), sums their Eq. "CCM_simp" correlations pair after pair, and records the
 * peak after nim[k] pairs. Results do not depend on the thread count. *out owns the arrays:
 * rpiv_ccm_mc_free. RPIV_EINTR if progress asks to stop. */
RPIV_NODISCARD rpiv_status rpiv_ccm_mc_run(const rpiv_ccm_model *m, const rpiv_ccm_params *p,
                                           const rpiv_ccm_mc_params *mc,
                                           const rpiv_progress *progress, rpiv_ccm_mc_result **out);
void rpiv_ccm_mc_free(rpiv_ccm_mc_result *r);

/* Write a Monte-Carlo result as text: "# rpiv-ccm-mc 1", header lines hdr (may be NULL), the
 * integral's peak (dx_int, dx_sub_int, px; NAN if not computed), then rows
 * "N_im mean std mean_sub std_sub" in U* (px / scale_px). Atomic; RPIV_EIO. */
RPIV_NODISCARD rpiv_status rpiv_ccm_mc_save(const rpiv_ccm_mc_result *r, double scale_px,
                                            double dx_int, double dx_sub_int, const char *hdr,
                                            const char *path);

/* ---- the paper's scenarios --------------------------------------------------------------- */

typedef enum rpiv_ccm_kind {
    RPIV_CCM_PPIV_SCAN = 0,  /* Gaussian sheet at z*_B, object plane z*_OP = z*_B          */
    RPIV_CCM_PPIV_FIXED = 1, /* Gaussian sheet at z*_B, object plane fixed at zop          */
    RPIV_CCM_RPIV = 2        /* the inclined sheet at the x* where z*_max(x*) = z*, fixed zop */
} rpiv_ccm_kind;

typedef struct rpiv_ccm_scenario {
    rpiv_ccm_kind kind;
    double e_star;   /* P-PIV sheet thickness at a quarter of the maximum (0.05)            */
    double zop_star; /* fixed object plane (PPIV_FIXED, RPIV) (0.5)                          */
    double z0, z1;   /* positions z*_B (P-PIV) or z*_max (R-PIV) from z0 to z1 (0.0625, 0.9375) */
    size_t n;        /* number of positions (15)                                             */
    int symmetric;   /* RPIV: mirror the rows to z* -> 1 - z* (the paper's extension) (1)    */
    double xlo, xhi; /* RPIV: bracket of the x* search (0.01, 100)                           */
} rpiv_ccm_scenario;

/* Defaults of each kind: the paper's values (RPIV: z*_max from 0.03125 to 0.5, 16 positions). */
rpiv_ccm_scenario rpiv_ccm_scenario_default(rpiv_ccm_kind kind);
RPIV_NODISCARD rpiv_status rpiv_ccm_scenario_check(const rpiv_ccm_scenario *s);

typedef struct rpiv_ccm_row {
    double xstar, zstar; /* section (R-PIV) and the height the velocity is associated with   */
    double uref;         /* U*_ref(z*)                                                        */
    double umodel;       /* U*_model: continuous peak / scale_px                              */
    double usub;         /* the sub-pixel estimator's peak / scale_px                         */
    double err, err_sub; /* pointwise relative errors (U_model - U_ref) / U_ref                */
    int mirrored;        /* 1: a row made by the symmetric extension                          */
} rpiv_ccm_row;

typedef struct rpiv_ccm_table {
    size_t n;
    rpiv_ccm_row *row;         /* increasing z*                                                  */
    double e1, e1_sub;         /* Eq. "E1" over the rows (trapezoid in z*)                       */
    double maxerr, maxerr_sub; /* max |pointwise relative error|                            */
} rpiv_ccm_table;

/* Run a scenario. base gives the camera (its zop is replaced), h, d_p, scale_px, U*, P; the
 * illumination is the Gaussian sheet of e_star (P-PIV) or sheet (R-PIV, ignored otherwise).
 * OpenMP over positions; deterministic. *out: rpiv_ccm_table_free. */
RPIV_NODISCARD rpiv_status rpiv_ccm_scenario_run(const rpiv_ccm_scenario *s,
                                                 const rpiv_ccm_model *base,
                                                 const rpiv_sheet *sheet, const rpiv_ccm_params *p,
                                                 int threads, const rpiv_progress *progress,
                                                 rpiv_ccm_table **out);
void rpiv_ccm_table_free(rpiv_ccm_table *t);
/* The row of t with the largest |err| (the first of equals, within 1e-12). */
size_t rpiv_ccm_table_worst(const rpiv_ccm_table *t);

/* Write a table as text ("# rpiv-ccm 1" header, header lines from hdr (may be NULL), E1 and
 * max errors, then columns x* z* U_ref U_model U_sub err err_sub mirrored). Atomic. */
RPIV_NODISCARD rpiv_status rpiv_ccm_table_save(const rpiv_ccm_table *t, const char *hdr,
                                               const char *path);

/* ---- beyond the paper: the inverse problem ----------------------------------------------- */

typedef struct rpiv_ccm_invert_params {
    size_t ncoef;    /* cubic B-spline coefficients over [0, 1], the end ones 0 (U = 0 at the
                        walls) (16)                                                          */
    double lambda;   /* weight of the second-difference penalty on the coefficients (1e-4)   */
    int symmetric;   /* 1: U(z*) = U(1 - z*) (0)                                             */
    double sigma;    /* measurement standard deviation in U* (sbar if usigma is given);
                        0 = sbar of usigma, else estimated from the fit (0)                  */
    size_t max_iter; /* Levenberg-Marquardt iterations (100)                                 */
    double xtol;     /* gsl_multifit_nlinear_driver tolerances (1e-10, 1e-10, 1e-12)         */
    double gtol;
    double ftol;
    size_t nout;  /* samples of the reconstructed profile on [0, 1] (129)                 */
    int measured; /* 1: U_pred is what the engine measures, the estimator p->subpixel on the
                     plane of base's window (rpiv_ccm_corr_peak_window with base->window_w,
                     window_h, window_deform: dx_sub); 0: the continuous peak (0). With 1 the
                     fit runs on the continuous peak plus the offset dx_sub - dx of each
                     measurement, the offsets recomputed at the fitted profile and the fit
                     repeated until none moves by more than 1e-6 px (at most 10 rounds;
                     docs/bias.md, "The inversion's forward model")                      */
} rpiv_ccm_invert_params;

rpiv_ccm_invert_params rpiv_ccm_invert_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_ccm_invert_params_check(const rpiv_ccm_invert_params *p);

typedef struct rpiv_ccm_invert_result {
    size_t nout;
    double *z, *u, *u_std; /* reconstructed U*(z*) on nout points and its 1-sigma band       */
    size_t nmeas;
    double *xstar; /* the measurement sections                                       */
    double *zmax;  /* z*_max(x*) of the sheet there                                   */
    double *umeas; /* measured U*                                                    */
    double *ufit;  /* the model's prediction of them with the reconstructed profile  */
    size_t ncoef;
    double *coef;      /* B-spline coefficients                                          */
    double sigma;      /* measurement sigma used for the band                            */
    double chi2;       /* sum of squared data residuals                                  */
    size_t iterations; /* Levenberg-Marquardt iterations, summed over the rounds      */
    size_t rounds;     /* fits with updated offsets (measured = 1; 1 otherwise)        */
    double offset_max; /* largest |dx_sub - dx| of the fitted profile, U* (0 with
                          measured = 0)                                                */
} rpiv_ccm_invert_result;

/* Reconstruct U*(z*) from R-PIV measurements umeas[j] at sections xstar[j] (U* units, i.e.
 * measured displacement / scale_px), with standard deviations usigma[j] (NULL: all equal):
 * minimise sum_j w_j (U_pred(x_j) - umeas_j)^2 + lambda |D2 c|^2 over the B-spline
 * coefficients c, w_j = (sbar / sigma_j)^2 with sbar = (mean 1/sigma_j^2)^-1/2, where U_pred(x_j)
 * is the peak of Eq. "statform" with the sheet at x_j (gsl_multifit_nlinear, trust region
 * Levenberg-Marquardt, analytic Jacobian by implicit differentiation of the peak condition). base
 * gives the camera (object plane), h, d_p, scale_px, P; its u, v and illum are ignored. The band is
 * the Bayesian covariance sigma^2 (J^T J + lambda D^T D)^-1 mapped to U(z). *out:
 * rpiv_ccm_invert_free. */
RPIV_NODISCARD rpiv_status rpiv_ccm_invert(const rpiv_ccm_model *base, const rpiv_sheet *sheet,
                                           const double *xstar, const double *umeas,
                                           const double *usigma, size_t n,
                                           const rpiv_ccm_invert_params *ip,
                                           const rpiv_ccm_params *p, const rpiv_progress *progress,
                                           rpiv_ccm_invert_result **out);
void rpiv_ccm_invert_free(rpiv_ccm_invert_result *r);

/* E1 (Eq. "E1") against a reference profile ref(z*) of the paper's association (the measured
 * U* placed at z*_max(x*)) and of the reconstructed profile, both on the same heights: the
 * z*_max of the measurements and, with mirror = 1, their mirrors 1 - z*_max for z*_max < 0.5
 * (the paper's symmetric extension). */
RPIV_NODISCARD rpiv_status rpiv_ccm_invert_e1(const rpiv_ccm_invert_result *r, rpiv_ccm_func ref,
                                              int mirror, double *e1_assoc, double *e1_corr);

/* Write an inversion as text: "# rpiv-ccm-invert 1", header lines hdr (may be NULL), sigma,
 * chi2, then the profile rows "z* U* std" and, as '#m' lines, the measurements
 * "x* z*_max U_meas U_fit". Atomic; RPIV_EIO. */
RPIV_NODISCARD rpiv_status rpiv_ccm_invert_save(const rpiv_ccm_invert_result *r, const char *hdr,
                                                const char *path);

/* ---- the sheet's bias for every vector of a field (src/ccm/ccm_bias.c, docs/bias.md) ----- */

/* The depth a measured vector is referred to: the sheet's peak z*_max(x*) at the vector's
 * section, or the object plane z*_OP. */
typedef enum rpiv_ccm_depth { RPIV_CCM_DEPTH_ZMAX = 0, RPIV_CCM_DEPTH_ZOP = 1 } rpiv_ccm_depth;
extern const char *const rpiv_ccm_depth_names[]; /* "zmax", "zop", NULL */

/* Where the velocity's variation across the depth comes from:
 *  - DUCT: the square duct's U*(y*, z*) at each vector's y* (the model's scale_px);
 *  - PROFILE: one profile U*(z*) for every vector (two columns, rpiv_ccm_curve_load);
 *  - FIELD: the measured field, locally linear in z*: the sheet's peak moves along x* (R-PIV),
 *    so du/dz* = (du/dx*) / (dz*_max/dx*), likewise v; needs a sheet whose peak moves. */
typedef enum rpiv_ccm_vary {
    RPIV_CCM_VARY_DUCT = 0,
    RPIV_CCM_VARY_PROFILE = 1,
    RPIV_CCM_VARY_FIELD = 2
} rpiv_ccm_vary;
extern const char *const rpiv_ccm_vary_names[]; /* "duct", "profile", "field", NULL */

typedef struct rpiv_ccm_bias_params {
    int depth;                   /* rpiv_ccm_depth (zmax)                                   */
    int vary;                    /* rpiv_ccm_vary (duct)                                    */
    char profile[RPIV_PATH_MAX]; /* PROFILE: the U*(z*) file ("")                         */
    double rel_thickness;        /* uncertainty: relative change of the sheet's thickness
                                    about its peak (0.1)                                    */
    double dz;                   /* uncertainty: shift of the sheet, z* (0.01)              */
    double pixel_box;            /* [bias] pixel_box: the CCM's pixel integration (1; 0 =
                                    the paper's point-sampled images). Not read by
                                    rpiv_ccm_bias_field (it uses base->pixel_box):
                                    rpiv_config_ccm_model copies it into every model made
                                    from a configuration (rpiv ccm, --sheet-bias, demo)    */
    int window_model;            /* [bias] window_model: 1 = the CCM's prediction of what the
                                    engine measures models the [piv] final window (pair
                                    loss, mean removal: rpiv_ccm_model.window_w/h, copied
                                    by rpiv_config_ccm_model); 0 = an infinite window. Not
                                    read by rpiv_ccm_bias_field (it uses base's window)    */
    int window_interp;           /* [bias] window_interp: 1 = with window_model and a deformed
                                    final pass, the window's plane through the deformation's
                                    interpolation kernel and its pairs lost per shift of the
                                    plane (rpiv_ccm_model.window_deform = 2; the default since
                                    session 10); 0: per term, no interpolation (docs/ccm.md) */
    double window_pairs;         /* [bias] window_pairs: with window_interp, the ensemble's
                                    pairs N whose noise the modelled plane carries
                                    (rpiv_ccm_model.window_pairs); 0 (default): the run's
                                    own where the caller knows it (rpiv piv --sheet-bias: the
                                    pairs summed, 1 for a mean of instantaneous fields; the
                                    demo: its R-PIV pairs), else the noise-free plane       */
    int window_area;             /* [bias] window_area: with window_model, N >= 2 makes
                                    rpiv_config_ccm_predict average the model over N x N
                                    sub-positions of the final window (rpiv_ccm_predict_area,
                                    the flow across it: the duct along y*, the sheet along
                                    x*; the deformation follows its quadratic variation, an
                                    interior window); 0 or 1 (default 0) = the window's centre:
                                    the same to 3e-5 px on the duct (docs/ccm.md) at 1/25 to
                                    1/180 of the cost. Not read by rpiv_ccm_bias_field      */
    int measured;                /* [bias] measured: 1 = D_pred is what the engine measures,
                                    the estimator p->subpixel on the plane of base's window
                                    (rpiv_ccm_peak.dx_sub, dy_sub of rpiv_ccm_predict: the
                                    forward model of rpiv_ccm_invert_params.measured = 1);
                                    0 = the continuous peak of <R_D> (dx, dy). Default 1
                                    (session 11; 0 before)                                  */
    int measured_step;           /* [bias] measured_step: with measured, the window's estimate
                                    is computed exactly at every measured_step-th unmasked
                                    vector of a row (and between two of them whose estimator
                                    paths differ, by bisection), its offset from the
                                    continuous peak interpolated between two with the same
                                    path (docs/bias.md); 1 = exactly at every vector. The
                                    `field` variation is always exact (8)                  */
    int threads;                 /* OpenMP threads over rows; 0 = default (0)               */
} rpiv_ccm_bias_params;

rpiv_ccm_bias_params rpiv_ccm_bias_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_ccm_bias_params_check(const rpiv_ccm_bias_params *bp);

/* For every unmasked vector of f (image coordinates, not y-up), placed in the channel by g:
 * the displacement Eq. "statform" predicts through the sheet at the vector's x* (its
 * continuous peak; with bp->measured the estimate on the plane of base's window, dx_sub, exact
 * at nodes and interpolated between them, bp->measured_step), D_pred,
 * for the velocity's variation across the depth of bp->vary, against the displacement D_ref at the
 * depth of bp->depth: bias = D_pred - D_ref (px), and the corrected field u - bias_u. The
 * uncertainty of the bias is the half-difference of the bias with the sheet's thickness scaled by 1
 * +- rel_thickness and, in quadrature, with the sheet shifted by +- dz. Adds (or overwrites) the
 * quantities bias_u, bias_v, u_corrected, v_corrected, bias_u_std, bias_v_std (px/dt) and z_ref
 * (the depth, z*). Masked vectors get 0. base gives the camera (object plane), h, d_p, scale_px and
 * P; its illum, u, v are ignored. Deterministic for any thread count. Errors: RPIV_EINVAL
 * (parameters, a y-up field, FIELD with a sheet whose peak does not move along x*), those of the
 * profile reader and rpiv_ccm_predict, RPIV_EINTR if progress asks to stop (rows done / rows). */
RPIV_NODISCARD rpiv_status rpiv_ccm_bias_field(rpiv_field *f, const rpiv_ccm_model *base,
                                               const rpiv_sheet *sheet, const rpiv_ccm_geometry *g,
                                               const rpiv_ccm_bias_params *bp,
                                               const rpiv_ccm_params *p,
                                               const rpiv_progress *progress);

#endif /* RPIV_CCM_H */
