/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/pairs.c - image pairs from two files, double-frame files, list files and glob
 * patterns with a pairing rule. Building the list only looks at names (and reads list files);
 * the images themselves are opened by rpiv_pairs_load, which names the pair and file at fault. */
#include "rpiv/pairs.h"

#include "base/text.h"

#include <ctype.h>
#include <errno.h>
#include <glob.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* ---- the list being built -------------------------------------------------------------- */

static rpiv_status add_pair(rpiv_pairs *p, size_t *cap, const char *a, const char *b)
{
    if (p->n == *cap) {
        size_t nc = *cap ? 2 * *cap : 16;
        rpiv_pair_src *np = realloc(p->pair, nc * sizeof *np);
        if (!np)
            return rpiv_fail(RPIV_ENOMEM, "out of memory for %zu image pairs", nc);
        p->pair = np;
        *cap = nc;
    }
    rpiv_pair_src *s = &p->pair[p->n];
    s->path_a = strdup(a);
    s->path_b = b ? strdup(b) : NULL;
    if (!s->path_a || (b && !s->path_b)) {
        free(s->path_a);
        free(s->path_b);
        return rpiv_fail(RPIV_ENOMEM, "out of memory for image pair '%s'", a);
    }
    p->n++;
    return RPIV_OK;
}

void rpiv_pairs_free(rpiv_pairs *p)
{
    if (!p)
        return;
    for (size_t i = 0; i < p->n; i++) {
        free(p->pair[i].path_a);
        free(p->pair[i].path_b);
    }
    free(p->pair);
    free(p);
}

/* ---- names ----------------------------------------------------------------------------- */

static int is_glob(const char *s)
{
    return strpbrk(s, "*?[") != NULL;
}

static int has_ext(const char *path, const char *ext)
{
    size_t n = strlen(path), e = strlen(ext);
    return n > e && strcasecmp(path + n - e, ext) == 0;
}

static int is_list(const char *s)
{
    return has_ext(s, ".txt") || has_ext(s, ".lst");
}

/* Natural order: runs of digits compare by value ("f_9" < "f_10"), the rest byte by byte;
 * equal values with different zero padding fall back to strcmp, so the order is total. */
static int natcmp(const char *a, const char *b)
{
    const char *p = a, *q = b;
    while (*p && *q) {
        if (isdigit((unsigned char)*p) && isdigit((unsigned char)*q)) {
            while (*p == '0')
                p++;
            while (*q == '0')
                q++;
            size_t lp = 0, lq = 0;
            while (isdigit((unsigned char)p[lp]))
                lp++;
            while (isdigit((unsigned char)q[lq]))
                lq++;
            if (lp != lq)
                return lp < lq ? -1 : 1;
            int c = strncmp(p, q, lp);
            if (c)
                return c;
            p += lp;
            q += lq;
        } else {
            if (*p != *q)
                return (unsigned char)*p < (unsigned char)*q ? -1 : 1;
            p++;
            q++;
        }
    }
    if (*p || *q)
        return *p ? 1 : -1;
    return strcmp(a, b);
}

static int natcmp_qsort(const void *x, const void *y)
{
    return natcmp(*(char *const *)x, *(char *const *)y);
}

/* The A/B marker of a file name: the last character of the stem (name without extension).
 * Returns 'A' or 'B' and writes the key (path with the marker removed, plus the marker's
 * class a/A/1 so that only a-b, A-B and 1-2 pair up); 0 if the stem has no marker. */
static int ab_marker(const char *path, char *key, size_t cap)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    size_t stem_end = dot && dot > base ? (size_t)(dot - path) : strlen(path);
    if (stem_end == (size_t)(base - path))
        return 0;
    char m = path[stem_end - 1], cls;
    int ab;
    switch (m) {
    case 'a':
    case 'b':
        cls = 'a';
        ab = m == 'a' ? 'A' : 'B';
        break;
    case 'A':
    case 'B':
        cls = 'A';
        ab = m == 'A' ? 'A' : 'B';
        break;
    case '1':
    case '2':
        cls = '1';
        ab = m == '1' ? 'A' : 'B';
        break;
    default:
        return 0;
    }
    int n = snprintf(key, cap, "%.*s%c%s", (int)(stem_end - 1), path, cls, path + stem_end);
    if (n < 0 || (size_t)n >= cap)
        return 0;
    return ab;
}

typedef struct abent {
    const char *path;
    char key[1024];
    int ab;
} abent;

static int abent_cmp(const void *x, const void *y)
{
    const abent *a = x, *b = y;
    int c = strcmp(a->key, b->key);
    if (c)
        return c;
    return a->ab - b->ab;
}

/* Pair sorted files by rule; `what` names the source (pattern) in messages. */
static rpiv_status pair_files(char **files, size_t n, rpiv_pairing rule, const char *what,
                              rpiv_pairs *p, size_t *cap)
{
    rpiv_status st = RPIV_OK;
    if (rule == RPIV_PAIR_CONSECUTIVE) {
        if (n % 2)
            return rpiv_fail(RPIV_EINVAL,
                             "%s: %zu files, an odd count for consecutive pairs (1-2, 3-4, ...); "
                             "last file %s has no partner",
                             what, n, files[n - 1]);
        for (size_t i = 0; i + 1 < n && !st; i += 2)
            st = add_pair(p, cap, files[i], files[i + 1]);
        return st;
    }
    if (rule == RPIV_PAIR_TIME_RESOLVED) {
        if (n < 2)
            return rpiv_fail(RPIV_EINVAL, "%s: %zu file, time-resolved pairs need at least 2", what,
                             n);
        for (size_t i = 0; i + 1 < n && !st; i++)
            st = add_pair(p, cap, files[i], files[i + 1]);
        return st;
    }
    if (rule != RPIV_PAIR_AB)
        return rpiv_fail(RPIV_EINVAL, "%s: unknown pairing rule %d", what, (int)rule);
    abent *e = calloc(n, sizeof *e);
    if (!e)
        return rpiv_fail(RPIV_ENOMEM, "out of memory pairing %zu files", n);
    for (size_t i = 0; i < n && !st; i++) {
        e[i].path = files[i];
        e[i].ab = ab_marker(files[i], e[i].key, sizeof e[i].key);
        if (!e[i].ab)
            st = rpiv_fail(RPIV_EINVAL,
                           "%s: %s: name does not end in an A/B frame marker (a/b, A/B, _a/_b "
                           "or 1/2 before the extension)",
                           what, files[i]);
    }
    if (!st)
        qsort(e, n, sizeof *e, abent_cmp);
    for (size_t i = 0; i < n && !st;) {
        int pair_ok =
            i + 1 < n && !strcmp(e[i].key, e[i + 1].key) && e[i].ab == 'A' && e[i + 1].ab == 'B';
        if (pair_ok) {
            st = add_pair(p, cap, e[i].path, e[i + 1].path);
            i += 2;
        } else if (i + 1 < n && !strcmp(e[i].key, e[i + 1].key)) {
            st = rpiv_fail(RPIV_EINVAL, "%s: %s and %s are the same frame of one pair", what,
                           e[i].path, e[i + 1].path);
        } else {
            st = rpiv_fail(RPIV_EINVAL, "%s: %s has no matching %s frame", what, e[i].path,
                           e[i].ab == 'A' ? "B" : "A");
        }
    }
    free(e);
    return st;
}

static rpiv_status from_glob(const char *pattern, rpiv_pairing rule, rpiv_pairs *p, size_t *cap)
{
    glob_t g;
    memset(&g, 0, sizeof g);
    int r = glob(pattern, GLOB_ERR, NULL, &g);
    if (r == GLOB_NOMATCH) {
        globfree(&g);
        return rpiv_fail(RPIV_EIO, "%s: no file matches the pattern", pattern);
    }
    if (r != 0) {
        globfree(&g);
        return rpiv_fail(r == GLOB_NOSPACE ? RPIV_ENOMEM : RPIV_EIO,
                         "%s: cannot list the files matching the pattern", pattern);
    }
    qsort(g.gl_pathv, g.gl_pathc, sizeof *g.gl_pathv, natcmp_qsort);
    rpiv_status st = pair_files(g.gl_pathv, g.gl_pathc, rule, pattern, p, cap);
    globfree(&g);
    return st;
}

/* ---- list files ------------------------------------------------------------------------ */

/* Next whitespace-separated token of line (double quotes allow spaces); NULL at the end, at
 * a '#' comment, or at a quote that is not closed on its line (*unterminated set). */
static char *token(char **s, int *unterminated)
{
    char *p = *s;
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
        p++;
    if (!*p || *p == '#')
        return NULL;
    char *t;
    if (*p == '"') {
        t = ++p;
        while (*p && *p != '"')
            p++;
        if (*p != '"') { /* the rest of the line (its newline too) is no path */
            *unterminated = 1;
            return NULL;
        }
    } else {
        t = p;
        while (*p && *p != ' ' && *p != '\t' && *p != '\r' && *p != '\n')
            p++;
    }
    if (*p)
        *p++ = '\0';
    *s = p;
    return t;
}

static rpiv_status join(const char *dir, const char *name, char *out, size_t cap, const char *where)
{
    int n = name[0] == '/' || !dir[0] ? snprintf(out, cap, "%s", name)
                                      : snprintf(out, cap, "%s/%s", dir, name);
    if (n < 0 || (size_t)n >= cap)
        return rpiv_fail(RPIV_EINVAL, "%s: path too long: %s", where, name);
    return RPIV_OK;
}

static rpiv_status from_list(const char *list, rpiv_pairs *p, size_t *cap)
{
    char pa[4096], pb[4096], where[1200];
    const char *slash = strrchr(list, '/');
    size_t dlen = slash ? (slash == list ? 1 : (size_t)(slash - list)) : 0;
    char *dir = strndup(list, dlen), *line = NULL;
    if (!dir)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", list);
    FILE *f = fopen(list, "r");
    if (!f) {
        free(dir);
        return rpiv_fail(RPIV_EIO, "%s: cannot open list: %s", list, strerror(errno));
    }
    rpiv_status st = RPIV_OK;
    size_t lcap = 0;
    long lineno = 0;
    while (!st && text_getline(f, &line, &lcap, list, &lineno, &st) >= 0) {
        snprintf(where, sizeof where, "%s:%ld", list, lineno);
        char *s = line, *t[3];
        int nt = 0, open_quote = 0;
        if (lineno == 1 && !strncmp(s, "\xef\xbb\xbf", 3)) /* a UTF-8 byte order mark */
            s += 3;
        while (nt < 3 && (t[nt] = token(&s, &open_quote)) != NULL)
            nt++;
        if (open_quote) {
            st = rpiv_fail(RPIV_EFORMAT, "%s: a double quote is not closed on its line", where);
            break;
        }
        if (nt == 0)
            continue;
        if (nt == 3) {
            st = rpiv_fail(RPIV_EFORMAT,
                           "%s: more than two paths on a line (\"A B\" or one double-frame "
                           "file expected)",
                           where);
            break;
        }
        st = join(dir, t[0], pa, sizeof pa, where);
        if (!st && nt == 2)
            st = join(dir, t[1], pb, sizeof pb, where);
        if (!st)
            st = add_pair(p, cap, pa, nt == 2 ? pb : NULL);
    }
    if (!st && ferror(f))
        st = rpiv_fail(RPIV_EIO, "%s: cannot read list: %s", list, strerror(errno));
    fclose(f);
    free(line);
    free(dir);
    if (!st && p->n == 0)
        st = rpiv_fail(RPIV_EFORMAT, "%s: the list holds no image pair", list);
    return st;
}

/* ---- public ---------------------------------------------------------------------------- */

rpiv_status rpiv_pairs_from_args(int nargs, char *const *args, rpiv_pairing rule, rpiv_pairs **out)
{
    *out = NULL;
    if (nargs < 1)
        return rpiv_fail(RPIV_EINVAL, "image pairs: no image file, list or pattern given");
    rpiv_pairs *p = calloc(1, sizeof *p);
    if (!p)
        return rpiv_fail(RPIV_ENOMEM, "out of memory for the image pair list");
    size_t cap = 0;
    rpiv_status st = RPIV_OK;
    int nglob = 0;
    for (int i = 0; i < nargs; i++)
        nglob += is_glob(args[i]);
    if (nargs == 1 && nglob) {
        st = from_glob(args[0], rule, p, &cap);
    } else if (nargs == 1 && is_list(args[0])) {
        st = from_list(args[0], p, &cap);
    } else if (nargs == 1) {
        st = add_pair(p, &cap, args[0], NULL);
    } else if (nargs == 2 && nglob == 2) {
        /* Two patterns (frames A, frames B): the k-th A with the k-th B, in natural order. */
        glob_t ga, gb;
        memset(&ga, 0, sizeof ga);
        memset(&gb, 0, sizeof gb);
        int ra = glob(args[0], GLOB_ERR, NULL, &ga), rb = glob(args[1], GLOB_ERR, NULL, &gb);
        if (ra || rb) {
            st = rpiv_fail(RPIV_EIO, "%s: no file matches the pattern", ra ? args[0] : args[1]);
        } else if (ga.gl_pathc != gb.gl_pathc) {
            st = rpiv_fail(RPIV_EINVAL, "%s matches %zu files but %s matches %zu", args[0],
                           (size_t)ga.gl_pathc, args[1], (size_t)gb.gl_pathc);
        } else {
            qsort(ga.gl_pathv, ga.gl_pathc, sizeof(char *), natcmp_qsort);
            qsort(gb.gl_pathv, gb.gl_pathc, sizeof(char *), natcmp_qsort);
            for (size_t i = 0; i < ga.gl_pathc && !st; i++)
                st = add_pair(p, &cap, ga.gl_pathv[i], gb.gl_pathv[i]);
        }
        globfree(&ga);
        globfree(&gb);
    } else if (nglob) {
        st = rpiv_fail(RPIV_EINVAL,
                       "image pairs: a pattern must be given alone (or as two patterns, A "
                       "and B); got %d arguments",
                       nargs);
    } else if (nargs == 2) {
        st = add_pair(p, &cap, args[0], args[1]);
    } else {
        /* Many files (a pattern the shell expanded): pair them like a glob. */
        char **v = malloc((size_t)nargs * sizeof *v);
        if (!v) {
            st = rpiv_fail(RPIV_ENOMEM, "out of memory for %d file names", nargs);
        } else {
            memcpy(v, args, (size_t)nargs * sizeof *v);
            qsort(v, (size_t)nargs, sizeof *v, natcmp_qsort);
            st = pair_files(v, (size_t)nargs, rule, "image files", p, &cap);
            free(v);
        }
    }
    if (st) {
        rpiv_pairs_free(p);
        return st;
    }
    *out = p;
    return RPIV_OK;
}

/* The two frames of a pair from two sources (two files, or pages 0 and 1 of one file), read
 * side by side when OpenMP has a second thread for it: each reader has its own handle and
 * reports into its own thread's message, taken back here; frame a's error first, as when read
 * one after the other. */
static rpiv_status load_two(const char *pa, int ka, const char *pb, int kb, rpiv_image **a,
                            rpiv_image **b)
{
    rpiv_status st[2] = {RPIV_OK, RPIV_OK};
    char msg[2][1024] = {"", ""};
#pragma omp parallel for num_threads(2) schedule(static, 1) if (omp_get_max_threads() > 1)
    for (int k = 0; k < 2; k++) {
        st[k] = rpiv_image_load(k ? pb : pa, k ? kb : ka, k ? b : a, NULL);
        if (st[k])
            snprintf(msg[k], sizeof msg[k], "%s", rpiv_errmsg());
    }
    for (int k = 0; k < 2; k++)
        if (st[k])
            return rpiv_fail(st[k], "%s", msg[k]);
    return RPIV_OK;
}

static rpiv_status load_pair(const rpiv_pair_src *s, rpiv_image **a, rpiv_image **b)
{
    rpiv_status st;
    if (!s->path_b) {
        int npages;
        st = rpiv_image_count_pages(s->path_a, &npages);
        if (st)
            return st;
        if (npages >= 2)
            st = load_two(s->path_a, 0, s->path_a, 1, a, b);
        else
            return rpiv_image_load_halves(s->path_a, a, b, NULL);
    } else {
        st = load_two(s->path_a, 0, s->path_b, 0, a, b);
    }
    if (!st && ((*a)->w != (*b)->w || (*a)->h != (*b)->h)) {
        if (s->path_b)
            st = rpiv_fail(RPIV_ESIZE, "%s (%dx%d) and %s (%dx%d) differ in size", s->path_a,
                           (*a)->w, (*a)->h, s->path_b, (*b)->w, (*b)->h);
        else
            st = rpiv_fail(RPIV_ESIZE, "%s: page 0 (%dx%d) and page 1 (%dx%d) differ in size",
                           s->path_a, (*a)->w, (*a)->h, (*b)->w, (*b)->h);
    }
    return st;
}

rpiv_status rpiv_pairs_load(const rpiv_pairs *p, size_t i, rpiv_image **a, rpiv_image **b)
{
    *a = *b = NULL;
    if (i >= p->n)
        return rpiv_fail(RPIV_EINVAL, "pair %zu requested but there are %zu pairs", i + 1, p->n);
    rpiv_status st = load_pair(&p->pair[i], a, b);
    if (st) {
        rpiv_image_free(*a);
        rpiv_image_free(*b);
        *a = *b = NULL;
        if (p->n > 1) {
            char msg[1024];
            snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
            st = rpiv_fail(st, "pair %zu of %zu: %s", i + 1, p->n, msg);
        }
    }
    return st;
}
