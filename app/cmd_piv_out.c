/* SPDX-License-Identifier: GPL-3.0-or-later */
/* app/cmd_piv_out.c - rpiv piv's outputs: the files' names and orientation, the sinks of the
 * batch, the header's metadata (app/cmd_piv.h). */
#include "cmd_piv.h"

#include "rpiv/version.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* OUT with `tag` inserted before the extension (tag "_0001", "_mean"). */
rpiv_status cmdpiv_out_name(const char *out, const char *tag, char *buf, size_t n)
{
    const char *dot;
    (void)rpiv_field_format_of(out, &dot); /* checked to be a known one before */
    int len = (int)(dot - out);
    if (snprintf(buf, n, "%.*s%s%s", len, out, tag, dot) >= (int)n)
        return rpiv_fail(RPIV_EINVAL, "%s: output path too long", out);
    return RPIV_OK;
}

/* An interrupted .nc series: the fields done so far go beside OUT, into OUT_partial.nc, never
 * over a complete OUT (issue 20 item 13). Returns RPIV_EINTR with the interruption's message
 * and where the fields are. */
rpiv_status cmdpiv_series_partial(rpiv_field_series *s, const char *out)
{
    char why[512], path[RPIV_PATH_MAX + 32];
    int written = 0;
    snprintf(why, sizeof why, "%s", rpiv_errmsg());
    rpiv_status st = cmdpiv_out_name(out, "_partial", path, sizeof path);
    if (st) {
        rpiv_status ign = rpiv_field_series_close(s, 1);
        (void)ign;
        return rpiv_fail(RPIV_EINTR, "%s; %s not written", why, out);
    }
    if ((st = rpiv_field_series_close_as(s, path, why, &written)))
        return rpiv_fail(RPIV_EINTR, "%s; %s not written, and the fields done were lost (%s)", why,
                         out, rpiv_errmsg());
    if (!written)
        return rpiv_fail(RPIV_EINTR, "%s; no field done, %s not written", why, out);
    return rpiv_fail(RPIV_EINTR, "%s; the fields done are in %s (%s not written)", why, path, out);
}

/* f as written: itself, or with --y-up or --derived (unless `plain`) a copy in *tmp, turned
 * and with the derived quantities (freed by the caller). */
static rpiv_status cmdpiv_oriented_as(const run_ctx *r, const rpiv_field *f, int plain,
                                      rpiv_field **tmp, const rpiv_field **out)
{
    *tmp = NULL;
    *out = f;
    const unsigned derived = plain ? 0 : r->derived;
    if (!r->y_up && !derived)
        return RPIV_OK;
    rpiv_status st = rpiv_field_copy(f, tmp);
    if (!st && derived) /* the physical sign: the same before or after turning */
        st = rpiv_field_derive(*tmp, derived);
    if (!st && r->y_up)
        st = rpiv_field_y_up(*tmp, r->height);
    if (!st)
        *out = *tmp;
    return st;
}

rpiv_status cmdpiv_oriented(const run_ctx *r, const rpiv_field *f, rpiv_field **tmp,
                            const rpiv_field **out)
{
    return cmdpiv_oriented_as(r, f, 0, tmp, out);
}

/* Save f as oriented; rms: f holds standard deviations, which keep their sign y-up. */
rpiv_status cmdpiv_save_as(const run_ctx *r, const rpiv_field *f, const rpiv_meta *meta,
                           const char *path, int rms)
{
    rpiv_field *tmp;
    const rpiv_field *g;
    rpiv_status st = cmdpiv_oriented_as(r, f, rms, &tmp, &g);
    for (size_t k = 0; !st && rms && tmp && k < (size_t)tmp->nx * (size_t)tmp->ny; k++)
        tmp->v[k] = tmp->v[k] == 0 ? 0.0f : -tmp->v[k];
    if (!st)
        st = rpiv_field_save(g, meta, path);
    rpiv_field_free(tmp);
    return st;
}

rpiv_status cmdpiv_save(const run_ctx *r, const rpiv_field *f, const rpiv_meta *meta,
                        const char *path)
{
    return cmdpiv_save_as(r, f, meta, path, 0);
}

/* On the rank that made pair i's field: its own file, unless it goes into a .nc series. */
rpiv_status cmdpiv_local_sink(void *user, size_t i, const rpiv_field *f)
{
    run_ctx *r = user;
    if (r->nc_series)
        return RPIV_OK;
    if (r->npairs == 1)
        return cmdpiv_save(r, f, r->meta, r->out);
    char tag[32], path[RPIV_PATH_MAX + 32];
    snprintf(tag, sizeof tag, "_%0*zu", r->digits, i + 1);
    rpiv_status st = cmdpiv_out_name(r->out, tag, path, sizeof path);
    return st ? st : cmdpiv_save(r, f, r->meta, path);
}

/* On rank 0, every field in pair order: counts, the .nc series, statistics, the first. */
rpiv_status cmdpiv_root_sink(void *user, size_t i, const rpiv_field *f)
{
    run_ctx *r = user;
    rpiv_status st = RPIV_OK;
    r->nvec += (size_t)f->nx * (size_t)f->ny;
    r->nreplaced += rpiv_field_count(f, RPIV_FLAG_REPLACED);
    if (r->series) {
        rpiv_field *tmp;
        const rpiv_field *g;
        st = cmdpiv_oriented(r, f, &tmp, &g);
        if (!st) /* t: the pair index, in frames */
            st = rpiv_field_series_append(r->series, g, (double)i);
        rpiv_field_free(tmp);
    }
    if (!st && r->stats)
        st = rpiv_series_stats_add(r->stats, f);
    if (!st && !r->first) {
        r->first_index = i;
        st = rpiv_field_copy(f, &r->first);
    }
    return st;
}

/* --skip-bad: say which pair is left out, on the rank that found it. */
void cmdpiv_warn_skip(void *user, size_t index, const char *msg)
{
    (void)user;
    (void)index;
    fprintf(stderr, "rpiv piv: warning: skipped: %s\n", msg);
}

/* The skipped pairs into the header: "I A B; ..." (1-based index, the pair's files). */
rpiv_status cmdpiv_add_skipped(rpiv_meta *m, const rpiv_batch *b, const rpiv_pairs *pairs)
{
    size_t n = rpiv_batch_nskipped(b), len = 1;
    if (!n)
        return RPIV_OK;
    for (size_t k = 0; k < n; k++) {
        const rpiv_pair_src *q = &pairs->pair[rpiv_batch_skipped(b, k)];
        len += strlen(q->path_a) + (q->path_b ? strlen(q->path_b) : 0) + 32;
    }
    char *list = malloc(len);
    if (!list)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory");
    list[0] = '\0';
    for (size_t k = 0, at = 0; k < n; k++) {
        size_t i = rpiv_batch_skipped(b, k);
        const rpiv_pair_src *q = &pairs->pair[i];
        at += (size_t)snprintf(list + at, len - at, "%s%zu %s%s%s", k ? "; " : "", i + 1, q->path_a,
                               q->path_b ? " " : "", q->path_b ? q->path_b : "");
    }
    rpiv_status st = rpiv_meta_add(m, "skipped_pairs", "%zu", n);
    if (!st)
        st = rpiv_meta_add(m, "skipped", "%s", list);
    free(list);
    return st;
}

/* "files": the image files of every pair, "A B; C D; ..." (a NetCDF string array). */
static rpiv_status cmdpiv_add_files(rpiv_meta *m, const rpiv_pairs *pairs)
{
    size_t len = 1;
    for (size_t k = 0; k < pairs->n; k++)
        len += strlen(pairs->pair[k].path_a) +
               (pairs->pair[k].path_b ? strlen(pairs->pair[k].path_b) : 0) + 3;
    char *list = malloc(len);
    if (!list)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory");
    size_t at = 0;
    list[0] = '\0';
    for (size_t k = 0; k < pairs->n; k++) {
        const rpiv_pair_src *q = &pairs->pair[k];
        at += (size_t)snprintf(list + at, len - at, "%s%s%s%s", k ? "; " : "", q->path_a,
                               q->path_b ? " " : "", q->path_b ? q->path_b : "");
    }
    rpiv_status st = rpiv_meta_add(m, "files", "%s", list);
    free(list);
    return st;
}

rpiv_status cmdpiv_add_meta(rpiv_meta *m, const rpiv_piv_params *p, const rpiv_pairs *pairs,
                            const rpiv_piv *pv)
{
    static const char *const bg[] = {"none", "min", "mean"};
    char win[256] = "";
    for (int k = 0; k < p->npass; k++)
        snprintf(win + strlen(win), sizeof win - strlen(win), "%s%dx%d", k ? "," : "", p->win_w[k],
                 p->win_h[k]);
    rpiv_status st;
    if ((st = rpiv_meta_add(m, "software", "rpiv %s", RPIV_VERSION_STRING)) ||
        (st = rpiv_meta_add(m, "mode", "%s", p->ensemble ? "ensemble" : "instantaneous")) ||
        (st = rpiv_meta_add(m, "pairs", "%zu", pairs->n)) ||
        (st = rpiv_meta_add(m, "first_pair", "%s %s", pairs->pair[0].path_a,
                            pairs->pair[0].path_b ? pairs->pair[0].path_b : "(double frame)")) ||
        (st = rpiv_meta_add(m, "windows", "%s", win)) ||
        (st = rpiv_meta_add(m, "overlap", "%g", p->overlap)) ||
        (st = rpiv_meta_add(m, "step_px", "%d", p->step_px)) ||
        (st = rpiv_meta_add(m, "subpixel", "%s%s", rpiv_subpixel_names[p->subpixel],
                            p->subpixel != RPIV_SUBPIXEL_AUTO ? ""
                            : p->ensemble                     ? " (spline)"
                                                              : " (gauss)")) ||
        (st = rpiv_meta_add(m, "deform", "%s", p->deform ? "cubic B-spline, symmetric" : "off")) ||
        (st = rpiv_meta_add(m, "median_threshold", "%g", p->median_thr)) ||
        (st = rpiv_meta_add(m, "median_eps_px", "%g", p->median_eps)) ||
        (st = rpiv_meta_add(m, "search_radius_px", "%d", p->search_radius)) ||
        (p->cbc && (st = rpiv_meta_add(m, "cbc", "%d", p->cbc))) ||
        (p->ensemble && p->ensemble_refine &&
         (st = rpiv_meta_add(m, "ensemble_refine", "%d (tol %g px)", p->ensemble_refine,
                             p->ensemble_refine_tol_px))) ||
        (p->ensemble && !p->ensemble_denoise &&
         (st = rpiv_meta_add(m, "ensemble_denoise", "0 (the final predictor notched)"))) ||
        (st = rpiv_meta_add(m, "background", "%s", bg[p->background])) ||
        (st = rpiv_meta_add(m, "mask", "%s", p->mask[0] ? p->mask : "none")) ||
        (st = rpiv_meta_add(m, "roi", "%d,%d,%d,%d", p->roi[0], p->roi[1], p->roi[2], p->roi[3])) ||
        (st = rpiv_meta_add(m, "threads", "%d", rpiv_piv_threads(pv))) ||
        (st = rpiv_meta_add(m, "orientation", "%s", p->y_up ? "y-up" : "image")) ||
        (st = cmdpiv_add_files(m, pairs)))
        return st;
    return RPIV_OK;
}
