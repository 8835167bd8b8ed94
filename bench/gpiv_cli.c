/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/gpiv_cli.c - libgpiv as a whole process, for bench_gpiv_ref's whole-process
 * comparison (issue 15): reads a double-frame image (PGM or PNG) with libgpiv's own reader (frame A
 * on top, frame B below, as libgpiv's cross-correlation images are stored), runs its single-pass
 * FFT interrogation (32 px windows, 50 % overlap, Gaussian fit, no deformation: the parameters of
 * bench/gpiv_ref.c) and writes the vectors as text with libgpiv's writer. Debian has no
 * libgpiv command-line tools, so this stands for one.
 *
 *     gpiv_cli IN.png OUT.txt
 *
 * Exit 0 on success, 1 with a one-line message on stderr otherwise. */
#include "gpiv_params.h"

#include <gpiv.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: gpiv_cli IN.png OUT.txt\n");
        return 1;
    }
    GpivImage *img = gpiv_fread_image(argv[1]);
    if (!img) {
        fprintf(stderr, "gpiv_cli: %s: libgpiv cannot read the image\n", argv[1]);
        return 1;
    }
    int w = (int)img->header->ncolumns, h = (int)img->header->nrows;
    GpivPivPar ppar;
    GpivValidPar vpar;
    bench_gpiv_params(w, h, FALSE, &ppar, &vpar);
    const char *gt = getenv("BENCH_GPIV_THREADS");
    omp_set_num_threads(gt && atoi(gt) > 0 ? atoi(gt) : 1);
    GpivPivData *pd = gpiv_piv_interrogate_img(img, &ppar, &vpar, FALSE);
    if (!pd) {
        fprintf(stderr, "gpiv_cli: %s: libgpiv's interrogation failed\n", argv[1]);
        gpiv_free_img(img);
        return 1;
    }
    gchar *err = gpiv_fwrite_pivdata(argv[2], pd, FALSE);
    if (err) {
        fprintf(stderr, "gpiv_cli: %s: %s\n", argv[2], err);
        gpiv_free_pivdata(pd);
        gpiv_free_img(img);
        return 1;
    }
    gpiv_free_pivdata(pd);
    gpiv_free_img(img);
    return 0;
}
