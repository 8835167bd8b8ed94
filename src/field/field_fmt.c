/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_fmt.c - the text writers' number formatting without printf: "%.Pg" of a
 * double and the shortest "%.Pg" (P = 6..9) that reads back as the same float, with the bytes
 * glibc's printf gives, in exact integer arithmetic (128 bits). Values of magnitude 1e-5 to
 * 1e15 take this path; zero, others, NaN and infinities go through snprintf and strtof as
 * before. printf and strtof were 15 % of a one-pair `rpiv piv` writing 21306 rows (issue 15).
 *
 * A double v = m 2^e (m < 2^53). Its P significant digits are q = v 10^s rounded to an
 * integer, s = P - 1 - X with X the decimal exponent (10^(P-1) <= v 10^s < 10^P), half to
 * even, as glibc rounds in the default rounding mode. v 10^s = m 10^s 2^e or m 2^e / 10^-s;
 * with |v| in [1e-5, 1e15] and P <= 17 every term stays below 2^127. */
#include "field_fmt.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

__extension__ typedef unsigned __int128 u128;

static u128 pow10u(int k) /* 10^k, 0 <= k <= 38 */
{
    u128 r = 1;
    for (; k >= 8; k -= 8)
        r *= 100000000u;
    static const uint32_t small[8] = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000};
    return r * small[k];
}

/* v = m 2^e with m < 2^53 (v finite and normal). */
static void split_double(double v, uint64_t *m, int *e)
{
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    int be = (int)((bits >> 52) & 0x7ff);
    *m = (bits & ((UINT64_C(1) << 52) - 1)) | (UINT64_C(1) << 52);
    *e = be - 1075;
}

/* t = floor(m 2^e 10^s); *sticky = 1 when the remainder is not zero. */
static u128 scaled(uint64_t m, int e, int s, int *sticky)
{
    u128 num = m, den = 1;
    if (s >= 0)
        num *= pow10u(s);
    else
        den = pow10u(-s);
    if (e >= 0) {
        num <<= e;
    } else if (s >= 0) { /* a division by 2^-e: a shift */
        *sticky = (num & (((u128)1 << -e) - 1)) != 0;
        return num >> -e;
    } else {
        den <<= -e;
    }
    u128 q = num / den;
    *sticky = num != q * den;
    return q;
}

static const uint64_t POW10[19] = {1u,
                                   10u,
                                   100u,
                                   1000u,
                                   10000u,
                                   100000u,
                                   1000000u,
                                   10000000u,
                                   100000000u,
                                   1000000000u,
                                   10000000000u,
                                   100000000000u,
                                   1000000000000u,
                                   10000000000000u,
                                   100000000000000u,
                                   1000000000000000u,
                                   10000000000000000u,
                                   100000000000000000u,
                                   1000000000000000000u};

/* The first P significant digits of |v| truncated, t (10^(P-1) <= t < 10^P), whether digits
 * follow (*sticky), and the decimal exponent X; 0 outside the fast range. The truncated
 * value decides the decade exactly (floor(y 10^s) >= 10^k iff y 10^s >= 10^k). */
static int digits_trunc(double v, int P, uint64_t *t, int *sticky, int *x)
{
    double a = fabs(v);
    if (!(a >= 1e-5 && a <= 1e15) || P < 2 || P > 18)
        return 0;
    uint64_t m;
    int e;
    split_double(a, &m, &e);
    /* X from the binary exponent: floor(E log10 2) is X or X - 1; the loop checks exactly */
    static const double p10[] = {1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1e0,  1e1,
                                 1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,
                                 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17};
    const int E = e + 52; /* a = (m / 2^52) 2^E, 1 <= m / 2^52 < 2 */
    int X = E >= 0 ? (E * 78913) >> 18 : -((-E * 78913 + (1 << 18) - 1) >> 18);
    if (X + 7 >= 0 && X + 7 < (int)(sizeof p10 / sizeof *p10) && a >= p10[X + 7])
        X++;
    for (int tries = 0; tries < 4; tries++) {
        u128 q = scaled(m, e, P - 1 - X, sticky);
        if (q < POW10[P - 1]) {
            X--;
        } else if (q >= POW10[P]) {
            X++;
        } else {
            *t = (uint64_t)q;
            *x = X;
            return 1;
        }
    }
    return 0;
}

/* p < P digits from the truncated P digits t (digits follow if sticky), rounded half to even
 * as "%.pe" rounds the exact value: *q (10^(p-1) <= q < 10^p) and the exponent *x. */
static void round_to(uint64_t t, int sticky, int X, int P, int p, uint64_t *q, int *x)
{
    const uint64_t d = POW10[P - p], r = t % d;
    uint64_t k = t / d;
    k += 2 * r > d || (2 * r == d && (sticky || (k & 1)));
    *x = k == POW10[p] ? X + 1 : X;
    *q = k == POW10[p] ? POW10[p - 1] : k;
}

/* Decimal digits of q (< 10^17) into d (most significant first); their count. */
static int digit_string(uint64_t q, char *d)
{
    char tmp[40];
    int n = 0;
    uint64_t v = q;
    do {
        tmp[n++] = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    for (int k = 0; k < n; k++)
        d[k] = tmp[n - 1 - k];
    return n;
}

/* "%.Pg" of the digits q (P of them) and exponent X, with sign; length written to out. */
static int format_g(char *out, int neg, uint64_t q, int X, int p)
{
    char d[40];
    int n = digit_string(q, d), len = 0; /* n == p */
    if (neg)
        out[len++] = '-';
    if (X < -4 || X >= p) { /* d.ddd e+XX */
        int last = n;
        while (last > 1 && d[last - 1] == '0')
            last--;
        out[len++] = d[0];
        if (last > 1) {
            out[len++] = '.';
            memcpy(out + len, d + 1, (size_t)(last - 1));
            len += last - 1;
        }
        out[len++] = 'e';
        out[len++] = X < 0 ? '-' : '+';
        int ax = X < 0 ? -X : X;
        if (ax >= 100)
            out[len++] = (char)('0' + ax / 100);
        out[len++] = (char)('0' + ax / 10 % 10);
        out[len++] = (char)('0' + ax % 10);
    } else if (X >= 0) { /* X + 1 integer digits, then the fraction */
        int last = n;
        while (last > X + 1 && d[last - 1] == '0')
            last--;
        memcpy(out + len, d, (size_t)(X + 1));
        len += X + 1;
        if (last > X + 1) {
            out[len++] = '.';
            memcpy(out + len, d + X + 1, (size_t)(last - X - 1));
            len += last - X - 1;
        }
    } else { /* 0.000ddd */
        int last = n;
        while (last > 1 && d[last - 1] == '0')
            last--;
        out[len++] = '0';
        out[len++] = '.';
        for (int k = 0; k < -X - 1; k++)
            out[len++] = '0';
        memcpy(out + len, d, (size_t)last);
        len += last;
    }
    out[len] = '\0';
    return len;
}

int field_fmt_g(char *out, double v, int p)
{
    uint64_t t, q;
    int X, sticky;
    if (p >= 1 && p <= 17 && digits_trunc(v, p + 1, &t, &sticky, &X)) {
        round_to(t, sticky, X, p + 1, p, &q, &X);
        return format_g(out, v < 0, q, X, p);
    }
    return snprintf(out, FIELD_FMT_MAX, "%.*g", p, v);
}

/* Whether the decimal q 10^t reads back (strtof, correctly rounded, ties to even) as the
 * float f = mf 2^ef (2^23 <= mf < 2^24): q 10^t within half a spacing of f, the bounds
 * included when mf is even. Everything is scaled by 10^max(0,-t) 2^max(0,2-ef). */
static int reads_back(uint32_t mf, int ef, uint64_t q, int t)
{
    int s10 = t < 0 ? -t : 0, s2 = ef < 2 ? 2 - ef : 0;
    u128 Q = (u128)q * pow10u(t > 0 ? t : 0) << s2;
    u128 F = (u128)mf * pow10u(s10) << (ef + s2);
    u128 up = pow10u(s10) << (ef - 1 + s2);
    u128 down = mf == (UINT32_C(1) << 23) ? pow10u(s10) << (ef - 2 + s2) : up;
    int even = !(mf & 1);
    if (Q >= F)
        return Q - F < up || (even && Q - F == up);
    return F - Q < down || (even && F - Q == down);
}

int field_fmt_float(char *out, float v)
{
    double a = fabs((double)v);
    if (a >= 1e-5 && a <= 1e15) {
        uint32_t bits;
        memcpy(&bits, &v, sizeof bits);
        uint32_t mf = (bits & ((UINT32_C(1) << 23) - 1)) | (UINT32_C(1) << 23);
        int ef = (int)((bits >> 23) & 0xff) - 150;
        uint64_t t;
        int X10, sticky;
        if (digits_trunc((double)v, 10, &t, &sticky, &X10))
            for (int p = 6; p <= 9; p++) {
                uint64_t q;
                int X;
                round_to(t, sticky, X10, 10, p, &q, &X);
                if (p == 9 || reads_back(mf, ef, q, X - p + 1))
                    return format_g(out, v < 0, q, X, p);
            }
    }
    /* zero, tiny, huge, NaN, infinite: printf and strtof, as the writers did before */
    int len = 0;
    for (int p = 6; p <= 9; p++) {
        len = snprintf(out, FIELD_FMT_MAX, "%.*g", p, (double)v);
        if (strtof(out, NULL) == v)
            break;
    }
    return len;
}
