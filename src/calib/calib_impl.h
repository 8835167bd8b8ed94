/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/calib/calib_impl.h - helpers shared inside the calib module: the target's image model
 * (calib_blur.c), the plate in the image (calib_plate.c), the focus curve (calib_focus.c).
 * Internal: not installed. */
#ifndef RPIV_CALIB_IMPL_H
#define RPIV_CALIB_IMPL_H

#include "rpiv/calib.h"

#include <stddef.h>

/* Object-space scale in px per metre: the given one, or M / sensor pixel pitch. */
double calib_scale(double scale_px_m, const rpiv_camera *cam);

/* Standard deviation, in image pixels, of the Gaussian blur of Eq. "diam" without the
 * geometric term (diffraction and defocus) for an object point at height zstar. */
double calib_blur_px(const rpiv_camera *cam, double h_m, double scale, double zstar);

/* Gaussian of standard deviation s (px) integrated over the pixel [u - 1/2, u + 1/2]. */
double calib_boxg(double u, double s);
/* The same integrated along the segment [-w, w] of the source: the column term of a uniform
 * bar of half-width w seen by a pixel at offset u, exactly (w >= 0). */
double calib_boxg_bar(double u, double w, double s);

/* Composite Gauss-Legendre rule on [-pi/2, pi/2] used to integrate ellipses row by row:
 * CALIB_GL_BASE nodes per panel, and enough panels (up to CALIB_GL_PANELS) that a panel spans
 * about two blur widths of the ellipse's rows. */
#define CALIB_GL_BASE   16
#define CALIB_GL_PANELS 32
#define CALIB_GL_MAX    (CALIB_GL_BASE * CALIB_GL_PANELS)
typedef struct calib_gl {
    double x[CALIB_GL_BASE], w[CALIB_GL_BASE]; /* on [-1, 1] */
} calib_gl;
RPIV_NODISCARD rpiv_status calib_gl_init(calib_gl *gl);

/* Darkness of a unit-darkness ellipse (semi-axes ax along x, ay along y, px) centred at
 * (cx, cy), blurred by a Gaussian s (px) and integrated over pixels: adds scale * value into
 * out[(y - y0) * nx + (x - x0)] for the nx x ny pixels starting at (x0, y0). work holds
 * (nx + ny) * CALIB_GL_MAX doubles. */
void calib_ellipse_add(const calib_gl *gl, double cx, double cy, double ax, double ay, double s,
                       int x0, int y0, int nx, int ny, double scale, double *out, double *work);

/* The same at one pixel centred at (px, py) (no accumulation). */
double calib_ellipse_at(const calib_gl *gl, double cx, double cy, double ax, double ay, double s,
                        double px, double py);

/* Darkness of the pixel nearest a dot centre in an infinite lattice (pitches ppx, ppy px) of
 * such ellipses centred on lattice points, averaged over the dot centre's offsets in that pixel
 * (n Gauss-Legendre nodes `node`, weights `wt` on [-1/2, 1/2] per axis, weights summing to 1). */
double calib_lattice_pixel(const calib_gl *gl, double ax, double ay, double ppx, double ppy,
                           double s, const double *node, const double *wt, int n);

/* Image preparation shared by both analyses. */
typedef struct calib_frame {
    const rpiv_image *im;   /* the shot's image        */
    const rpiv_image *dark; /* dark image or NULL      */
    double dark_level;      /* scalar dark if no image */
    int row0, row1;         /* span window             */
} calib_frame;

/* Check sizes/rows/region against the image and work out the dark level. `what` names the shot
 * in messages ("shot 2"). */
RPIV_NODISCARD rpiv_status calib_frame_init(const rpiv_calib_geom *g, const rpiv_image *im,
                                            const rpiv_image *dark, const char *what,
                                            calib_frame *f);
/* Grey above dark at pixel (x, y). */
double calib_frame_at(const calib_frame *f, int x, int y);
/* Noise of the span-averaged profile: median over columns of the standard deviation along the
 * span, divided by sqrt(rows) (structure along the span counts as noise: conservative). */
RPIV_NODISCARD rpiv_status calib_frame_noise(const calib_frame *f, double *noise);
/* Span-averaged, dark-subtracted profile along x (w values). */
void calib_frame_profile(const calib_frame *f, double *p);

/* Plate geometry of one shot: foot column, angle, x* of the foot, z* per px (k: z* = (X - foot) k).
 */
typedef struct calib_place {
    double foot, angle_deg, x_foot, scale, k, h_m;
} calib_place;
/* Resolve given or detected foot and angle from the span-averaged profile p (w values). */
RPIV_NODISCARD rpiv_status calib_place_init(const rpiv_calib_geom *g, const rpiv_camera *cam,
                                            const rpiv_channel *ch, const rpiv_calib_shot *shot,
                                            const double *p, int w, const char *what,
                                            calib_place *pl);

/* The focus curve (calib_focus.c). calib_focus_alloc: the arrays for n heights (and the dot
 * counts if counts). calib_focus_analyse: from z and I* (filled by the caller), 1/I*, its local
 * fit (m columns each side), g, the crossings, DOF*, z*_OP and the secondary widths; `what`
 * names the analysis in messages. */
RPIV_NODISCARD rpiv_status calib_focus_alloc(rpiv_calib_focus *c, size_t n, int counts);
RPIV_NODISCARD rpiv_status calib_focus_analyse(rpiv_calib_focus *c, int m, const char *what);

#endif /* RPIV_CALIB_IMPL_H */
