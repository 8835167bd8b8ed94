/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/xcorr_pack.h - the glue around the transforms of xcorr.c (packing, cross-spectra,
 * unpacking), included by src/xcorr.c once per vector width with these defined:
 *   XG_VL          lanes (4 or 8 floats), XG_VF its float vector type, XG_VU the same type
 *                  unaligned and allowed to alias floats;
 *   XG_(name)      the name with the width's suffix; XG_TARGET the functions' target attribute;
 *   XG_REV(r)      the vector's complex numbers in reverse order;
 *   XG_SWAP(x)     real and imaginary parts swapped;
 *   XG_PE(a, b)    (a0, b0, a2, b2, ...) and XG_PO(a, b) (a1, b1, a3, b3, ...);
 *   XG_ZLO(a, b)   (a0, b0, a1, b1, ...) over the low half, XG_ZHI(a, b) the high half;
 *   XG_EV(a, b)    the even elements of a then b, XG_OD(a, b) the odd ones.
 * It undefines them. Both widths perform the same float operations on the same elements in
 * the same order, and their sums run in the same 8 logical lanes (two 4-wide vectors stand
 * for one 8-wide one), so the AVX2 and the SSE2 / NEON code give the same bits. */

#define XG_LD(p)    (*(const XG_VU *)(p))
#define XG_ST(p, v) (*(XG_VU *)(p) = (v))
#define XG_H        (8 / XG_VL) /* vectors per 8 logical lanes */

/* Pack a w x h window pair into z as a + i b (rows of a stride_a floats apart, of b
 * stride_b), remove each window's mean; the energies sum a'^2, sum b'^2 go to e[0], e[1].
 * Sums run in 8 lanes combined in a fixed order (even lanes a, odd lanes b): the result
 * depends on nothing but the data. Float lanes are enough: a lane sums at most 64 x 64 / 4
 * grey levels of 16 bits, and the mean and energy only need ~1e-6 relative precision. */
static XG_TARGET void XG_(load_pack)(float *restrict z, const float *a, size_t stride_a,
                                     const float *b, size_t stride_b, int w, int h, double e[2])
{
    const size_t n2 = 2 * (size_t)w * (size_t)h;
    XG_VF sa[XG_H], sb[XG_H];
    for (int q = 0; q < XG_H; q++)
        sa[q] = sb[q] = (XG_VF){0};
    double s[2] = {0, 0};
    for (int j = 0; j < h; j++) {
        const float *ra = a + (size_t)j * stride_a, *rb = b + (size_t)j * stride_b;
        float *d = z + 2 * (size_t)j * (size_t)w;
        int i = 0;
        for (; i + 8 <= w; i += 8)
            for (int q = 0; q < XG_H; q++) {
                const int o = i + q * XG_VL;
                XG_VF va = XG_LD(ra + o), vb = XG_LD(rb + o);
                sa[q] += va;
                sb[q] += vb;
                XG_ST(d + 2 * o, XG_ZLO(va, vb));
                XG_ST(d + 2 * o + XG_VL, XG_ZHI(va, vb));
            }
        for (; i < w; i++) {
            d[2 * i] = ra[i];
            d[2 * i + 1] = rb[i];
            s[0] += (double)ra[i];
            s[1] += (double)rb[i];
        }
    }
    for (int l = 0; l < 8; l++) {
        s[0] += (double)sa[l / XG_VL][l % XG_VL];
        s[1] += (double)sb[l / XG_VL][l % XG_VL];
    }
    const double n = (double)(n2 / 2);
    const float ma = (float)(s[0] / n), mb = (float)(s[1] / n);
    XG_VF m;
    for (int l = 0; l < XG_VL; l++)
        m[l] = l & 1 ? mb : ma;
    /* four accumulators of 8 lanes: one would make the loop wait on each addition */
    XG_VF sq[4][XG_H];
    for (int r = 0; r < 4; r++)
        for (int q = 0; q < XG_H; q++)
            sq[r][q] = (XG_VF){0};
    size_t k = 0;
    for (; k + 32 <= n2; k += 32)
        for (int r = 0; r < 4; r++)
            for (int q = 0; q < XG_H; q++) {
                float *p = z + k + 8 * (size_t)r + (size_t)(q * XG_VL);
                XG_VF v = XG_LD(p) - m;
                XG_ST(p, v);
                sq[r][q] += v * v;
            }
    for (; k + 8 <= n2; k += 8)
        for (int q = 0; q < XG_H; q++) {
            float *p = z + k + (size_t)(q * XG_VL);
            XG_VF v = XG_LD(p) - m;
            XG_ST(p, v);
            sq[0][q] += v * v;
        }
    e[0] = e[1] = 0;
    for (; k < n2; k++) {
        z[k] -= k & 1 ? mb : ma;
        e[k & 1] += (double)z[k] * (double)z[k];
    }
    for (int q = 0; q < XG_H; q++)
        sq[0][q] = (sq[0][q] + sq[1][q]) + (sq[2][q] + sq[3][q]);
    for (int l = 0; l < 8; l++)
        e[l & 1] += (double)sq[0][l / XG_VL][l % XG_VL];
}

/* Spectra f0 and f1 of packed pairs a + i b -> t = c0 S0 + i c1 S1 (see cross_pack in
 * xcorr.c for the formulas), XG_VL / 2 complex at a time where the width allows.
 *
 * S0 and S1 are Hermitian, so t(-k) = c0 conj S0(k) + i c1 conj S1(k): where w is a multiple
 * of 4 and h even, rows 0 and h/2 (their own partners) are computed whole, and each row ky of
 * 1 .. h/2 - 1 also writes its partner row h - ky, half the arithmetic and reads. The values
 * are the bits computing row h - ky itself would give: there P and R trade places, the
 * products are the same, Re S's sum is commutative and Im S is negated exactly. A partner
 * row is written reversed, so the vector at kx = 0 reaches one complex past the row's end
 * (its column 0 is stored apart): into row h - ky + 1, written afterwards because ky goes
 * down, or for ky = 1 into the spare complex after t. */
static XG_TARGET void XG_(cross_pack)(const float *f0, const float *f1, float *restrict t, int w,
                                      int h, float c0, float c1)
{
    const size_t sw = 2 * (size_t)w; /* floats per spectrum row */
    const int nc = XG_VL / 2;        /* complex per vector */
    const float a0 = 0.5f * c0, b0 = 0.25f * c0, a1 = 0.5f * c1, b1 = 0.25f * c1;
    XG_VF ca, cb, da, db; /* t(k) = ca m0 + cb m1, t(-k) = da m0 + db m1 */
    for (int l = 0; l < XG_VL; l += 2) {
        ca[l] = a0;
        ca[l + 1] = b0;
        cb[l] = -b1;
        cb[l + 1] = a1;
        da[l] = a0;
        da[l + 1] = -b0;
        db[l] = b1;
        db[l + 1] = a1;
    }
    const int half = w % 4 == 0 && h % 2 == 0;
    const int nrows = half ? h / 2 + 1 : h;
    for (int r = 0; r < nrows; r++) {
        /* halved: rows 0, h/2, then h/2 - 1 down to 1 with their partners */
        const int ky = !half ? r : r == 0 ? 0 : r == 1 ? h / 2 : h / 2 + 1 - r;
        const int pair = half && r >= 2;
        const size_t kr = (size_t)(ky ? h - ky : 0);
        const float *p0 = f0 + (size_t)ky * sw, *q0 = f0 + kr * sw;
        const float *p1 = f1 + (size_t)ky * sw, *q1 = f1 + kr * sw;
        float *tr = t + (size_t)ky * sw, *tp = t + kr * sw;
        int kx = 0;
        if (w % 4 == 0)
            for (; kx < w; kx += nc) {
                /* R at kx.. is the partner row at w-kx.. backwards (index w is index 0) */
                const size_t o = 2 * (size_t)(w - kx - (nc - 1));
                XG_VF r0 = XG_REV(XG_LD(q0 + o)), r1 = XG_REV(XG_LD(q1 + o));
                if (!kx) {
                    r0[0] = q0[0];
                    r0[1] = q0[1];
                    r1[0] = q1[0];
                    r1[1] = q1[1];
                }
                XG_VF x0 = XG_LD(p0 + 2 * kx), x1 = XG_LD(p1 + 2 * kx);
                XG_VF y0 = r0 * r0 - x0 * x0, y1 = r1 * r1 - x1 * x1;
                x0 = r0 * XG_SWAP(x0);
                x1 = r1 * XG_SWAP(x1);
                /* m0 = (Re S0, Im S0) x 2 and x 4, m1 = (Im S1, Re S1) likewise */
                XG_VF m0 = XG_PE(x0, y0) + XG_PO(x0, y0), m1 = XG_PE(y1, x1) + XG_PO(y1, x1);
                XG_ST(tr + 2 * kx, ca * m0 + cb * m1);
                if (pair) {
                    XG_VF u = XG_REV(da * m0 + db * m1);
                    XG_ST(tp + o, u);
                    if (!kx) {
                        tp[0] = u[XG_VL - 2];
                        tp[1] = u[XG_VL - 1];
                    }
                }
            }
        for (; kx < w; kx++) { /* widths that are not a multiple of 4 */
            const size_t i = 2 * (size_t)kx, rx = 2 * (size_t)(kx ? w - kx : 0);
            float pr = p0[i], pi = p0[i + 1], rr = q0[rx], ri = q0[rx + 1];
            float sr0 = rr * pi + ri * pr, si0 = (rr * rr - pr * pr) + (ri * ri - pi * pi);
            pr = p1[i];
            pi = p1[i + 1];
            rr = q1[rx];
            ri = q1[rx + 1];
            float sr1 = rr * pi + ri * pr, si1 = (rr * rr - pr * pr) + (ri * ri - pi * pi);
            tr[i] = a0 * sr0 - b1 * si1;
            tr[i + 1] = b0 * si0 + a1 * sr1;
        }
    }
    t[0] = t[1] = 0;
}

/* a > m ? a : m, lane by lane (m where a is NaN) */
static inline XG_TARGET XG_VF XG_(gtmax)(XG_VF a, XG_VF m)
{
    const __typeof__(a > m) k = a > m;
    return (XG_VF)((k & (__typeof__(k))a) | (~k & (__typeof__(k))m));
}

/* The columns [i0, i0 + nv XG_VL) of the packed planes t (w x h complex) into plane0, plane1
 * (may be NULL) and their maxima over the rows into cm0, cm1; nv = 4 or 1, the maxima held
 * in registers down the rows. */
#define XG_UNPACK_COLS(nv)                                                                         \
    do {                                                                                           \
        XG_VF m0[nv], m1[nv];                                                                      \
        for (int q = 0; q < (nv); q++)                                                             \
            m0[q] = m1[q] = ninf;                                                                  \
        for (int j = 0; j < h; j++) {                                                              \
            const size_t o = (size_t)j * (size_t)w + (size_t)i0;                                   \
            for (int q = 0; q < (nv); q++) {                                                       \
                const float *tp = t + 2 * (o + (size_t)(q * XG_VL));                               \
                XG_VF u = XG_LD(tp), v = XG_LD(tp + XG_VL), a = s0 * XG_EV(u, v);                  \
                XG_ST(plane0 + o + q * XG_VL, a);                                                  \
                m0[q] = XG_(gtmax)(a, m0[q]);                                                      \
                if (plane1) {                                                                      \
                    XG_VF b = s1 * XG_OD(u, v);                                                    \
                    XG_ST(plane1 + o + q * XG_VL, b);                                              \
                    m1[q] = XG_(gtmax)(b, m1[q]);                                                  \
                }                                                                                  \
            }                                                                                      \
        }                                                                                          \
        for (int q = 0; q < (nv); q++) {                                                           \
            XG_ST(cm0 + i0 + q * XG_VL, m0[q]);                                                    \
            XG_ST(cm1 + i0 + q * XG_VL, m1[q]);                                                    \
        }                                                                                          \
        i0 += (nv)*XG_VL;                                                                          \
    } while (0)

/* The packed planes t (w x h complex) -> plane0 = Re t * s0 and plane1 = Im t * s1 (plane1
 * may be NULL), and their column maxima cm0, cm1 (w each; cm1 -inf without plane1) over the
 * rows, as rpiv_peak_find_cm takes them: m = v > m ? v : m from -inf, row after row. By
 * blocks of columns, the maxima in registers. */
static XG_TARGET void XG_(unpack)(const float *t, int w, int h, float s0, float s1,
                                  float *restrict plane0, float *restrict plane1,
                                  float *restrict cm0, float *restrict cm1)
{
    XG_VF ninf;
    for (int l = 0; l < XG_VL; l++)
        ninf[l] = -INFINITY;
    int i0 = 0;
    while (i0 + 4 * XG_VL <= w)
        XG_UNPACK_COLS(4);
    while (i0 + XG_VL <= w)
        XG_UNPACK_COLS(1);
    for (int i = i0; i < w; i++) {
        cm0[i] = cm1[i] = -INFINITY;
        for (int j = 0; j < h; j++) {
            const size_t o = (size_t)j * (size_t)w + (size_t)i;
            plane0[o] = t[2 * o] * s0;
            cm0[i] = plane0[o] > cm0[i] ? plane0[o] : cm0[i];
            if (plane1) {
                plane1[o] = t[2 * o + 1] * s1;
                cm1[i] = plane1[o] > cm1[i] ? plane1[o] : cm1[i];
            }
        }
    }
}
#undef XG_UNPACK_COLS

#undef XG_LD
#undef XG_ST
#undef XG_H
#undef XG_VL
#undef XG_VF
#undef XG_VU
#undef XG_
#undef XG_TARGET
#undef XG_REV
#undef XG_SWAP
#undef XG_PE
#undef XG_PO
#undef XG_ZLO
#undef XG_ZHI
#undef XG_EV
#undef XG_OD
