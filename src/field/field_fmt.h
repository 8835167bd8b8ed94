/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_fmt.h - number formatting of the text writers (field_fmt.c): the bytes of
 * glibc's printf without it. Not installed. */
#ifndef RPIV_FIELD_FMT_H
#define RPIV_FIELD_FMT_H

/* out must hold FIELD_FMT_MAX bytes; each returns the length written (NUL excluded). */
enum { FIELD_FMT_MAX = 32 };
/* "%.Pg" of v, 1 <= p <= 17. */
int field_fmt_g(char *out, double v, int p);
/* The shortest "%.Pg", P = 6..9, that reads back (strtof) as v. */
int field_fmt_float(char *out, float v);

#endif /* RPIV_FIELD_FMT_H */
