/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/imaging.h - the receiving optics and the particle-image model of the paper
 * (Eq. "diam" and Eq. "int", after Olsen & Adrian 2000). One implementation, used by the
 * synthetic-image generator (synth.h) and by the correlation model (ccm.h).
 *
 * Units: lengths in metres unless the name says otherwise; z* is height / channel height h.
 * Reading of the paper (docs/model.md): the defocus distance z' of Eq. "diam" and "int" is a
 * physical length; the paper writes the normalised difference |z* - z*_OP|, which cannot be
 * added to s0 (a length). The camera looks into the fluid through a flat wall, so a particle
 * a geometric distance h |z* - z*_OP| from the object plane is defocused like one at the
 * apparent (paraxial) distance z' = h |z* - z*_OP| / n_medium in air; n_medium = 1 gives the
 * paper's geometric reading. */
#ifndef RPIV_IMAGING_H
#define RPIV_IMAGING_H

#include "rpiv/error.h"

/* The camera and its lens. */
typedef struct rpiv_camera {
    int width_px, height_px; /* sensor size in pixels (2560 x 2160)                      */
    double sensor_w_m;       /* sensor width, m (16.6e-3); pixel pitch = sensor_w_m/width_px */
    double sensor_h_m;       /* sensor height, m (14e-3)                                  */
    double focal_m;          /* lens focal length f, m (0.135)                            */
    double fnumber;          /* aperture number f# (5.6)                                  */
    double magnification;    /* M (0.39)                                                  */
    double s0_m;             /* working distance camera - object plane, m (0.5)           */
    double zop_star;         /* object plane height z*_OP (0.45)                          */
    double lambda_p_m;       /* wavelength of the light reaching the sensor, m (570e-9)   */
    double beta2;            /* beta^2 of the Gaussian approximation of the Airy disc (3.67) */
    double n_medium;         /* refractive index of the fluid the camera looks into through a
                                flat wall (1.33); 1 = the paper's geometric defocus      */
} rpiv_camera;

/* The seeding. */
typedef struct rpiv_particles {
    double dp_m;        /* mean geometric diameter d_p, m (10e-6)                 */
    double dp_sigma_m;  /* spread of d_p (uniform +- or Gaussian sigma), m (4e-6)  */
    double density_ppp; /* particle images per pixel in the image plane (0.015)     */
} rpiv_particles;

rpiv_camera rpiv_camera_default(void);
rpiv_particles rpiv_particles_default(void);
RPIV_NODISCARD rpiv_status rpiv_camera_check(const rpiv_camera *c);
RPIV_NODISCARD rpiv_status rpiv_particles_check(const rpiv_particles *p);

/* Pixel pitch on the sensor, m. */
double rpiv_camera_pixel_m(const rpiv_camera *c);
/* Lens aperture diameter D_a = f / f#, m. */
double rpiv_camera_aperture_m(const rpiv_camera *c);

/* Defocus distance z' = h |z* - z*_OP| / n_medium, m (apparent distance in air). */
double rpiv_imaging_defocus_m(const rpiv_camera *c, double h_m, double zstar);

/* Effective particle image diameter d_e on the sensor (Eq. "diam"), m:
 * d_e^2 = M^2 d_p^2 + 5.95 (M+1)^2 lambda^2 f#^2 + M^2 z'^2 D_a^2 / (s0 + z')^2. */
double rpiv_imaging_de_m(const rpiv_camera *c, double dp_m, double zdef_m);

/* Peak value of the particle image of Eq. "int" for an emitted intensity Ip = I0 d_p^2:
 * Ip D_a^2 beta^2 / (4 pi d_e^2 (s0 + z')^2), in arbitrary intensity units per m^2 of sensor.
 * The image is peak * exp(-4 beta^2 r^2 / d_e^2); its integral over the sensor plane is
 * Ip D_a^2 / (16 (s0 + z')^2) (independent of d_e). */
double rpiv_imaging_peak(const rpiv_camera *c, double ip, double de_m, double zdef_m);

/* Standard deviation of that Gaussian, m: sigma = d_e / (sqrt(8) beta) (Appendix A). */
double rpiv_imaging_sigma_m(const rpiv_camera *c, double de_m);

#endif /* RPIV_IMAGING_H */
