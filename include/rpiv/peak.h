/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/peak.h - correlation peak: integer search, sub-pixel fit, peak ratio.
 *
 * Planes are in circular (FFT) order, as rpiv_xcorr_run leaves them: element (i, j) of a
 * w x h plane, plane[j * w + i], holds the correlation at shift (sx, sy) with sx = i for
 * i < w/2 and sx = i - w otherwise (likewise sy). Neighbours wrap around, as the circular
 * correlation does. A peak at shift (dx, dy) means b(x + dx, y + dy) ~ a(x, y): the pattern of
 * window a moved by (+dx, +dy) in window b. */
#ifndef RPIV_PEAK_H
#define RPIV_PEAK_H

typedef enum rpiv_subpixel {
    RPIV_SUBPIXEL_GAUSS = 0,    /* 3-point Gaussian fit in x and y           */
    RPIV_SUBPIXEL_PARABOLA = 1, /* 3-point parabola                          */
    RPIV_SUBPIXEL_CENTROID = 2, /* 3x3 centroid                              */
    RPIV_SUBPIXEL_SPLINE = 3,   /* continuous maximum of a cubic spline through the logarithm
                                   of the 7x7 samples (5x5 if one of those is <= 0); the
                                   3-point Gaussian where it cannot (a sample <= 0 in the 5x5,
                                   no maximum within 1 px; docs/piv.md "Peak")              */
    RPIV_SUBPIXEL_AUTO = 4      /* spline on sums of correlation (ensemble runs, the CCM),
                                   gauss on single pairs (the engine's default)           */
} rpiv_subpixel;

/* The methods' names in enum order (NULL-terminated): "gauss", "parabola", "centroid",
 * "spline", "auto". */
extern const char *const rpiv_subpixel_names[];

/* The estimator that `method` stands for on a sum of correlation (ensemble = 1: an ensemble
 * run, the CCM's model of one) or on a single pair (0): AUTO becomes SPLINE or GAUSS, any
 * other method itself. rpiv_peak_find takes AUTO as GAUSS. */
rpiv_subpixel rpiv_subpixel_resolve(rpiv_subpixel method, int ensemble);

/* The peak ratio reported when there is no second peak (or it is not positive). */
#define RPIV_PEAK_RATIO_MAX 1000.0f

/* Half-width of the neighbourhood of the highest peak that the second peak must lie outside:
 * the second peak is the highest local maximum whose shift differs from the first by more
 * than this in x or y (a 5 x 5 block is excluded). */
#define RPIV_PEAK_EXCLUDE 2
/* The largest plane side the search takes (as rpiv_xcorr's windows). */
#define RPIV_PEAK_MAX_SIZE 4096

typedef struct rpiv_peak {
    double dx, dy; /* sub-pixel shift of the highest peak, px                          */
    int ix, iy;    /* integer shift of the highest peak                                */
    float value;   /* plane value at the integer peak                                  */
    float second;  /* value of the second peak (0 if none)                             */
    float ratio;   /* value / second; RPIV_PEAK_RATIO_MAX if second <= 0 or none       */
    int fit_ok;    /* 0: the sub-pixel fit was impossible (flat or non-finite plane);
                      dx, dy are then the integer shift                               */
} rpiv_peak;

/* Find the highest value of a w x h plane among shifts with |sx| <= max_shift and
 * |sy| <= max_shift (max_shift <= 0: the whole plane), refine it with `method`, and find
 * the second peak over the same shifts. 3 <= w, h <= RPIV_PEAK_MAX_SIZE (other sizes: no
 * peak, fit_ok 0 and value 0). Never fails; see fit_ok. */
void rpiv_peak_find(const float *plane, int w, int h, int max_shift, rpiv_subpixel method,
                    rpiv_peak *out);

/* rpiv_peak_find over the whole plane (max_shift 0), given the plane's column maxima:
 * colmax[i] = the largest value of column i over the rows, taken row after row as
 * m = v > m ? v : m from -inf (rpiv_xcorr_work's colmax). The same result, without the pass
 * over the plane that finds them. */
void rpiv_peak_find_cm(const float *plane, int w, int h, const float *colmax, rpiv_subpixel method,
                       rpiv_peak *out);

/* The peak near the origin, for a pass whose windows were shifted by a predictor: the
 * highest local maximum (>= its 8 neighbours) among shifts with |sx| <= radius and |sy| <=
 * radius, refined with `method`; the plane's highest value if no local maximum lies there
 * (or radius <= 0, or the square covers the plane). The second peak and the ratio are those
 * of the whole plane: the highest local maximum outside the chosen peak's neighbourhood,
 * which may be higher than it (ratio < 1: a higher peak lies farther away). colmax: the
 * plane's column maxima as rpiv_peak_find_cm takes them, or NULL. */
void rpiv_peak_find_near(const float *plane, int w, int h, int radius, const float *colmax,
                         rpiv_subpixel method, rpiv_peak *out);

/* The sub-pixel offset, in -1..1 px, of a peak from three samples c(-1), c(0), c(+1) with
 * c(0) the largest: Gaussian (exact for samples of exp(-(x-x0)^2/k)), parabola (exact for a
 * parabola). The Gaussian falls back to the parabola when a sample is not positive. *ok is 0
 * (and the offset 0) when the three samples do not make a maximum. CENTROID is not a 3-point
 * method here: it gives the 3-sample centroid (negative samples taken as 0); SPLINE and AUTO
 * give the Gaussian. */
double rpiv_peak_fit3(double cm, double c0, double cp, rpiv_subpixel method, int *ok);

#endif /* RPIV_PEAK_H */
