/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_load.c - reading whitespace column files (rpiv's own, OpenPIV's) back into a
 * field on a regular grid. */
#include "rpiv/field.h"

#include "field_impl.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The rows of a column file, as read. */
typedef struct rows {
    size_t n, cap;
    double *x, *y;
    float *u, *v, *pr, *cc;
    unsigned char *flag;
    long *line;
    size_t nq; /* extra quantities per row (rpiv's files) */
    float *ex; /* nq per row */
} rows;

/* What rpiv's header says. */
#define MAXQ 64
typedef struct header {
    int is_rpiv, y_up;
    double scale, dt;
    size_t nq;
    char qname[MAXQ][RPIV_QUANTITY_NAME_MAX];
    int qunit[MAXQ];
} header;

static void rows_free(rows *r)
{
    free(r->x);
    free(r->y);
    free(r->u);
    free(r->v);
    free(r->pr);
    free(r->cc);
    free(r->flag);
    free(r->line);
    free(r->ex);
}

#define GROW(p, cap) (tmp = realloc((p), (cap) * sizeof *(p))) ? ((p) = tmp, 1) : 0

static int rows_push(rows *r)
{
    if (r->n < r->cap)
        return 1;
    size_t cap = r->cap ? 2 * r->cap : 256;
    void *tmp;
    if (!(GROW(r->x, cap)) || !(GROW(r->y, cap)) || !(GROW(r->u, cap)) || !(GROW(r->v, cap)) ||
        !(GROW(r->pr, cap)) || !(GROW(r->cc, cap)) || !(GROW(r->flag, cap)) ||
        !(GROW(r->line, cap)))
        return 0;
    if (r->nq && !(tmp = realloc(r->ex, cap * r->nq * sizeof *r->ex)))
        return 0;
    if (r->nq)
        r->ex = tmp;
    r->cap = cap;
    return 1;
}

/* "# key = value" header lines rpiv writes; only the ones that change the field are used.
 * RPIV_EFORMAT for a quantity line that cannot be used. */
static rpiv_status header_line(const char *s, header *h, const char *path, long lineno)
{
    while (*s == '#' || *s == ' ' || *s == '\t')
        s++;
    if (strncmp(s, "rpiv vector field", 17) == 0) {
        h->is_rpiv = 1;
        return RPIV_OK;
    }
    double val;
    char key[32], name[64], unit[16], odd[16];
    if (sscanf(s, "orientation = %15s", unit) == 1) {
        h->y_up = strcmp(unit, "y-up") == 0;
        return RPIV_OK;
    }
    int nf = sscanf(s, "quantity = %63s %15s %15s", name, unit, odd);
    if (nf >= 2) {
        int u = field_unit_of_name(unit);
        if (u < 0 || h->nq == MAXQ || strlen(name) >= RPIV_QUANTITY_NAME_MAX)
            return rpiv_fail(RPIV_EFORMAT, "%s:%ld: quantity '%s' in '%s': %s", path, lineno, name,
                             unit, u < 0 ? "unknown unit" : "too many or name too long");
        if (nf == 3 && strcmp(odd, "odd_y") == 0)
            u |= RPIV_UNIT_ODD_Y;
        memcpy(h->qname[h->nq], name, strlen(name) + 1);
        h->qunit[h->nq++] = u;
        return RPIV_OK;
    }
    if (sscanf(s, "%31[A-Za-z0-9_] = %lf", key, &val) == 2) {
        /* the ranges of the [piv] keys, dt at least 1 ps: within them the mm and m/s columns
         * of any vector fit a float, so what is loaded can be written and read back (a scale
         * of 6.5e87 mm/px gave coordinates of 4e89 mm that no float holds: the fuzzer) */
        const int is_scale = strcmp(key, "scale_mm_per_px") == 0, is_dt = strcmp(key, "dt_s") == 0;
        if ((is_scale && !(val > 0 && val <= 1e6)) || (is_dt && !(val >= 1e-12 && val <= 1e6)))
            return rpiv_fail(RPIV_EFORMAT, "%s:%ld: %s = %g is outside %s", path, lineno, key, val,
                             is_scale ? "(0, 1e6] mm/px" : "[1e-12, 1e6] s");
        if (is_scale)
            h->scale = val;
        else if (is_dt)
            h->dt = val;
    }
    return RPIV_OK;
}

#define MAXCOL (7 + MAXQ)

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Infer origin, step and count from the coordinates v[0..n-1]: distinct values (within a
 * relative 1e-6) must be an arithmetic progression, possibly with gaps filled by other rows.
 * *bad gets the index of a value that is off the grid, or n. */
static rpiv_status infer_axis(const double *v, size_t n, double *o0, double *step, long *count,
                              size_t *bad)
{
    double *s = malloc(n * sizeof *s);
    if (!s)
        return RPIV_ENOMEM;
    memcpy(s, v, n * sizeof *s);
    qsort(s, n, sizeof *s, cmp_double);
    double span = s[n - 1] - s[0];
    double tol = 1e-6 * fmax(1.0, fmax(fabs(s[0]), fabs(s[n - 1])));
    double gap = (double)INFINITY;
    for (size_t k = 1; k < n; k++) {
        double d = s[k] - s[k - 1];
        if (d > tol && d < gap)
            gap = d;
    }
    double lo = s[0];
    free(s);
    *bad = n;
    *o0 = lo;
    if (!isfinite(gap)) { /* one distinct value */
        *count = 1;
        *step = 0;
        return RPIV_OK;
    }
    double c = span / gap;
    if (c > 1e8) {
        *count = -1;
        return RPIV_OK;
    }
    /* every value must sit on lo + k * gap; the step is then refined over the whole span */
    for (size_t k = 0; k < n; k++) {
        double q = (v[k] - lo) / gap;
        if (fabs(q - nearbyint(q)) > 1e-3) {
            *bad = k;
            break;
        }
    }
    *count = lround(c) + 1;
    /* off the grid: report the step that was tried */
    *step = *bad < n ? gap : span / (double)(*count - 1);
    return RPIV_OK;
}

/* The physical columns a save would add to f (mm, and m/s or mm per pair) must fit a float,
 * or the file written from this field could not be read back. */
rpiv_status field_check_units(const rpiv_field *f, const char *path)
{
    const double scale = f->scale_mm_per_px, dt = f->dt_s;
    if (!(scale > 0))
        return RPIV_OK;
    const double mx = fmax(fmax(fabs(f->x0), fabs(f->x0 + (f->nx - 1) * f->dx)),
                           fmax(fabs(f->y0), fabs(f->y0 + (f->ny - 1) * f->dy)));
    double mu = 0;
    for (size_t k = 0, n = (size_t)f->nx * (size_t)f->ny; k < n; k++)
        mu = fmax(mu, fmax(fabs((double)f->u[k]), fabs((double)f->v[k])));
    const double ku = scale * (dt > 0 ? fmax(1.0, 1e-3 / dt) : 1.0);
    if (!(mx * scale <= (double)FLT_MAX && mu * ku <= (double)FLT_MAX))
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: scale_mm_per_px = %g puts the physical columns beyond a float "
                         "(coordinates up to %g px, velocities up to %g px)",
                         path, scale, mx, mu);
    return RPIV_OK;
}

static rpiv_status build_field(const rows *r, const char *path, const header *h, rpiv_field **out)
{
    double x0, y0, dx, dy;
    long nx, ny;
    size_t badx, bady;
    if (infer_axis(r->x, r->n, &x0, &dx, &nx, &badx) ||
        infer_axis(r->y, r->n, &y0, &dy, &ny, &bady))
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    if (nx < 0 || ny < 0)
        return rpiv_fail(RPIV_EFORMAT, "%s: not a regular grid (coordinate steps too uneven)",
                         path);
    if (badx < r->n)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s:%ld: not a regular grid: x = %g is not on x0 + i*dx "
                         "(x0 = %g, dx = %g)",
                         path, r->line[badx], r->x[badx], x0, dx);
    if (bady < r->n)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s:%ld: not a regular grid: y = %g is not on y0 + j*dy "
                         "(y0 = %g, dy = %g)",
                         path, r->line[bady], r->y[bady], y0, dy);
    if ((double)nx * (double)ny != (double)r->n)
        return rpiv_fail(RPIV_EFORMAT, "%s: not a regular grid: %zu vectors for %ld x %ld points",
                         path, r->n, nx, ny);
    /* a line or a single point: borrow the other axis' step, or 1 px */
    if (nx == 1)
        dx = ny > 1 ? dy : 1.0;
    if (ny == 1)
        dy = nx > 1 ? dx : 1.0;
    rpiv_field *f;
    rpiv_status st = rpiv_field_new((int)nx, (int)ny, x0, y0, dx, dy, &f);
    if (st)
        return st;
    for (size_t q = 0; q < r->nq; q++) {
        if ((st = rpiv_field_add_quantity(f, h->qname[q], h->qunit[q], NULL))) {
            char msg[512];
            snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
            rpiv_field_free(f);
            return rpiv_fail(RPIV_EFORMAT, "%s: %s", path, msg);
        }
    }
    long *seen = calloc(r->n, sizeof *seen);
    if (!seen) {
        rpiv_field_free(f);
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    }
    for (size_t k = 0; k < r->n; k++) {
        long i = lround((r->x[k] - x0) / dx), j = lround((r->y[k] - y0) / dy);
        size_t idx = (size_t)j * (size_t)nx + (size_t)i;
        if (seen[idx]) {
            st = rpiv_fail(RPIV_EFORMAT,
                           "%s:%ld: not a regular grid: point (%g, %g) repeats "
                           "line %ld",
                           path, r->line[k], r->x[k], r->y[k], seen[idx]);
            break;
        }
        seen[idx] = r->line[k];
        f->u[idx] = r->u[k];
        f->v[idx] = r->v[k];
        f->flag[idx] = r->flag[k];
        f->peak_ratio[idx] = r->pr[k];
        f->corr[idx] = r->cc[k];
        for (size_t q = 0; q < r->nq; q++)
            f->q[q].data[idx] = r->ex[k * r->nq + q];
    }
    free(seen);
    if (st) {
        rpiv_field_free(f);
        return st;
    }
    f->scale_mm_per_px = h->scale;
    f->dt_s = h->dt;
    f->y_up = h->y_up;
    if ((st = field_check_units(f, path))) {
        rpiv_field_free(f);
        return st;
    }
    *out = f;
    return RPIV_OK;
}

rpiv_status rpiv_field_load_txt(const char *path, rpiv_field **out)
{
    *out = NULL;
    FILE *fp = fopen(path, "r");
    if (!fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    rows r = {0};
    char *line = NULL;
    size_t cap = 0;
    long lineno = 0, ncol_line = 0;
    int ncol = 0;
    header h = {0};
    rpiv_status st = RPIV_OK;
    ssize_t len;
    while ((len = text_getline(fp, &line, &cap, path, &lineno, &st)) >= 0) {
        char *s = line + strspn(line, " \t\r\n");
        if (*s == '#') {
            if (r.n == 0 && (st = header_line(s, &h, path, lineno)))
                goto out_free;
            continue;
        }
        if (*s == '\0')
            continue;
        double val[MAXCOL] = {0};
        int nc = text_columns(s, val, MAXCOL, path, lineno, &st);
        if (nc < 0)
            goto out_free;
        if (!r.n && h.is_rpiv)
            r.nq = h.nq;
        if (nc < 4) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: %d column%s, need at least 4 (x y u v)", path,
                           lineno, nc, nc == 1 ? "" : "s");
            goto out_free;
        }
        if (r.nq && nc < 7 + (int)r.nq) {
            st = rpiv_fail(RPIV_EFORMAT,
                           "%s:%ld: %d columns, the header names %zu quantities "
                           "after column 7",
                           path, lineno, nc, r.nq);
            goto out_free;
        }
        if (!ncol) {
            ncol = nc;
            ncol_line = lineno;
        } else if (nc != ncol) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: %d columns, line %ld has %d", path, lineno, nc,
                           ncol_line, ncol);
            goto out_free;
        }
        if (nc >= 5 && (val[4] < 0 || val[4] > 255 || val[4] != floor(val[4]))) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: flag %g is not an integer 0..255", path, lineno,
                           val[4]);
            goto out_free;
        }
        /* u, v (and rpiv's peak ratio and correlation) are stored as float */
        for (int c = 2; c < (nc < MAXCOL ? nc : MAXCOL); c++) {
            if ((c == 2 || c == 3 || (h.is_rpiv && c >= 5)) && fabs(val[c]) > (double)FLT_MAX) {
                st = rpiv_fail(RPIV_EFORMAT,
                               "%s:%ld: column %d: %g is beyond the range of a "
                               "32-bit float",
                               path, lineno, c + 1, val[c]);
                goto out_free;
            }
        }
        if (!rows_push(&r)) {
            st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory at line %ld", path, lineno);
            goto out_free;
        }
        size_t k = r.n++;
        r.x[k] = val[0];
        r.y[k] = val[1];
        r.u[k] = (float)val[2];
        r.v[k] = (float)val[3];
        r.flag[k] = (unsigned char)val[4];
        /* columns 6-7 mean peak ratio and correlation only in rpiv's files (OpenPIV's 6th
         * column is a mask) */
        r.pr[k] = h.is_rpiv ? (float)val[5] : 0.0f;
        r.cc[k] = h.is_rpiv ? (float)val[6] : 0.0f;
        for (size_t q = 0; q < r.nq; q++)
            r.ex[k * r.nq + q] = (float)val[7 + q];
        r.line[k] = lineno;
    }
    if (len == -2)
        goto out_free;
    if (ferror(fp)) {
        st = rpiv_fail(RPIV_EIO, "%s: read error: %s", path, strerror(errno));
        goto out_free;
    }
    if (r.n == 0) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: no vectors (expected columns x y u v)", path);
        goto out_free;
    }
    st = build_field(&r, path, &h, out);
out_free:
    free(line);
    rows_free(&r);
    fclose(fp);
    return st;
}

/* ---- profiles ----------------------------------------------------------------- */

void rpiv_profile_free(rpiv_profile *p)
{
    if (!p)
        return;
    free(p->alpha);
    free(p->value);
    free(p);
}

rpiv_status rpiv_text_columns(const char *path, int *ncol)
{
    FILE *fp = fopen(path, "r");
    if (!fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    char *line = NULL;
    size_t cap = 0;
    long lineno = 0;
    rpiv_status st = rpiv_fail(RPIV_EFORMAT, "%s: no data lines", path);
    ssize_t len;
    while ((len = text_getline(fp, &line, &cap, path, &lineno, &st)) >= 0) {
        char *s = line + strspn(line, " \t\r\n");
        if (*s == '#' || *s == '\0')
            continue;
        double val[MAXCOL];
        int nc = text_columns(s, val, MAXCOL, path, lineno, &st);
        if (nc >= 0) {
            *ncol = nc;
            st = RPIV_OK;
        }
        break;
    }
    free(line);
    fclose(fp);
    return st;
}

rpiv_status rpiv_profile_load(const char *path, rpiv_profile **out)
{
    *out = NULL;
    FILE *fp = fopen(path, "r");
    if (!fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    rpiv_profile *p = calloc(1, sizeof *p);
    char *line = NULL;
    size_t cap = 0, pcap = 0;
    long lineno = 0;
    rpiv_status st = RPIV_OK;
    int dir = 0; /* +1 increasing, -1 decreasing */
    if (!p) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
        goto out_close;
    }
    ssize_t len;
    while ((len = text_getline(fp, &line, &cap, path, &lineno, &st)) >= 0) {
        char *s = line + strspn(line, " \t\r\n");
        if (*s == '#' || *s == '\0')
            continue;
        double val[MAXCOL];
        int nc = text_columns(s, val, MAXCOL, path, lineno, &st);
        if (nc < 0)
            goto out_close;
        if (nc < 2) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: 1 column, a profile needs 2 (alpha value)", path,
                           lineno);
            goto out_close;
        }
        if (p->n) {
            double prev = p->alpha[p->n - 1];
            int d = val[0] > prev ? 1 : val[0] < prev ? -1 : 0;
            if (!dir)
                dir = d;
            if (!d || d != dir) {
                st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: alpha %g is not %s (previous %g)", path,
                               lineno, val[0], dir < 0 ? "decreasing" : "increasing", prev);
                goto out_close;
            }
        }
        if (p->n == pcap) {
            size_t nc2 = pcap ? 2 * pcap : 128;
            double *a = realloc(p->alpha, nc2 * sizeof *a);
            if (a)
                p->alpha = a;
            double *v = a ? realloc(p->value, nc2 * sizeof *v) : NULL;
            if (v)
                p->value = v;
            if (!a || !v) {
                st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory at line %ld", path, lineno);
                goto out_close;
            }
            pcap = nc2;
        }
        p->alpha[p->n] = val[0];
        p->value[p->n] = val[1];
        p->n++;
    }
    if (len == -2)
        goto out_close;
    if (ferror(fp)) {
        st = rpiv_fail(RPIV_EIO, "%s: read error: %s", path, strerror(errno));
        goto out_close;
    }
    if (p->n < 2) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: %zu point%s, a profile needs at least 2", path, p->n,
                       p->n == 1 ? "" : "s");
        goto out_close;
    }
    if (dir < 0) {
        for (size_t a = 0, b = p->n - 1; a < b; a++, b--) {
            double t = p->alpha[a];
            p->alpha[a] = p->alpha[b];
            p->alpha[b] = t;
            t = p->value[a];
            p->value[a] = p->value[b];
            p->value[b] = t;
        }
    }
    *out = p;
    p = NULL;
out_close:
    rpiv_profile_free(p);
    free(line);
    fclose(fp);
    return st;
}
