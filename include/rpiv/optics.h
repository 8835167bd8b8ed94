/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/optics.h - 2-D (x, z) ray tracing of the R-PIV laser sheet: Gaussian beam, converging
 * lens, air/PMMA refraction at the prism's inclined face, PMMA/water refraction at the channel
 * floor (Snell-Descartes and Fresnel, the paper's Eq. "Desc"), and the sheet it makes in the
 * water: intensity profiles I0(z*) at stations x*, their metrics, sweeps over beta1, the one-ray
 * sensitivity to the index ratio (paper fig. 10) and a self-similar fit for the sheet module.
 *
 * Geometry (docs/optics.md has the diagram): x horizontal along the sheet's propagation in the
 * water, z up, channel floor z = 0 (water above, PMMA below), ceiling z = h absorbs. The
 * inclined face's inward normal makes the angle theta_p with the vertical, so a ray along it
 * meets the floor at incidence theta_p. The beam axis meets the face at the point P whose
 * distance to the floor along the face normal is the block thickness; the lens is lens_dist
 * before P along the axis. The axis deviates from the face normal by beta1 towards the vertical
 * (it lowers the incidence on the floor); beta1 is the incidence in the air (default) or the
 * deviation in the PMMA (laser.beta1_side). x* = 0 where the axis, refracted at the face,
 * crosses the floor.
 *
 * Units: SI (metres, radians) in structs unless a name says _deg; z* = z/h, x* = x/h.
 * Thread-safety: every function is reentrant; rpiv_optics_trace runs OpenMP threads itself and
 * its results are bit-identical for any thread count. */
#ifndef RPIV_OPTICS_H
#define RPIV_OPTICS_H

#include "rpiv/error.h"
#include "rpiv/progress.h"
#include "rpiv/sheet.h"

#include <stddef.h>

typedef enum rpiv_polar {
    RPIV_POLAR_P = 0, /* p-polarised, the paper's Eq. "Desc" (default) */
    RPIV_POLAR_S = 1,
    RPIV_POLAR_UNPOLARISED = 2 /* mean of the p and s reflectances */
} rpiv_polar;

/* Where beta1 is measured: the angle between the beam axis and the inclined face's normal, on
 * the air side (the incidence on the face, default: the paper's words; inside, the axis then
 * deviates by asin(n_air sin(beta1) / n_pmma)) or on the PMMA side (after refraction: the
 * reading that reproduces the paper's one-ray figures, fig. 10). The face refracts in both
 * cases; docs/optics.md compares them. */
typedef enum rpiv_beta1_side { RPIV_BETA1_AIR = 0, RPIV_BETA1_PMMA = 1 } rpiv_beta1_side;

/* The laser and its emitting optics. */
typedef struct rpiv_laser {
    double lambda_m;            /* wavelength, m (532e-9; recorded, unused by the 2-D tracer) */
    double beam_d_m;            /* beam diameter at 1/e^2 at the laser output, m (6e-3) */
    double expander;            /* beam expander factor (2): 1/e^2 diameter 12 mm at the lens */
    double divergence_rad;      /* full divergence angle at the laser output, rad (3.5e-3) */
    double lens_f_m;            /* spherical converging lens focal length, m (0.5) */
    double lens_dist_m;         /* lens to the inclined face along the axis, m (0.27) */
    double beta1_deg;           /* axis deviation from the face normal, deg (1.3) */
    double bundle_m;            /* full width of the equally spaced ray bundle at the lens, m
                                   (19e-3: the paper's "complete beam ... of width 19 mm") */
    long nrays;                 /* rays traced (100000) */
    rpiv_polar polar;           /* Fresnel transmission (p) */
    rpiv_beta1_side beta1_side; /* side of the face beta1 is measured on (air) */
} rpiv_laser;

/* The PMMA prism and the fluid. */
typedef struct rpiv_prism {
    double theta_p_deg; /* inclination of the inclined face, deg (64) */
    double thickness_m; /* block thickness, m (49e-3): distance from the beam's entry
                           point on the face to the floor along the face normal */
    double n_pmma;      /* refractive index of PMMA (1.49) */
    double n_water;     /* refractive index of the fluid (1.33) */
    double n_air;       /* refractive index of air (1.0) */
} rpiv_prism;

rpiv_laser rpiv_laser_default(void);
rpiv_prism rpiv_prism_default(void);
/* RPIV_EINVAL naming the field and its range. */
RPIV_NODISCARD rpiv_status rpiv_laser_check(const rpiv_laser *l);
RPIV_NODISCARD rpiv_status rpiv_prism_check(const rpiv_prism *p);

/* Short names: "p", "s", "unpolarised"; "air", "pmma". */
/* The names in enum order (NULL-terminated), as the INI file spells them. */
extern const char *const rpiv_polar_names[];
extern const char *const rpiv_beta1_side_names[];
const char *rpiv_polar_name(rpiv_polar pol);
const char *rpiv_beta1_side_name(rpiv_beta1_side side);

/* ---- one interface --------------------------------------------------------------------- */

/* Snell-Descartes and Fresnel at a plane interface from index n1 into n2, incidence theta_i in
 * [0, pi/2] rad from the normal. Returns 1 when the ray is transmitted, with *theta_t the
 * refraction angle and *T = 1 - R the power transmission for `pol` (p: the paper's Eq. "Desc",
 * R = |tan(theta_t - theta_i) / tan(theta_t + theta_i)|^2; s: R = |sin(..)/sin(..)|^2;
 * unpolarised: mean R; at normal incidence R = ((n1 - n2)/(n1 + n2))^2 for all three).
 * Returns 0 on total internal reflection (n1 sin(theta_i) >= n2): *theta_t = pi/2, *T = 0.
 * Either output pointer may be NULL. */
int rpiv_optics_refract(double n1, double n2, double theta_i, rpiv_polar pol, double *theta_t,
                        double *T);

/* ---- the beam axis --------------------------------------------------------------------- */

/* The central ray (lens axis) through the set-up, traced whether or not the floor reflects it
 * totally. Angles in rad. */
typedef struct rpiv_optics_axis {
    double beta1_air;       /* incidence on the inclined face (air side) */
    double beta1_pmma;      /* deviation from the face normal inside the PMMA */
    double theta_i;         /* incidence on the floor (PMMA/water), = theta_p - beta1_pmma */
    double theta_c;         /* critical angle asin(n_water / n_pmma) */
    double theta_t;         /* refraction angle in the water (pi/2 if totally reflected) */
    double elevation;       /* angle of the transmitted axis above the floor, pi/2 - theta_t */
    double T_face, T_floor; /* Fresnel transmissions of the two interfaces (0 if TIR) */
    double path_pmma_m;     /* axis path from the face to the floor */
    double path_air_m;      /* = lens_dist_m */
    double depth_m;         /* depth of the entry point P below the floor */
    double x_apex_m;        /* apex (face/floor edge) relative to the emerging point x = 0 */
    int transmitted;        /* 0 if the axis is totally reflected at the floor */
} rpiv_optics_axis;

RPIV_NODISCARD rpiv_status rpiv_optics_axis_of(const rpiv_laser *l, const rpiv_prism *p,
                                               rpiv_optics_axis *out);

/* ---- tracing the beam ------------------------------------------------------------------ */

typedef struct rpiv_optics_opts {
    double dz_star;     /* profile bin width in z* (0.005: 200 bins over the channel) */
    double smooth_star; /* Gaussian smoothing of the profiles, sigma in z* (0 = none) */
    int threads;        /* OpenMP threads (0 = OpenMP's default); results do not depend on it */
} rpiv_optics_opts;

rpiv_optics_opts rpiv_optics_opts_default(void);
RPIV_NODISCARD rpiv_status rpiv_optics_opts_check(const rpiv_optics_opts *o);

/* Power bookkeeping, normalised by the incident power Ig (so incident = 1 up to rounding):
 * incident = refl_face + refl_floor + tir + missed + transmitted. */
typedef struct rpiv_optics_stats {
    double incident;    /* Ig: the Gaussian weights of all rays */
    double refl_face;   /* reflected by the air/PMMA face (Fresnel 1 - T) */
    double refl_floor;  /* reflected by the floor below the critical angle (1 - T) */
    double tir;         /* lost by total internal reflection at the floor */
    double missed;      /* rays that miss the face or go down in the prism (0 normally) */
    double transmitted; /* It / Ig: power entering the water */
    long n_rays, n_tir, n_missed, n_transmitted;
} rpiv_optics_stats;

/* A traced sheet: profiles at nx stations, each on nz bins of width dz_star over z* in
 * [0, 1] (bin j centred at zstar[j] = (j + 0.5) dz_star). inten[k * nz + j] is the fluence
 * rate at x*[k], z*[j] in units of Ig / h (the power per unit height of the ray tubes measured
 * across the rays, so that the integral over z* of a sheet that crosses the station whole and
 * nearly horizontal is its share of It/Ig), smoothed if asked. Rays that reach the ceiling
 * (z* = 1) before a station are absorbed there and do not count at it. Read-only. */
typedef struct rpiv_optics_result {
    size_t nx, nz;
    double *xstar; /* [nx] stations */
    double *zstar; /* [nz] bin centres */
    double *inten; /* [nx * nz] */
    double dz_star, smooth_star;
    rpiv_optics_stats stats;
    rpiv_optics_axis axis;
    rpiv_laser laser; /* the parameters traced (polarisation, beta1, rays ...) */
    rpiv_prism prism;
    double h_m; /* channel height */
} rpiv_optics_result;

/* Trace laser->nrays equally spaced rays (no random numbers) and bin their crossings of the
 * vertical lines x* = xstar[k] (any finite values, nx >= 1). h_m: channel height. On RPIV_OK
 * *out owns a new result (free with rpiv_optics_result_free). Errors: RPIV_EINVAL (bad
 * parameters, named), RPIV_ENOMEM, RPIV_EINTR if the progress callback asks to stop
 * (progress is reported in rays, from the calling thread). */
RPIV_NODISCARD rpiv_status rpiv_optics_trace(const rpiv_laser *l, const rpiv_prism *p, double h_m,
                                             const double *xstar, size_t nx,
                                             const rpiv_optics_opts *o, const rpiv_progress *prog,
                                             rpiv_optics_result **out);
void rpiv_optics_result_free(rpiv_optics_result *r); /* NULL is a no-op */

/* Profile k normalised by its maximum, I0*(z*) (nz values into out). Returns the maximum
 * (Ig / h), 0 if the station is dark (then out is all zeros). */
double rpiv_optics_profile_norm(const rpiv_optics_result *r, size_t k, double *out);

/* Sheet metrics of station k (sheet.h: z*_max, z*_inf, z*_sup, e* at 0.25 max, imax in
 * Ig / h). RPIV_ENUMERIC (message names x*) if the station is dark or the profile does not
 * fall to a quarter of its maximum inside the channel on both sides. */
RPIV_NODISCARD rpiv_status rpiv_optics_metrics(const rpiv_optics_result *r, size_t k,
                                               rpiv_sheet_metrics *m);
/* z*_inf, z*_max, z*_sup and e* of every station of r (arrays of r->nx), NaN where the
 * station has no metrics (dark, or not falling to a quarter: rpiv_optics_metrics fails). */
void rpiv_optics_metrics_all(const rpiv_optics_result *r, double *zinf, double *zmax, double *zsup,
                             double *e);

/* ---- the self-similar sheet ------------------------------------------------------------ */

/* Least-squares lines e*(x*) = e0 + e1 x* and z*_max(x*) = zm0 + zm1 x* through the metrics of
 * the stations where they exist, and the mean normalised shape S(z+), z+ = (z* - z*_max)/e*,
 * on a grid of step dzplus (mean over the stations covering each z+; renormalised to max 1).
 * The sheet's inclination is atan(zm1), its thickness growth e1. */
typedef struct rpiv_optics_selfsim {
    double e0, e1, zm0, zm1;
    double rms_e, rms_zm;  /* rms residuals of the two lines */
    double rms_shape;      /* rms departure of the stations' normalised profiles
                              from the mean shape (0 = exactly self-similar) */
    size_t nused;          /* stations with metrics */
    size_t n;              /* shape rows */
    double *zplus, *shape; /* [n] */
} rpiv_optics_selfsim;

/* Fit from nx profiles sampled on the same nz heights zstar (increasing), inten[k * nz + j]
 * at station xstar[k] (any scale per station). Needs at least 2 stations with metrics,
 * otherwise RPIV_ENUMERIC. On RPIV_OK *out owns a new fit (rpiv_optics_selfsim_free). Usable on
 * measured profiles as well as traced ones. */
RPIV_NODISCARD rpiv_status rpiv_optics_selfsim_fit(const double *xstar, size_t nx,
                                                   const double *zstar, size_t nz,
                                                   const double *inten, double dzplus,
                                                   rpiv_optics_selfsim **out);
void rpiv_optics_selfsim_free(rpiv_optics_selfsim *f); /* NULL is a no-op */

/* Write a fit as a sheet profile file (sheet.h, "# rpiv-sheet 1"), readable with
 * sheet.kind = selfsim, sheet.profile = path. RPIV_EIO naming the path. */
RPIV_NODISCARD rpiv_status rpiv_optics_selfsim_save(const rpiv_optics_selfsim *f, const char *path);

/* ---- sweeps ---------------------------------------------------------------------------- */

/* One beta1 of a sweep at station x*: metrics (NaN where missing), It/Ig, the peak fluence
 * rate (Ig / h) and the peak normalised by the beta1 = 2 deg case (paper fig. 12). */
typedef struct rpiv_optics_sweep_row {
    double beta1_deg;
    double zmax, zinf, zsup, e; /* NaN when the profile has no quarter-height crossing */
    double it_ig;
    double ipeak, ipeak_star;
    double elevation_deg; /* of the axis in the water (NaN if totally reflected) */
} rpiv_optics_sweep_row;

/* Sweep beta1 over n values beta1[i] (deg) at station xstar, everything else from *l.
 * rows[i] and, if profiles is not NULL, the normalised profiles profiles[i * nz + j] on the
 * result's nz bins (nz = ceil(1/dz_star)) are filled. Reference peak: a trace at beta1 = 2 deg
 * (reused if in the list). Errors as rpiv_optics_trace. */
RPIV_NODISCARD rpiv_status rpiv_optics_sweep_beta1(const rpiv_laser *l, const rpiv_prism *p,
                                                   double h_m, double xstar, const double *beta1,
                                                   size_t n, const rpiv_optics_opts *o,
                                                   const rpiv_progress *prog,
                                                   rpiv_optics_sweep_row *rows, double *profiles);

/* Number of bins of a profile for opts o: ceil(1 / dz_star). */
size_t rpiv_optics_nbins(const rpiv_optics_opts *o);

/* ---- one-ray sensitivity to the index ratio (paper fig. 10) ---------------------------- */

/* For the axis ray (incidence theta_i on the floor fixed by the geometry), the floor's
 * refraction with eta = n_pmma / n_water + deta: theta_t, T and their relative changes from
 * deta = 0. transmitted = 0 beyond the cut-off (then theta_t = pi/2, T = 0, dT_rel = -1 and
 * dtheta_rel = NaN). */
typedef struct rpiv_optics_sens_row {
    double deta, theta_t, T, dtheta_rel, dT_rel;
    int transmitted;
} rpiv_optics_sens_row;

/* n rows with deta evenly from deta0 to deta1 (n >= 2); *cutoff (may be NULL) gets the deta
 * beyond which the ray is totally reflected, 1/sin(theta_i) - eta0. RPIV_ENUMERIC if the axis
 * is totally reflected at deta = 0 (no reference). */
RPIV_NODISCARD rpiv_status rpiv_optics_sensitivity(const rpiv_laser *l, const rpiv_prism *p,
                                                   double deta0, double deta1, size_t n,
                                                   rpiv_optics_sens_row *rows, double *cutoff);

/* ---- text tables ----------------------------------------------------------------------- */

/* Each table starts with '#' lines recording every laser and prism parameter (polarisation and
 * beta1 side included), then a '# columns:' line, then whitespace-separated rows; NaN is
 * written "nan". Written through a temporary file and renamed. RPIV_EIO naming the path. */

/* Station k: z*, I (Ig / h), I0* = I / max. */
RPIV_NODISCARD rpiv_status rpiv_optics_save_profile(const rpiv_optics_result *r, size_t k,
                                                    const char *path);
/* One row per station: x*, z*_inf, z*_max, z*_sup, e*, I_max (nan where metrics are missing). */
RPIV_NODISCARD rpiv_status rpiv_optics_save_metrics(const rpiv_optics_result *r, const char *path);
/* Sweep rows (beta1, e*, z*_inf, z*_max, z*_sup, It/Ig, I_peak, I*_peak, axis elevation);
 * if profiles is not NULL, also `profiles_path`: z* then one I0* column per beta1. l and p are
 * recorded in the header (their beta1 is the swept one). */
RPIV_NODISCARD rpiv_status rpiv_optics_save_sweep(const rpiv_laser *l, const rpiv_prism *p,
                                                  double xstar, const rpiv_optics_sweep_row *rows,
                                                  size_t n, const char *path,
                                                  const double *profiles, const rpiv_optics_opts *o,
                                                  const char *profiles_path);
/* deta, theta_t (deg), T, dtheta_t/theta_t0, dT/T0, transmitted; the cut-off in the header. */
RPIV_NODISCARD rpiv_status rpiv_optics_save_sensitivity(const rpiv_laser *l, const rpiv_prism *p,
                                                        const rpiv_optics_sens_row *rows, size_t n,
                                                        double cutoff, const char *path);

#endif /* RPIV_OPTICS_H */
