/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/gpiv_params.h - libgpiv's parameters as the reference benchmarks run it (gpiv_ref.c,
 * gpiv_cli.c, gpiv_noise.c): FFT interrogation of 32 px windows at 50 % overlap (16 px
 * shift) over the whole w x h frame, Gaussian 3-point fit, no weighting, no filter; with
 * deform, libgpiv's own image deformation from 64 px windows. Its default validation. */
#ifndef RPIV_BENCH_GPIV_PARAMS_H
#define RPIV_BENCH_GPIV_PARAMS_H

#include <gpiv.h>
#include <string.h>

static inline void bench_gpiv_params(int w, int h, int deform, GpivPivPar *ppar, GpivValidPar *vpar)
{
    memset(ppar, 0, sizeof *ppar);
    gpiv_piv_default_parameters(ppar, TRUE);
    ppar->col_start = 0;
    ppar->col_end = w - 1;
    ppar->row_start = 0;
    ppar->row_end = h - 1;
    ppar->int_geo = GPIV_AOI;
    ppar->int_size_f = 32;
    ppar->int_size_i = deform ? 64 : 32;
    ppar->int_shift = 16;
    ppar->ifit = GPIV_GAUSS;
    ppar->peak = 1;
    ppar->pre_shift_col = ppar->pre_shift_row = 0;
    ppar->int_scheme = deform ? GPIV_IMG_DEFORM : GPIV_NO_CORR;
    ppar->int_deform = deform;
    ppar->gauss_weight_ia = FALSE;
    ppar->spof_filter = FALSE;
    ppar->print_par = ppar->print_piv = 0;
    memset(vpar, 0, sizeof *vpar);
    gpiv_valid_default_parameters(vpar, TRUE);
}

#endif /* RPIV_BENCH_GPIV_PARAMS_H */
