/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/synth.h - synthetic PIV image pairs from the paper's particle-image model. */
#ifndef RPIV_SYNTH_H
#define RPIV_SYNTH_H

#include "rpiv/error.h"
#include "rpiv/flow.h"
#include "rpiv/imaging.h"
#include "rpiv/sheet.h"

typedef struct rpiv_synth_params {
    int width_px, height_px;  /* image size; 0 = the camera's sensor (0)            */
    int pairs;                /* number of pairs (500)                              */
    unsigned long seed;       /* RNG seed (1)                                       */
    double dt_s;              /* pulse separation, s (see docs/config.md)           */
    int bits;                 /* 8, 12 or 16 (16)                                   */
    double peak_counts;       /* grey level of an in-focus particle at I0 = 1 (1000) */
    double background;        /* constant background, counts (100)                */
    double read_noise;        /* Gaussian read noise sigma, counts (5)              */
    int shot_noise;           /* 1: Poisson shot noise (1)                          */
    double margin_px;         /* particle margin around the image, px (16)          */
    double w_star;            /* out-of-plane displacement between frames, z* (0)  */
    int double_frame;         /* 1: write A above B in one file (0)                 */
} rpiv_synth_params;

rpiv_synth_params rpiv_synth_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_synth_params_check(const rpiv_synth_params *p);

/* (The generator API follows; see the synthetic-images issue.) */

#endif /* RPIV_SYNTH_H */
