/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/synth.h - synthetic PIV image pairs from the paper's particle-image model.
 *
 * Model (docs/model.md): particles fill the field of view plus a margin in x, y (only the
 * fluid, 0 < y* < 1, for the duct) and the channel height in z* (uniform, or a tabulated
 * density P(z*)), with diameters uniform in d_p +- spread. Each particle's image in each frame
 * is a Gaussian of diameter d_e(z) (Eq. "diam", sigma = d_e / (sqrt(8) beta)) and amplitude
 * proportional to I0(x*, z*) d_p^2 / (d_e^2 (s0 + z')^2) (Eq. "int"), integrated over each
 * pixel (erf). The random positions are those at the middle of the pulse separation; frame A
 * and frame B are the positions dt/2 before and after, integrated along the flow (exact for
 * path-invariant flows, RK4 otherwise). Then background, Poisson shot noise, Gaussian read
 * noise, rounding and saturation at the bit depth.
 *
 * Determinism: pair `index` depends only on (parameters, seed, index), never on the thread
 * count: the particles of a pair come from one RNG stream derived from (seed, index), the
 * noise of each band of 32 rows from a stream derived from (seed, index, frame, band), and
 * every pixel sums its particles in particle order.
 *
 * Threads: a made rpiv_synth is read-only; every function taking a const rpiv_synth * may be
 * called from several threads at once. The functions use OpenMP inside. */
#ifndef RPIV_SYNTH_H
#define RPIV_SYNTH_H

#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/flow.h"
#include "rpiv/image.h"
#include "rpiv/imaging.h"
#include "rpiv/piv.h"
#include "rpiv/sheet.h"

#include <stddef.h>

typedef struct rpiv_synth_params {
    /* image size; 0 = the camera's sensor (0). Another size is a window of the sensor
     * centred on the field of view (same pixel pitch). */
    int width_px, height_px;
    int pairs;          /* number of pairs (500) */
    unsigned long seed; /* RNG seed (1) */
    double dt_s;        /* pulse separation, s (1e-3: 3.50 px bulk, 7.33 px duct centre) */
    int bits;           /* 8, 12 or 16 (16) */
    /* peak of the continuous Gaussian image of an in-focus particle of the mean diameter at
     * I0 = 1, counts (1000) */
    double peak_counts;
    double background;        /* constant background, counts (100) */
    double read_noise;        /* Gaussian read noise sigma, counts (5) */
    int shot_noise;           /* 1: Poisson shot noise, gain 1 count per photo-electron (1) */
    double margin_px;         /* particle margin around the image, px (16) */
    double w_star;            /* out-of-plane displacement between frames, z* (0) */
    int double_frame;         /* 1: write A above B in one file (0) */
    char flow[RPIV_PATH_MAX]; /* flow spec, see rpiv_synth_flow_parse ("duct") */
    /* z* of the ground truth of z-dependent flows; < 0: the sheet's peak z*_max(x*)
     * (gauss: z*_B; uniform: z*_OP) (-1) */
    double truth_z;
    char pz_profile[RPIV_PATH_MAX]; /* tabulated P(z*) file, "" = uniform ("") */
    double radius_sigma;            /* particle images are drawn out to this many sigma (4) */
    double cutoff_counts;           /* particle images with a lower peak are not drawn (1e-3) */
    int rk_steps;                   /* RK4 steps over dt/2 for flows varying along the path (4) */
} rpiv_synth_params;

rpiv_synth_params rpiv_synth_params_default(void);
/* RPIV_EINVAL naming the field and its range (the flow spec is parsed here). */
RPIV_NODISCARD rpiv_status rpiv_synth_params_check(const rpiv_synth_params *p);

/* Parse a flow spec into a flow of the given kind and amplitudes (see rpiv_flow_kind):
 *   uniform:U,V        (u, v) = (U, V) px
 *   duct[:A]           square duct, A px = bulk displacement (default U_b dt M / pixel)
 *   poiseuille[:A]     plane Poiseuille in z*, A px = bulk displacement (same default)
 *   poiseuille-y:A     parabola across the image rows, A px at the centre row
 *   oseen:A,RC[,CX,CY] Lamb-Oseen vortex, peak swirl A px, core RC px, centre (CX, CY) px
 *                      (default the image centre)
 *   sine:A,L           u = A sin(2 pi y / L) px
 * Only the spec's own numbers are set here: *has_amp says whether A was given (duct,
 * poiseuille) and *has_centre whether CX, CY were; rpiv_synth_new fills the rest from the
 * geometry. RPIV_EINVAL with the spec and what is wrong. */
RPIV_NODISCARD rpiv_status rpiv_synth_flow_parse(const char *spec, rpiv_flow *flow, int *has_amp,
                                                 int *has_centre);

/* The name of a flow kind as rpiv_synth_flow_parse reads it ("?" for an unknown kind). */
const char *rpiv_synth_flow_name(rpiv_flow_kind kind);

/* A generator, ready to make pairs. Read-only once made. */
typedef struct rpiv_synth rpiv_synth;

/* What a generator is made from: the pieces of the experiment it uses (rpiv/config.h maps an
 * experiment onto it, rpiv_config_synth_setup). */
typedef struct rpiv_synth_setup {
    rpiv_camera camera;
    rpiv_particles particles;
    rpiv_channel channel;
    rpiv_sheet_params sheet;
    rpiv_synth_params synth;
} rpiv_synth_setup;

/* Every piece at its module's default (the same values as the default experiment's). */
rpiv_synth_setup rpiv_synth_setup_default(void);

/* Make a generator (the setup is copied, the sheet profile and P(z*) files are read now).
 * flow: the displacement field in px, or NULL to build it from setup->synth.flow and the
 * geometry (duct: y* of each image row, amplitude U_b dt M / pixel; oseen: centre of the
 * image). Errors: RPIV_EINVAL (parameters), RPIV_EIO / RPIV_EFORMAT (profile files),
 * RPIV_ENOMEM. On failure *out is NULL. */
RPIV_NODISCARD rpiv_status rpiv_synth_new(const rpiv_synth_setup *setup, const rpiv_flow *flow,
                                          rpiv_synth **out);
void rpiv_synth_free(rpiv_synth *s); /* NULL is a no-op */

/* Derived figures of a generator. */
typedef struct rpiv_synth_info {
    int width_px, height_px; /* image size */
    double pixel_m;          /* sensor pixel pitch, m */
    double star_per_px;      /* x* (= y*) per image pixel: pixel / (M h) */
    double x0_star, y0_star; /* x*, y* of the image's left and top edges */
    double region[4];        /* particle region x0, y0, x1, y1 in px (edges) */
    size_t nparticles;       /* particles per pair: round(density * region area) */
    double bulk_px;          /* U_b dt M / pixel, px */
    double de_focus_px;      /* d_e of a particle of the mean d_p in focus, px */
    double sigma_focus_px;   /* its Gaussian sigma, px */
    rpiv_flow flow;          /* the displacement field used */
} rpiv_synth_info;
void rpiv_synth_get_info(const rpiv_synth *s, rpiv_synth_info *info);

/* One particle: position (px, pixel centres at integers; x along columns, y down rows),
 * height z* and geometric diameter. */
typedef struct rpiv_synth_particle {
    double x, y;
    double z;
    double dp_m;
} rpiv_synth_particle;

/* The particles of pair `index` at the middle of the pulse separation (*n of them, equal to
 * info.nparticles). Release *out with rpiv_synth_particles_free(). RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status rpiv_synth_particles_new(const rpiv_synth *s, unsigned long index,
                                                    rpiv_synth_particle **out, size_t *n);
void rpiv_synth_particles_free(rpiv_synth_particle *p); /* NULL is a no-op */

/* Position of a particle tau * dt after its mid-time position `mid` (tau = -0.5: frame A,
 * +0.5: frame B), integrated along the flow; z* moves by tau * w_star. */
void rpiv_synth_advect(const rpiv_synth *s, const rpiv_synth_particle *mid, double tau,
                       rpiv_synth_particle *out);

/* The image model for one particle (in the frame where it is at p): *amp_counts, the peak of
 * the continuous Gaussian (Eq. "int"), peak_counts * I0(x*, z*) (d_p/d_p0)^2 (d_e0/d_e)^2
 * (s0/(s0+z'))^2 with d_e0 = d_e(d_p0, z' = 0); *de_px, d_e of Eq. "diam" in pixels;
 * *sigma_px = d_e / (sqrt(8) beta) in pixels. Any of the outputs may be NULL. */
void rpiv_synth_image_model(const rpiv_synth *s, const rpiv_synth_particle *p, double *amp_counts,
                            double *de_px, double *sigma_px);

/* Add the noiseless, unquantised images of n particles (at the given positions) to im, which
 * must be the generator's size (RPIV_ESIZE otherwise). RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status rpiv_synth_render(const rpiv_synth *s, const rpiv_synth_particle *p,
                                             size_t n, rpiv_image *im);

/* Pair `index` (0-based; the CLI's file pair_00001 is index 0) into a and b, which must be the
 * generator's size (RPIV_ESIZE otherwise); their bits are set to the bit depth. Values are
 * integer counts in 0 .. 2^bits - 1. RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status rpiv_synth_pair(const rpiv_synth *s, unsigned long index, rpiv_image *a,
                                           rpiv_image *b);
/* The same pair as one double-frame image of width w and height 2h (A above B). */
RPIV_NODISCARD rpiv_status rpiv_synth_pair_double(const rpiv_synth *s, unsigned long index,
                                                  rpiv_image *ab);

/* Fill the field's u, v (px over dt) with the ground truth at its grid points (any grid, e.g.
 * the final pass's of rpiv_piv_grid, as `rpiv synth` writes truth.txt): the flow's
 * displacement at (x, y) and z* = truth_z (or the sheet's peak there, see truth_z); flag
 * RPIV_FLAG_MASKED where there is no fluid (duct rows outside 0 < y* < 1), else VALID;
 * peak_ratio and corr are set to 0; scale_mm_per_px and dt_s are set. */
void rpiv_synth_truth(const rpiv_synth *s, rpiv_field *f);

#endif /* RPIV_SYNTH_H */
