/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_field_fmt.c - the text writers' formatter (src/field/field_fmt.c) gives the bytes
 * of glibc's printf: "%.Pg" of doubles and the shortest "%.Pg" (P = 6..9) of a float that
 * strtof reads back, compared with snprintf and strtof on random values, every bit pattern
 * class (zero, subnormal, huge, NaN, infinite), the decades' edges and rounding ties.
 * RPIV_SLOW_TESTS=1 also runs every float of three binades. */
#include "check.h"
#include "field_fmt.h"

#include <stdint.h>
#include <string.h>

static uint64_t rng = 0x9e3779b97f4a7c15u;

static uint64_t next(void) /* xorshift64* */
{
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return rng * 0x2545f4914f6cdd1du;
}

/* The writers' former code: printf and strtof. */
static void ref_float(char *out, float v)
{
    for (int p = 6; p <= 9; p++) {
        snprintf(out, FIELD_FMT_MAX, "%.*g", p, (double)v);
        if (strtof(out, NULL) == v)
            break;
    }
}

static int bad_float, bad_double;

static void same_float(float v)
{
    char a[FIELD_FMT_MAX], b[FIELD_FMT_MAX];
    int n = field_fmt_float(a, v);
    ref_float(b, v);
    if ((strcmp(a, b) || n != (int)strlen(b)) && bad_float++ < 10)
        fprintf(stderr, "float %a: '%s', printf '%s'\n", (double)v, a, b);
}

static void same_double(double v, int p)
{
    char a[FIELD_FMT_MAX], b[FIELD_FMT_MAX];
    int n = field_fmt_g(a, v, p);
    snprintf(b, sizeof b, "%.*g", p, v);
    if ((strcmp(a, b) || n != (int)strlen(b)) && bad_double++ < 10)
        fprintf(stderr, "double %a %%.%dg: '%s', printf '%s'\n", v, p, a, b);
}

static float float_of(uint32_t bits)
{
    float v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

static void floats_match_printf(void)
{
    bad_float = 0;
    for (int k = 0; k < 400000; k++) /* any bit pattern */
        same_float(float_of((uint32_t)next()));
    for (int k = 0; k < 400000; k++) { /* the range of displacements and peak ratios */
        double u = (double)(next() >> 11) / 9007199254740992.0;
        same_float((float)((u - 0.5) * 64.0));
        same_float((float)(u * 2.0));
    }
    for (int k = 0; k < 200000; k++) /* short decimals, the usual ties of %.6g */
        same_float((float)((double)(int64_t)(next() % 2000001) / 1e4 - 100.0));
    const float special[] = {
        0.0f,     -0.0f,    1.0f,       -1.0f,           0.5f,           1e-5f,     9.99999e-6f,
        1e15f,    1.5e15f,  1e-45f,     1.17549435e-38f, 3.40282347e38f, 0.1f,      0.3187f,
        -2.4481f, 65535.0f, 8388608.0f, 16777215.0f,     16777216.0f,    123456.5f, 999999.5f};
    for (size_t k = 0; k < sizeof special / sizeof *special; k++)
        same_float(special[k]);
    same_float(float_of(0x7fc00000u)); /* NaN */
    same_float(float_of(0x7f800000u)); /* +inf */
    same_float(float_of(0xff800000u)); /* -inf */
    for (int e = -6; e <= 16; e++) {   /* the neighbours of every power of ten in range */
        float t = (float)pow(10.0, e);
        uint32_t bits;
        memcpy(&bits, &t, sizeof bits);
        for (int d = -3; d <= 3; d++)
            same_float(float_of(bits + (uint32_t)d));
    }
    for (int e = -20; e <= 52; e++) { /* powers of two: the spacing below is half that above */
        uint32_t bits;
        float t = ldexpf(1.0f, e);
        memcpy(&bits, &t, sizeof bits);
        for (int d = -2; d <= 2; d++) {
            same_float(float_of(bits + (uint32_t)d));
            same_float(-float_of(bits + (uint32_t)d));
        }
    }
    CHECK(bad_float == 0);
}

static void doubles_match_printf(void)
{
    bad_double = 0;
    for (int k = 0; k < 300000; k++) {
        int p = 1 + (int)(next() % 17);
        uint64_t bits = next();
        double v;
        memcpy(&v, &bits, sizeof v);
        same_double(v, p); /* mostly out of the fast range: printf's path */
        double u = (double)(next() >> 11) / 9007199254740992.0;
        same_double(pow(10.0, 20.0 * u - 5.0) * (next() & 1 ? 1 : -1), p);
        same_double((double)(int64_t)(next() % 100000) / 4.0 + 0.75, p); /* grid positions */
        same_double((double)(int64_t)(next() % 2000000) / 1000.0, p);    /* ties */
    }
    for (int e = -6; e <= 16; e++)
        for (int p = 1; p <= 17; p++) {
            double t = pow(10.0, e);
            same_double(t, p);
            same_double(nextafter(t, 0), p);
            same_double(nextafter(t, 1e300), p);
            same_double(-t, p);
        }
    for (int p = 1; p <= 17; p++) {
        same_double(0.0, p);
        same_double(-0.0, p);
        same_double(9.5, p);
        same_double(0.125, p);
        same_double(2.5e-5, p);
        same_double(99999.95, p);
    }
    CHECK(bad_double == 0);
}

/* Every float of a binade, with RPIV_SLOW_TESTS=1 (about a minute a binade). */
static void whole_binades_match_printf(void)
{
    if (!getenv("RPIV_SLOW_TESTS"))
        return;
    bad_float = 0;
    const uint32_t starts[] = {0x3f800000u /* [1, 2) */, 0x3a800000u /* [2^-10, 2^-9) */,
                               0x4b000000u /* [2^23, 2^24) */};
    for (size_t s = 0; s < sizeof starts / sizeof *starts; s++)
        for (uint32_t k = 0; k < (UINT32_C(1) << 23); k++)
            same_float(float_of(starts[s] + k));
    CHECK(bad_float == 0);
}

int main(void)
{
    RUN_TEST(floats_match_printf);
    RUN_TEST(doubles_match_printf);
    RUN_TEST(whole_binades_match_printf);
    return check_summary();
}
