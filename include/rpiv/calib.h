/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/calib.h - calibration from target images (paper, section "Optical properties of
 * R-PIV"): the light-sheet profile from a fluorescent plate inclined in the sheet, and the
 * depth of focus and object plane from a dotted target on an inclined plate. Also renders such
 * target images from the imaging model (imaging.h) and a sheet (sheet.h), for tests, demos and
 * for users checking their set-up.
 *
 * Geometry (docs/calib.md): the camera looks along z through the floor; image x (columns) is the
 * streamwise x, image y (rows) the span. A plate inclined by `angle` from the floor, with its foot
 * (the line where it meets the floor, z = 0) at image column X_f, puts the plate point seen at
 * column X at the height
 *     z* = (X - X_f) tan(angle) / (s h),      s = image scale in px per metre (object space),
 * and at the streamwise position x* = x*_f + (X - X_f) / (s h). The default scale is
 * s = M / pixel pitch (camera magnification and sensor pixel).
 *
 * Units: SI (metres, degrees where the name says _deg); z*, x* are normalised by the channel
 * height h. Images are not modified; results are owned by the caller and freed with the
 * matching _free. All functions are reentrant (no global state). */
#ifndef RPIV_CALIB_H
#define RPIV_CALIB_H

#include "rpiv/error.h"
#include "rpiv/flow.h"
#include "rpiv/image.h"
#include "rpiv/imaging.h"
#include "rpiv/sheet.h"

#include <stddef.h>
#include <stdio.h>

/* ---- geometry and image preparation shared by both analyses ------------------------------ */

typedef struct rpiv_calib_geom {
    double angle_deg;      /* plate inclination from the floor, deg (45). |angle| in [5, 85];
                              negative: the plate rises toward decreasing image x (foot on the
                              right). 0: detect it from the plate's visible extent, which must
                              then span from the floor to plate_height_m (foot on the left). */
    double plate_height_m; /* height of the plate's top edge, used only to detect the angle, m
                              (0 = the channel height h) */
    double scale_px_m;     /* object-space image scale, px per metre (0 = M / pixel pitch) */
    int row0, row1;        /* span window: rows [row0, row1) are averaged (0, 0 = all rows) */
    double dark;           /* dark level subtracted from every pixel, grey (0); ignored when a
                              dark image or a dark region is given */
    int dark_x, dark_y, dark_w, dark_h; /* region whose mean grey is the dark level (w = 0: none) */
    int edge_window; /* plate-edge detection: columns used for the background and the
                        plate levels on each side of the edge, px (8) */
} rpiv_calib_geom;

rpiv_calib_geom rpiv_calib_geom_default(void);
/* RPIV_EINVAL naming the field: angle out of range, negative scale, bad rows or region. */
RPIV_NODISCARD rpiv_status rpiv_calib_geom_check(const rpiv_calib_geom *g);

/* One target image and where its plate is. */
typedef struct rpiv_calib_shot {
    const rpiv_image *image; /* the image (not owned, not modified)                          */
    double foot_px;          /* image column of the plate foot (z* = 0); NAN: detect it as the
                                half-height crossing of the step from the floor to the plate  */
    double x_foot;           /* x* of the plate foot; NAN: channel fov_x0 + X_f / (s h)       */
} rpiv_calib_shot;

/* ---- light-sheet profile from a fluorescent inclined plate ------------------------------ */

typedef struct rpiv_calib_sheet_params {
    rpiv_calib_geom geom;
    double smooth_px;   /* Gaussian smoothing (sigma) of the span-averaged profile, px (0: none) */
    int subtract_floor; /* 1: also subtract the profile's minimum along the plate (scattered
                           light, plate glow) before normalising (1) */
    double min_signal;  /* the sheet's peak above that floor must exceed min_signal x floor and
                           10 x the noise of the span average, else "no sheet" (0.1) */
    double margin;      /* z* dropped next to the floor and the plate top, where the blurred image
                           of the floor or of the plate edge leaks into the profile (0.03) */
    double zplus_step;  /* step of the mean shape table in z+ (0.01) */
    double zplus_max;   /* the mean shape covers |z+| <= zplus_max where measured (3) */
} rpiv_calib_sheet_params;

rpiv_calib_sheet_params rpiv_calib_sheet_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_calib_sheet_params_check(const rpiv_calib_sheet_params *p);

/* What one plate image gives. */
typedef struct rpiv_calib_sheet_plate {
    double foot_px, angle_deg;  /* used (given or detected)                                   */
    double x_foot;              /* x* of the foot                                              */
    double dark, floor;         /* grey levels subtracted: dark (NAN: dark image), floor   */
    double peak;                /* grey level of the profile maximum after subtraction         */
    size_t n;                   /* samples along the plate, z* increasing                      */
    double *z, *x, *inten;      /* z*, x* of each sample, and I0* = I / max                     */
    rpiv_sheet_metrics raw;     /* metrics of I0*(z*) as read along the plate                  */
    double x_max, x_inf, x_sup; /* x* where the plate meets z*_max, z*_inf, z*_sup            */
    rpiv_sheet_metrics at;      /* metrics of the sheet at x* = x_max, from the fitted lines
                                   (corrects the plate's oblique cut through the inclined sheet) */
    double shape_rms;           /* rms of this plate's I0*(z+) minus the mean shape             */
} rpiv_calib_sheet_plate;

typedef struct rpiv_calib_sheet_result {
    size_t nplates;
    rpiv_calib_sheet_plate *plate;
    /* The self-similar model: z*_max(x*) = zm0 + zm1 x*, e*(x*) = e0 + e1 x*, and the edge
     * lines z*_inf = inf0 + inf1 x*, z*_sup = sup0 + sup1 x* (e = sup - inf). With one plate
     * (or all plates at one x*) the slopes are 0. */
    double zm0, zm1, e0, e1, inf0, inf1, sup0, sup1;
    /* Mean shape S(z+), z+ = (z* - z*_max(x*)) / e*(x*), normalised to max 1, z+ increasing. */
    size_t nshape;
    double *zplus, *shape;
} rpiv_calib_sheet_result;

/* Analyse nshots >= 1 images of the plate at several positions: span average, dark and floor
 * subtraction, z* mapping, normalisation, metrics; then the straight lines through the
 * (x*, z*) points where each plate meets z*_max, z*_inf, z*_sup (least squares), and the mean
 * shape. `dark` is an optional dark image (same size as every shot; NULL: geom.dark_* or
 * geom.dark). Errors: RPIV_EINVAL (parameters, no shots), RPIV_ESIZE (dark image or region or
 * rows do not fit an image), RPIV_ENUMERIC naming the shot (blank image, plate edge not found,
 * profile not falling to 0.25 on both sides inside the channel), RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status rpiv_calib_sheet_run(const rpiv_calib_sheet_params *p,
                                                const rpiv_camera *cam, const rpiv_channel *ch,
                                                const rpiv_calib_shot *shots, size_t nshots,
                                                const rpiv_image *dark,
                                                rpiv_calib_sheet_result **out);
void rpiv_calib_sheet_result_free(rpiv_calib_sheet_result *r); /* NULL is a no-op */

/* Write the model and mean shape as a sheet profile file ("# rpiv-sheet 1", sheet.h), the file
 * the generator and the CCM read. RPIV_EIO if it cannot be written. */
RPIV_NODISCARD rpiv_status rpiv_calib_sheet_save_profile(const rpiv_calib_sheet_result *r,
                                                         const char *path);
/* Text tables: one line per plate with its metrics (plates), every sample (profiles). */
RPIV_NODISCARD rpiv_status rpiv_calib_sheet_write_plates(const rpiv_calib_sheet_result *r,
                                                         FILE *fp);
RPIV_NODISCARD rpiv_status rpiv_calib_sheet_write_profiles(const rpiv_calib_sheet_result *r,
                                                           FILE *fp);

/* ---- depth of focus from a dotted target ------------------------------------------------ */

typedef struct rpiv_calib_dof_params {
    rpiv_calib_geom geom;
    double dot_d_m;      /* dot diameter on the target, m (62.5e-6)                       */
    double pitch_m;      /* dot pitch on the target, both directions, m (125e-6)          */
    double min_contrast; /* a dot centre must be this fraction below the local mean (0.03) */
    double min_snr;      /* ... and below it by min_snr x the standard deviation of the
                            pixels around it (whole cells): a lattice of dots gives >= 1.4
                            (a blurred lattice is a sinusoid), noise minima less (1)      */
    double smooth_px;    /* Gaussian smoothing (sigma) of the image used to detect the dots
                            and locate their centres, px (0.7); the grey level is read on
                            the unsmoothed image                                          */
    double lattice_tol;  /* a dot needs a neighbour one pitch away within this fraction of
                            the pitch, else it is rejected as spurious (0.25)             */
    int ref_cells;       /* the reference grey is the mean over ref_cells x ref_cells
                            lattice cells around the dot (2)                              */
    int fit_columns;     /* the curve 1/I*(z*) is smoothed by a local least-squares parabola
                            through 2 fit_columns + 1 columns before its maximum and
                            half-maximum crossings are read; this averages the pixel phase
                            of the columns (4; 0 = none)                                  */
} rpiv_calib_dof_params;

rpiv_calib_dof_params rpiv_calib_dof_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_calib_dof_params_check(const rpiv_calib_dof_params *p);

/* The focus curve: I*(z*) and 1/I* per column of dots (or per model sample).
 * I* = (grey of the pixel nearest the dot centre) / (local mean grey over whole lattice cells),
 * both above the dark level. The local mean is unchanged by blur, so a fully blurred dot has
 * I* = 1. The normalised inverse grey level is g = (1/I* - 1) / (max(1/I*) - 1), the excess
 * over that "no dot" baseline; DOF* is its full width at half maximum and z*_OP its maximum. */
typedef struct rpiv_calib_focus {
    size_t n;
    double *z;           /* z* of each column of dots, increasing                             */
    double *istar;       /* span-averaged I*                                                  */
    double *inv;         /* 1 / I*                                                            */
    double *g;           /* normalised inverse grey level (1/I* - 1) / (inv_max - 1)           */
    double *gfit;        /* the same after the local fit (fit_columns): the curve DOF* is read on */
    size_t *count;       /* dots averaged in each column (NULL for a model curve)             */
    double inv_max;      /* maximum of the fitted 1/I*, used to normalise                     */
    double zop;          /* z*_OP: vertex of the least-squares parabola through g in [zlo, zhi] */
    double zmid;         /* midpoint of the half-maximum crossings                            */
    double zlo, zhi;     /* half-maximum crossings of gfit (linear interpolation)             */
    double dof;          /* DOF* = zhi - zlo                                                  */
    double dof_raw;      /* FWHM of 1/I* / max(1/I*) without the baseline (NAN if it never
                            falls to half its maximum: max(1/I*) < 2)                         */
    double dof_contrast; /* FWHM of the darkness 1 - I* (NAN if not reached)               */
} rpiv_calib_focus;

/* One detected dot. */
typedef struct rpiv_calib_dot {
    size_t shot;  /* index of its image                                   */
    double x, y;  /* sub-pixel centre, px                                 */
    double zstar; /* height of the dot                                    */
    double grey;  /* grey of the pixel nearest the centre, above dark     */
    double ref;   /* local mean grey above dark                           */
    double istar; /* grey / ref                                           */
} rpiv_calib_dot;

typedef struct rpiv_calib_dof_result {
    size_t nshots;
    double *foot_px, *angle_deg, *dark; /* per shot: used (given or detected) */
    size_t ndots;
    rpiv_calib_dot *dot;
    rpiv_calib_focus curve;
} rpiv_calib_dof_result;

/* Detect the dots (local minima of the lightly smoothed image darker than the local mean by
 * min_contrast and min_snr, one per lattice cell, with a lattice neighbour), measure each dot's
 * centre grey level relative to the local mean, average the columns of dots along the span (pooling
 * all shots by z*), and find DOF* and z*_OP. Errors: as rpiv_calib_sheet_run; RPIV_ENUMERIC when no
 * dot is found, fewer than 5 columns of dots remain, or the curve does not fall to half its
 * maximum on both sides (DOF wider than the target). */
RPIV_NODISCARD rpiv_status rpiv_calib_dof_run(const rpiv_calib_dof_params *p,
                                              const rpiv_camera *cam, const rpiv_channel *ch,
                                              const rpiv_calib_shot *shots, size_t nshots,
                                              const rpiv_image *dark, rpiv_calib_dof_result **out);
void rpiv_calib_dof_result_free(rpiv_calib_dof_result *r); /* NULL is a no-op */
/* Text table of the focus curve (z*, dots, I*, 1/I*, g). */
RPIV_NODISCARD rpiv_status rpiv_calib_focus_write(const rpiv_calib_focus *c, FILE *fp);

/* The model's focus curve for a target (dot diameter, pitch, angle from p) of dot reflectance
 * `reflectance` (0 = black, < 1) seen by camera `cam` (its z*_OP, f#, M, s0, lambda): I* at a dot
 * centre of an infinite lattice, blurred by the Gaussian of Eq. "diam" (diameter
 * rpiv_imaging_de_m with d_p = 0, i.e. diffraction and defocus; the dot's own geometric image is
 * the ellipse) and by the pixel, sampled every zstep in z* over [zop - 1, zop + 1]. Fills *c
 * (release with rpiv_calib_focus_free). RPIV_ENUMERIC if the curve has no half maximum there. */
RPIV_NODISCARD rpiv_status rpiv_calib_dof_model(const rpiv_calib_dof_params *p,
                                                const rpiv_camera *cam, double h_m,
                                                double reflectance, double zstep,
                                                rpiv_calib_focus *c);
void rpiv_calib_focus_free(rpiv_calib_focus *c); /* frees the arrays, not c */

/* The dot reflectance for which the model's 1/I* at the object plane equals inv_max (a
 * measured maximum), so that rpiv_calib_dof_model can be compared with a measurement whose
 * target contrast is unknown. RPIV_ENUMERIC if no reflectance in [0, 1) gives that peak (the
 * measured dots are darker than a black dot of the model, or not darker than the mean). */
RPIV_NODISCARD rpiv_status rpiv_calib_dof_reflectance(const rpiv_calib_dof_params *p,
                                                      const rpiv_camera *cam, double h_m,
                                                      double inv_max, double *reflectance);

/* Text table of the detected dots (image, x, y, z*, grey, reference, I*). */
RPIV_NODISCARD rpiv_status rpiv_calib_dof_write_dots(const rpiv_calib_dof_result *r, FILE *fp);

/* ---- target images from the model ------------------------------------------------------- */

typedef struct rpiv_calib_render_params {
    double angle_deg;      /* plate inclination (45), as rpiv_calib_geom.angle_deg (not 0) */
    double foot_px;        /* column of the plate foot (40.3187)                            */
    double x_foot;         /* x* of the foot (NAN: channel fov_x0 + foot / (s h))           */
    double plate_height_m; /* height of the plate's top edge, m (0 = channel height)        */
    double scale_px_m;     /* object-space scale, px/m (0 = M / pixel pitch)                */
    double dark;           /* sensor dark level, grey (100)                                  */
    double background;     /* floor (outside the plate) above dark, grey (150)              */
    double level;          /* sheet: fluorescence at I0 = 1; dots: white level; above dark (3000) */
    double glow;           /* sheet: uniform emission of the plate outside the sheet (0)     */
    double white_slope;    /* dots: relative illumination change across the image width (0)  */
    double dot_d_m;        /* dots: diameter, m (62.5e-6)                                     */
    double pitch_m;        /* dots: pitch, m (125e-6)                                         */
    double reflectance;    /* dots: reflectance of a dot relative to the white (0.1)          */
    double phase_x,
        phase_y;  /* dots: lattice offset from the foot / row 0, in pitches (0.3187, 0.2219) */
    double noise; /* standard deviation of added Gaussian noise, grey (0)           */
    unsigned long seed; /* noise seed (1)                                                 */
} rpiv_calib_render_params;

rpiv_calib_render_params rpiv_calib_render_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_calib_render_params_check(const rpiv_calib_render_params *rp);

/* Fill im (any size, allocated by the caller) with the image of a fluorescent plate in the sheet
 * `sheet`: each plate point emits level * I0(x*, z*) (+ glow) scaled by (s0 / (s0 + z'))^2
 * (Eq. "int"), imaged with the Gaussian blur of Eq. "diam" (d_p = 0) at its own defocus
 * z' = h |z* - z*_OP| and integrated over the pixel; uniform along the span. */
RPIV_NODISCARD rpiv_status rpiv_calib_render_sheet(const rpiv_calib_render_params *rp,
                                                   const rpiv_camera *cam, const rpiv_channel *ch,
                                                   const rpiv_sheet *sheet, rpiv_image *im);
/* Fill im with a dotted target (black dots of reflectance `reflectance` on white) on the plate:
 * each dot is an ellipse (its diameter foreshortened by cos(angle) along x) blurred like the
 * sheet image above. */
RPIV_NODISCARD rpiv_status rpiv_calib_render_dots(const rpiv_calib_render_params *rp,
                                                  const rpiv_camera *cam, const rpiv_channel *ch,
                                                  rpiv_image *im);

#endif /* RPIV_CALIB_H */
