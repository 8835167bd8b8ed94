/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/preprocess.h - image preprocessing before correlation: contrast-limited adaptive
 * histogram equalisation (CLAHE), high-pass (background removal), intensity capping, local
 * min/max normalisation, inversion. A list of operations is applied in order to each frame.
 *
 * Each operation works on one image in place and depends on nothing but that image and its
 * parameters: frames A and B are processed alike, the result is the same for any thread
 * count (each output pixel or tile is computed by one thread, sums in a fixed order).
 * docs/preprocess.md gives the formulas, the defaults and their reasons. */
#ifndef RPIV_PREPROCESS_H
#define RPIV_PREPROCESS_H

#include "rpiv/error.h"
#include "rpiv/image.h"

#define RPIV_PREPROCESS_MAX_OPS 8

typedef enum rpiv_prep_kind {
    RPIV_PREP_CLAHE = 0,     /* contrast-limited adaptive histogram equalisation, tiles of size */
    RPIV_PREP_HIGHPASS = 1,  /* subtract the background: sliding minimum or Gaussian blur (size) */
    RPIV_PREP_CAP = 2,       /* values above mean + cap_k std set to that level               */
    RPIV_PREP_NORMALIZE = 3, /* (I - local min) / (local max - local min), windows of size    */
    RPIV_PREP_INVERT = 4     /* max + min - I (dark particles on a bright background)         */
} rpiv_prep_kind;

/* The operations' names in enum order (NULL-terminated), as --preprocess spells them. */
extern const char *const rpiv_prep_kind_names[];

typedef enum rpiv_prep_background {
    RPIV_PREP_BG_MIN = 0, /* sliding minimum over size x size, then its moving mean */
    RPIV_PREP_BG_BLUR = 1 /* Gaussian blur of standard deviation size / 4           */
} rpiv_prep_background;

/* The methods' names in enum order (NULL-terminated): "min", "blur". */
extern const char *const rpiv_prep_background_names[];

typedef struct rpiv_prep_op {
    rpiv_prep_kind kind;
    int size_px; /* tile (clahe) or window (highpass, normalize) side; 0: the default */
} rpiv_prep_op;

#define RPIV_PREPROCESS_LIST_MAX 128

typedef struct rpiv_preprocess_params {
    char ops[RPIV_PREPROCESS_LIST_MAX];   /* the list, e.g. "clahe,highpass:21" ("": none) */
    int clahe_tile_px;                    /* default tile side (64)                 */
    double clahe_clip;                    /* clip limit, 0..1 of a tile (0.01)      */
    int clahe_bins;                       /* histogram bins (256)                   */
    double clahe_low_pct, clahe_high_pct; /* the bins' range: percentiles (0, 100) */
    int highpass_px;                      /* default background window (15)         */
    rpiv_prep_background highpass_method; /* (min)                                  */
    double cap_k;                         /* capping level: mean + k std (2)        */
    int normalize_px;                     /* default min/max window (15)            */
} rpiv_preprocess_params;

/* No operation (ops ""); the defaults above for each operation's parameters. */
rpiv_preprocess_params rpiv_preprocess_params_default(void);

/* RPIV_EINVAL naming the field and its range: ops a list rpiv_preprocess_parse reads, sizes
 * 3..1024 px, clip 0..1, bins 16..65536, 0 <= clahe_low_pct < clahe_high_pct <= 100,
 * cap_k 0.1..100. */
RPIV_NODISCARD rpiv_status rpiv_preprocess_params_check(const rpiv_preprocess_params *p);

/* Parse a list "clahe[:TILE],highpass[:SIZE],cap,normalize[:SIZE],invert" (any order, at
 * most RPIV_PREPROCESS_MAX_OPS in all; "" or "none": no operation) into op[0..*n-1].
 * RPIV_EINVAL naming the word at fault and the accepted words. */
RPIV_NODISCARD rpiv_status rpiv_preprocess_parse(const char *list,
                                                 rpiv_prep_op op[RPIV_PREPROCESS_MAX_OPS], int *n);

/* Apply p's operations in order to im, in place, with nthreads threads (0: OpenMP's
 * default). An image of one grey level is left as it is by clahe and normalize. RPIV_EINVAL
 * for bad params, RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status rpiv_preprocess_run(const rpiv_preprocess_params *p, rpiv_image *im,
                                               int nthreads);

#endif /* RPIV_PREPROCESS_H */
