/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/deform_block.h - the vector blocks of deform_row, included by src/deform.c once per
 * vector width with DB_VL (lanes), DB_VF / DB_VI (float / int32 vector types of DB_VL lanes),
 * DB_(name) (the suffixed name), DB_TARGET (the function's target attribute),
 * DB_ALLZERO(e) (1 if every lane of the DB_VI e is 0) and DB_GATHER(c, idx) (the DB_VF of
 * c[idx[j]]) defined; it undefines them. Lane j of a block
 * is pixel x + j and performs the float operations of locate, bweights and sample_w for that pixel,
 * in the same order. */

ALWAYS_INLINE DB_TARGET DB_VF DB_(loadv)(const float *p)
{
    DB_VF v;
    memcpy(&v, p, sizeof v);
    return v;
}

/* Lanes of b where m is all ones, of a where it is zero. */
ALWAYS_INLINE DB_TARGET DB_VF DB_(selv)(DB_VI m, DB_VF b, DB_VF a)
{
    return (DB_VF)(((DB_VI)b & m) | ((DB_VI)a & ~m));
}

/* floor and fraction of every lane, as ifloor and locate compute them. */
ALWAYS_INLINE DB_TARGET void DB_(vfloor)(DB_VF o, DB_VI *fi, DB_VF *t)
{
#ifdef DB_FLOOR
    /* floor(o) is exact, and so is its conversion: the same integer and fraction */
    const DB_VF f = DB_FLOOR(o);
    *fi = __builtin_convertvector(f, DB_VI);
    *t = o - f;
#else
    DB_VI i = __builtin_convertvector(o, DB_VI);
    DB_VF f = __builtin_convertvector(i, DB_VF);
    i += (DB_VI)(f > o); /* -1 where the truncation went up */
    *fi = i;
    *t = o - __builtin_convertvector(i, DB_VF);
#endif
}

/* The tap weights of every lane, as bweights computes them. */
ALWAYS_INLINE DB_TARGET void DB_(weights)(DB_VF t, DB_VF wt[4])
{
    DB_VF t2 = t * t, t3 = t2 * t, s = 1.0f - t;
    wt[0] = s * s * s * (1.0f / 6.0f);
    wt[1] = (2.0f / 3.0f) - t2 + 0.5f * t3;
    wt[3] = t3 * (1.0f / 6.0f);
    wt[2] = 1.0f - wt[0] - wt[1] - wt[3];
}

/* The 4 x 4 taps of the block from base (row and column of its lowest first tap): lanes with
 * mx (my) set take their taps one column (row) further; sx (sy) says whether any lane does.
 * Summed as sample_w sums: over the rows first, then the columns. */
ALWAYS_INLINE DB_TARGET DB_VF DB_(taps)(const float *base, size_t sw, int sx, int sy, DB_VI mx,
                                        DB_VI my, const DB_VF wx[4], const DB_VF wy[4])
{
    DB_VF t[4];
    for (int k = 0; k < 4; k++) {
        DB_VF acc = {0};
        for (int m = 0; m < 4; m++) {
            const float *r = base + (size_t)m * sw + (size_t)k;
            DB_VF s = DB_(loadv)(r);
            if (sx)
                s = DB_(selv)(mx, DB_(loadv)(r + 1), s);
            if (sy) {
                DB_VF s2 = DB_(loadv)(r + sw);
                if (sx)
                    s2 = DB_(selv)(mx, DB_(loadv)(r + sw + 1), s2);
                s = DB_(selv)(my, s2, s);
            }
            acc = m ? acc + wy[m] * s : wy[m] * s;
        }
        t[k] = acc;
    }
    return (wx[0] * t[0] + wx[1] * t[1]) + (wx[2] * t[2] + wx[3] * t[3]);
}

/* taps for the blocks whose integer parts differ by 1 (sx, sy: along x, y), into out. */
static DB_TARGET __attribute__((noinline)) void DB_(taps_mixed)(const float *base, size_t sw,
                                                                int sx, int sy, const DB_VI *mx,
                                                                const DB_VI *my, const DB_VF wx[4],
                                                                const DB_VF wy[4], float *out)
{
    DB_VF r;
    if (!sy)
        r = DB_(taps)(base, sw, 1, 0, *mx, *my, wx, wy);
    else if (!sx)
        r = DB_(taps)(base, sw, 0, 1, *mx, *my, wx, wy);
    else
        r = DB_(taps)(base, sw, 1, 1, *mx, *my, wx, wy);
    memcpy(out, &r, sizeof r);
}

/* taps for the blocks whose integer parts spread over more than 1 (a noisy predictor, as in
 * badly lit parts of an image): every lane's 16 taps fetched by index (idx: the lane's first
 * tap, counted from c), summed as taps() sums them. */
static DB_TARGET __attribute__((noinline)) void DB_(taps_gather)(const float *c, size_t sw,
                                                                 DB_VI idx, const DB_VF wx[4],
                                                                 const DB_VF wy[4], float *out)
{
    DB_VF t[4];
    for (int k = 0; k < 4; k++) {
        DB_VF acc = {0};
        for (int m = 0; m < 4; m++) {
            DB_VF s = DB_GATHER(c, idx + (int32_t)((size_t)m * sw + (size_t)k));
            acc = m ? acc + wy[m] * s : wy[m] * s;
        }
        t[k] = acc;
    }
    DB_VF r = (wx[0] * t[0] + wx[1] * t[1]) + (wx[2] * t[2] + wx[3] * t[3]);
    memcpy(out, &r, sizeof r);
}

/* The samples of a frame (coefficients c) at the pixels x..x+DB_VL-1 of row y offset by
 * (ox, oy), into out[0..DB_VL-1], if all their taps lie inside the image (contiguous loads
 * when their integer offsets differ by at most 1 across the block, gathered otherwise);
 * returns 0 (nothing written) otherwise. */
ALWAYS_INLINE DB_TARGET int DB_(block)(const float *c, int w, int h, int x, int y, DB_VF ox,
                                       DB_VF oy, float *out)
{
    DB_VI fx, fy;
    DB_VF tx, ty;
    DB_(vfloor)(ox, &fx, &tx);
    DB_(vfloor)(oy, &fy, &ty);
    int lx = fx[0], hx = fx[0], ly = fy[0], hy = fy[0];
    if (!DB_ALLZERO((fx - lx) | (fy - ly))) /* rarely: the predictor varies slowly */
        for (int j = 1; j < DB_VL; j++) {
            lx = fx[j] < lx ? fx[j] : lx;
            hx = fx[j] > hx ? fx[j] : hx;
            ly = fy[j] < ly ? fy[j] : ly;
            hy = fy[j] > hy ? fy[j] : hy;
        }
    const int sx = hx - lx, sy = hy - ly;
    if (x + lx - 1 < 0 || x + DB_VL - 1 + hx + 2 > w - 1 || y + ly - 1 < 0 || y + hy + 2 > h - 1)
        return 0;
    DB_VF wx[4], wy[4], r;
    DB_(weights)(tx, wx);
    DB_(weights)(ty, wy);
    const size_t sw = (size_t)w;
    if (sx > 1 || sy > 1) {
        /* pixel indices fit in int32: images hold fewer than 2^31 pixels (img_check_size) */
        DB_VI lane;
        for (int j = 0; j < DB_VL; j++)
            lane[j] = j;
        const DB_VI idx = (y - 1 + fy) * (int32_t)w + (x - 1 + fx + lane);
        const DB_VF cx[4] = {wx[0], wx[1], wx[2], wx[3]}, cy[4] = {wy[0], wy[1], wy[2], wy[3]};
        DB_(taps_gather)(c, sw, idx, cx, cy, out);
        return 1;
    }
    const float *base = c + (size_t)(y + ly - 1) * sw + (size_t)(x + lx - 1);
    if (sx || sy) { /* out of line: the common case keeps its registers */
        const DB_VI mx = fx != lx, my = fy != ly;
        const DB_VF cx[4] = {wx[0], wx[1], wx[2], wx[3]}, cy[4] = {wy[0], wy[1], wy[2], wy[3]};
        DB_(taps_mixed)(base, sw, sx, sy, &mx, &my, cx, cy, out);
        return 1;
    }
    const DB_VI zero = {0};
    r = DB_(taps)(base, sw, 0, 0, zero, zero, wx, wy);
    memcpy(out, &r, sizeof r);
    return 1;
}

/* The blocks of row y from x0 while a whole block fits before x1 (pu, pv: the predictor
 * from x0); blocks a frame cannot take go through pixels(). Returns the first column left. */
static DB_TARGET int DB_(blocks)(const float *coef_a, const float *coef_b, int w, int h, float c,
                                 const float *pu, const float *pv, int x0, int x1, int y,
                                 float fill_a, float fill_b, float *ra, float *rb)
{
    int x = x0;
    for (; x + DB_VL <= x1; x += DB_VL) {
        const DB_VF hx = 0.5f * DB_(loadv)(pu + (x - x0)), hy = 0.5f * DB_(loadv)(pv + (x - x0));
        const DB_VF cc = (DB_VF){0} + c;
        /* the tap row the next row of output brings in where the predictor's integer part
         * is 0 (y + 3), 64 columns ahead: without it the blocks wait on the frames (the
         * hardware prefetcher does not keep up with the 8 tap rows in use; bench_deform
         * 30 -> 26-28 ms per pair) */
        if (x + 64 < w && y + 3 < h) {
            __builtin_prefetch(coef_a + (size_t)(y + 3) * (size_t)w + (size_t)(x + 64));
            __builtin_prefetch(coef_b + (size_t)(y + 3) * (size_t)w + (size_t)(x + 64));
        }
        int da = DB_(block)(coef_a, w, h, x, y, cc - hx, cc - hy, ra + x);
        int db = DB_(block)(coef_b, w, h, x, y, cc + hx, cc + hy, rb + x);
        if (!da || !db)
            pixels(coef_a, coef_b, w, h, c, pu + (x - x0), pv + (x - x0), x, x + DB_VL, y, fill_a,
                   fill_b, ra, rb, da, db);
    }
    return x;
}

/* The predictor at the columns [xx, xx + DB_VL) from the combined grid row t, with the
 * first tap i0 common to these columns: per column, the arithmetic of deform_pred_row_ref. */
ALWAYS_INLINE DB_TARGET void DB_(pred_block)(const rpiv_deform_pred *p, const float *t, int i0,
                                             int xx, float *o)
{
    const size_t sw = (size_t)p->w;
    const float *w0 = p->wxs + (size_t)xx;
    const float a0 = t[i0], a1 = t[i0 + 1], a2 = t[i0 + 2], a3 = t[i0 + 3];
    DB_VF r = DB_(loadv)(w0) * a0 + DB_(loadv)(w0 + sw) * a1 + DB_(loadv)(w0 + 2 * sw) * a2 +
              DB_(loadv)(w0 + 3 * sw) * a3;
    memcpy(o, &r, sizeof r);
}

/* The columns x0..x1-1 of rpiv_deform_pred_row from the combined grid rows tu, tv. Along a
 * run of columns sharing their first tap, the 4 grid values are common and the weights are
 * loaded by tap: DB_VL columns at a time, the last block of a run of at least DB_VL columns
 * overlapping the previous one (it recomputes the same values). */
static DB_TARGET void DB_(pred_runs)(const rpiv_deform_pred *p, const float *tu, const float *tv,
                                     int x0, int x1, float *u, float *v)
{
    for (int x = x0; x < x1;) {
        const int e = p->runend[x] < x1 ? p->runend[x] : x1, i0 = p->ix[x];
        int xx = x;
        for (; xx + DB_VL <= e; xx += DB_VL) {
            DB_(pred_block)(p, tu, i0, xx, u + (xx - x0));
            DB_(pred_block)(p, tv, i0, xx, v + (xx - x0));
        }
        if (xx < e && e - x >= DB_VL) {
            DB_(pred_block)(p, tu, i0, e - DB_VL, u + (e - DB_VL - x0));
            DB_(pred_block)(p, tv, i0, e - DB_VL, v + (e - DB_VL - x0));
        } else
            for (; xx < e; xx++) {
                const float *wx = p->wx + 4 * (size_t)xx, *a = tu + i0, *b = tv + i0;
                u[xx - x0] = wx[0] * a[0] + wx[1] * a[1] + wx[2] * a[2] + wx[3] * a[3];
                v[xx - x0] = wx[0] * b[0] + wx[1] * b[1] + wx[2] * b[2] + wx[3] * b[3];
            }
        x = e;
    }
}

#undef DB_VL
#undef DB_VF
#undef DB_VI
#undef DB_
#undef DB_TARGET
#undef DB_ALLZERO
#undef DB_GATHER
#undef DB_FLOOR
