/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The demo's image series: the image band and the PIV grid (step 2 with the duct), the P-PIV
 * z-scan (step 3) and the R-PIV series (step 4). Each series is synthesised by the synth module
 * and processed by the sum of correlation of the series module (rpiv_series_ensemble_source:
 * the loop of `rpiv piv --ensemble` over image files, here over pairs made in memory). */
#include "demo_impl.h"

#include "rpiv/ensemble.h"
#include "rpiv/flow.h"
#include "rpiv/piv.h"
#include "rpiv/report.h"
#include "rpiv/series.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- step 2: the band, the grid, the duct ------------------------------------------------- */

/* A generator for experiment e (only its geometry is read here). */
static rpiv_status band_info(const rpiv_experiment *e, rpiv_synth_info *info)
{
    rpiv_synth *s;
    rpiv_status st = rpiv_config_synth_new(e, NULL, &s);
    if (st)
        return st;
    rpiv_synth_get_info(s, info);
    rpiv_synth_free(s);
    return RPIV_OK;
}

/* Work units of one series of n pairs: its syntheses and its pair-passes. */
static size_t series_units(const demo_ctx *c, size_t n)
{
    size_t np = (size_t)c->e.piv.npass;
    double mb = 4.0 * (double)n * (double)c->w * (double)c->h / 1048576.0;
    return mb <= c->p.cache_mb ? n * (1 + np) : n * 2 * np;
}

rpiv_status demo_geometry(demo_ctx *c)
{
    rpiv_status st;
    rpiv_demo_result *r = c->res;
    /* the synthesis always makes the duct, the truth at the sheet's peak (gauss: z*_B) */
    snprintf(c->e.synth.flow, sizeof c->e.synth.flow, "duct");
    c->e.synth.truth_z = -1;
    c->e.piv.ensemble = 1;

    /* the band: the width asked, and the rows of the channel plus the margin, centred on the
     * field of view (the generator's window of the sensor) */
    rpiv_experiment e = c->e;
    e.synth.width_px = c->p.width_px ? c->p.width_px : e.camera.width_px;
    e.synth.height_px = e.camera.height_px;
    rpiv_synth_info in;
    if ((st = band_info(&e, &in)))
        return st;
    double yc = in.y0_star + 0.5 * in.height_px * in.star_per_px;
    double half = fmax(fabs(yc), fabs(1 - yc)) / in.star_per_px + c->p.margin_px;
    int h = 2 * (int)ceil(half);
    if (h > e.camera.height_px)
        h = e.camera.height_px;
    e.synth.height_px = h;
    if ((st = band_info(&e, &in)))
        return st;
    c->e.synth.width_px = in.width_px;
    c->e.synth.height_px = in.height_px;
    c->w = in.width_px;
    c->h = in.height_px;
    c->spp = in.star_per_px;
    c->x0s = in.x0_star;
    c->y0s = in.y0_star;
    c->bulk_px = in.bulk_px;
    r->width_px = c->w;
    r->height_px = c->h;
    r->x0_star = c->x0s;
    r->x1_star = c->x0s + c->w * c->spp;
    r->y0_star = c->y0s;
    r->y1_star = c->y0s + c->h * c->spp;
    r->bulk_px = c->bulk_px;
    /* the work ahead, for the progress: 2 traces, the series, the model and the inversion,
     * about 17 plots */
    c->total = 2 + (size_t)c->p.ppiv_planes * series_units(c, (size_t)c->p.ppiv_pairs) +
               series_units(c, (size_t)c->p.rpiv_pairs) + 2 + 17;
    return demo_tick(c, 0);
}

rpiv_status demo_flow(demo_ctx *c)
{
    rpiv_status st;
    rpiv_demo_result *r = c->res;
    demo_note(c,
              "step 2/6: the square duct at Re = %g (U_b = %.4g m/s), the image band and the "
              "PIV grid",
              c->e.channel.reynolds, rpiv_channel_bulk_ms(&c->e.channel));
    r->reynolds = c->e.channel.reynolds;
    r->umax_star = rpiv_duct_u(0.5, 0.5);

    /* the mask: rows whose centre lies in the fluid, 0 < y* < 1 */
    if ((st = rpiv_image_new(c->w, c->h, &c->mask)))
        return st;
    for (int y = 0; y < c->h; y++) {
        double ys = c->y0s + (y + 0.5) * c->spp;
        float v = ys > 0 && ys < 1 ? 1.0f : 0.0f;
        for (int x = 0; x < c->w; x++)
            c->mask->px[(size_t)y * (size_t)c->w + (size_t)x] = v;
    }

    char path[RPIV_PATH_MAX];
    if ((st = demo_path(c, "data/mask.png", path, sizeof path)) ||
        (st = rpiv_image_save_png16(c->mask, path)))
        return st;

    /* the grid of the final pass, from the engine */
    rpiv_piv *pv;
    if ((st = rpiv_piv_new(&c->e.piv, c->w, c->h, c->mask, &pv)))
        return st;
    rpiv_field *g;
    st = rpiv_piv_grid(pv, rpiv_piv_npass(pv) - 1, &g);
    rpiv_piv_free(pv);
    if (st)
        return st;
    c->nx = g->nx;
    c->ny = g->ny;
    c->gx0 = g->x0;
    c->gy0 = g->y0;
    c->gdx = g->dx;
    c->gdy = g->dy;
    rpiv_field_free(g);
    if (c->ny < 2 || c->nx < 1)
        return rpiv_fail(RPIV_ESIZE,
                         "demo: the PIV grid has %d x %d points; need at least "
                         "1 x 2 (widen the band or shrink the windows)",
                         c->nx, c->ny);
    r->grid_nx = c->nx;
    r->grid_ny = c->ny;
    size_t n = (size_t)c->nx * (size_t)c->ny;
    c->xs = malloc((size_t)c->nx * sizeof *c->xs);
    c->ys = malloc((size_t)c->ny * sizeof *c->ys);
    c->fluid = malloc(n);
    if (!c->xs || !c->ys || !c->fluid)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    for (int i = 0; i < c->nx; i++)
        c->xs[i] = c->x0s + (c->gx0 + i * c->gdx + 0.5) * c->spp;
    for (int j = 0; j < c->ny; j++)
        c->ys[j] = c->y0s + (c->gy0 + j * c->gdy + 0.5) * c->spp;
    /* compared vectors: window centres at least a quarter window inside the fluid (a window
     * centred on a wall has half its rows without particles) */
    const rpiv_piv_params *pp = &c->e.piv;
    double q = 0.25 * pp->win_h[pp->npass - 1] * c->spp;
    for (int j = 0; j < c->ny; j++)
        for (int i = 0; i < c->nx; i++)
            c->fluid[(size_t)j * (size_t)c->nx + (size_t)i] = c->ys[j] >= q && c->ys[j] <= 1 - q;
    demo_note(c,
              "  band %d x %d px: x* %.3f ... %.3f, y* %.3f ... %.3f (channel rows and %d px "
              "margins; rows outside 0 < y* < 1 masked); grid %d x %d; U* = 1 is %.3f px",
              c->w, c->h, r->x0_star, r->x1_star, r->y0_star, r->y1_star, c->p.margin_px, c->nx,
              c->ny, c->bulk_px);
    return RPIV_OK;
}

/* ---- one series ----------------------------------------------------------------------------- */

typedef struct series {
    const char *label; /* names the series in messages and files              */
    rpiv_experiment e; /* its experiment                                      */
    int npairs;
    const int *snap; /* final-pass snapshots after snap[k] pairs (may be NULL) */
    size_t nsnap;
    rpiv_field **snapf; /* [nsnap] out                                          */
    rpiv_field *final;  /* out: the ensemble field of the last pass              */
    rpiv_field *truth;  /* out: the synthetic truth on the same grid              */
    int save_first;     /* write pair 0 into DIR/images/<label>_a.tif, _b.tif and
                           the generator's parameters into DIR/data/<label>.ini     */
    rpiv_image *sample; /* out if save_first: frame A of pair 0                 */
} series;

/* Pair i into a, b: from the cache if it holds it, else synthesised (and cached if there
 * is a cache). The generator's values are integer counts, so 16-bit caching is exact. */
static rpiv_status get_pair(const rpiv_synth *s, uint16_t *cache, int cached, size_t i,
                            rpiv_image *a, rpiv_image *b)
{
    size_t np = (size_t)a->w * (size_t)a->h;
    if (cache && cached) {
        const uint16_t *ca = cache + 2 * i * np, *cb = ca + np;
        for (size_t k = 0; k < np; k++) {
            a->px[k] = ca[k];
            b->px[k] = cb[k];
        }
        return RPIV_OK;
    }
    rpiv_status st = rpiv_synth_pair(s, (unsigned long)i, a, b);
    if (st || !cache)
        return st;
    uint16_t *ca = cache + 2 * i * np, *cb = ca + np;
    for (size_t k = 0; k < np; k++) {
        ca[k] = (uint16_t)a->px[k];
        cb[k] = (uint16_t)b->px[k];
    }
    return RPIV_OK;
}

static rpiv_status save_pair(demo_ctx *c, const char *label, const rpiv_image *a,
                             const rpiv_image *b)
{
    char name[128], path[RPIV_PATH_MAX];
    rpiv_status st;
    snprintf(name, sizeof name, "images/%s_a.tif", label);
    if ((st = demo_path(c, name, path, sizeof path)) || (st = rpiv_image_save_tiff16(a, path)))
        return st;
    snprintf(name, sizeof name, "images/%s_b.tif", label);
    if ((st = demo_path(c, name, path, sizeof path)) || (st = rpiv_image_save_tiff16(b, path)))
        return st;
    return RPIV_OK;
}

/* The pairs of a series for the ensemble run (rpiv_series_source): synthesised, or taken from
 * the cache after the first pass, with the demo's progress, pair 0 saved, and the last pass
 * finished after snap[k] pairs (the sum of correlation of the first snap[k] pairs, with the
 * predictor of all pairs). */
typedef struct series_src {
    demo_ctx *c;
    series *sr;
    const rpiv_synth *s;
    uint16_t *cache; /* NULL: synthesised at every pass */
    int npass;
    size_t ks; /* snapshots taken */
} series_src;

static rpiv_status src_pair(void *user, size_t i, int pass, rpiv_image *a, rpiv_image *b)
{
    series_src *q = user;
    rpiv_status st;
    int fresh = !q->cache || pass == 0;
    if ((st = get_pair(q->s, q->cache, pass > 0, i, a, b)))
        return st;
    if (fresh && (st = demo_tick(q->c, 1)))
        return st;
    if (pass == 0 && i == 0 && q->sr->save_first) {
        if ((st = save_pair(q->c, q->sr->label, a, b)) || (st = rpiv_image_copy(a, &q->sr->sample)))
            return st;
    }
    return RPIV_OK;
}

static rpiv_status src_added(void *user, int pass, size_t i, const rpiv_ensemble *e)
{
    series_src *q = user;
    series *sr = q->sr;
    rpiv_status st;
    if ((st = demo_tick(q->c, 1)))
        return st;
    if (pass == q->npass - 1 && q->ks < sr->nsnap && (int)(i + 1) == sr->snap[q->ks]) {
        if ((st = rpiv_ensemble_finish(e, &sr->snapf[q->ks])))
            return st;
        q->ks++;
    }
    return RPIV_OK;
}

/* Synthesise and process a series: the ensemble run of the series module over the source
 * above (every pass reads all the pairs, adds them to the pass's accumulator, and the finished
 * field predicts the next pass). */
static rpiv_status series_run(demo_ctx *c, series *sr)
{
    rpiv_status st;
    rpiv_synth *s = NULL;
    rpiv_piv *pv = NULL;
    uint16_t *cache = NULL;
    size_t n = (size_t)sr->npairs;

    sr->e.synth.pairs = sr->npairs;
    if ((st = rpiv_config_synth_new(&sr->e, NULL, &s)))
        goto out;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    if (in.width_px != c->w || in.height_px != c->h) {
        st = rpiv_fail(RPIV_ESIZE, "demo: %s: images %d x %d, expected %d x %d", sr->label,
                       in.width_px, in.height_px, c->w, c->h);
        goto out;
    }
    if (sr->save_first) {
        char rel[128], path[RPIV_PATH_MAX];
        snprintf(rel, sizeof rel, "data/%s.ini", sr->label);
        if ((st = demo_path(c, rel, path, sizeof path)) ||
            (st = rpiv_config_save_synth(&sr->e, s, path)))
            goto out;
    }
    if ((st = rpiv_piv_new(&sr->e.piv, c->w, c->h, c->mask, &pv)))
        goto out;
    double mb = 4.0 * (double)n * (double)c->w * (double)c->h / 1048576.0;
    if (mb <= c->p.cache_mb) {
        cache = malloc(2 * n * (size_t)c->w * (size_t)c->h * sizeof *cache);
        /* no memory for the cache: synthesise again at every pass instead */
    }
    series_src q = {c, sr, s, cache, rpiv_piv_npass(pv), 0};
    rpiv_series_source src = {n, src_pair, src_added, &q};
    if ((st = rpiv_series_ensemble_source(pv, &src, NULL, &sr->final)) ||
        (st = rpiv_field_copy(sr->final, &sr->truth)))
        goto out;
    rpiv_synth_truth(s, sr->truth);
out:
    if (st && st != RPIV_EINTR) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
        st = rpiv_fail(st, "demo: %s: %s", sr->label, msg);
    }
    free(cache);
    rpiv_piv_free(pv);
    rpiv_synth_free(s);
    return st;
}

static void series_clear(series *sr)
{
    rpiv_field_free(sr->final);
    rpiv_field_free(sr->truth);
    rpiv_image_free(sr->sample);
    sr->final = sr->truth = NULL;
    sr->sample = NULL;
}

/* The grid of a result must be the demo's. */
static rpiv_status same_grid(const demo_ctx *c, const rpiv_field *f, const char *label)
{
    if (f->nx != c->nx || f->ny != c->ny || f->x0 != c->gx0 || f->y0 != c->gy0 || f->dx != c->gdx ||
        f->dy != c->gdy)
        return rpiv_fail(RPIV_ESIZE,
                         "demo: %s: the engine's grid %d x %d differs from the "
                         "plan's %d x %d",
                         label, f->nx, f->ny, c->nx, c->ny);
    return RPIV_OK;
}

/* Drop the vectors the engine masked from the compared ones; mask the others in the truth so
 * that field comparisons use the compared vectors only. */
static void and_fluid(demo_ctx *c, const rpiv_field *f, rpiv_field *truth)
{
    for (size_t k = 0; k < (size_t)c->nx * (size_t)c->ny; k++) {
        if (f->flag[k] == RPIV_FLAG_MASKED)
            c->fluid[k] = 0;
        if (!c->fluid[k])
            truth->flag[k] = RPIV_FLAG_MASKED;
    }
}

/* Save a field into DIR/data/<name>. */
static rpiv_status save_field(demo_ctx *c, const rpiv_field *f, const char *name, const char *what)
{
    char rel[128], path[RPIV_PATH_MAX];
    snprintf(rel, sizeof rel, "data/%s", name);
    rpiv_status st = demo_path(c, rel, path, sizeof path);
    if (st)
        return st;
    rpiv_meta m = {0};
    if (!(st = rpiv_meta_add(&m, "rpiv_demo", "%s", what)) &&
        !(st = rpiv_meta_add(&m, "bulk_px", "%.9g", c->bulk_px)) &&
        !(st = rpiv_meta_add(&m, "x0_star", "%.9g", c->x0s)) &&
        !(st = rpiv_meta_add(&m, "y0_star", "%.9g", c->y0s)) &&
        !(st = rpiv_meta_add(&m, "star_per_px", "%.9g", c->spp)))
        st = rpiv_field_save(f, &m, path);
    rpiv_meta_clear(&m);
    return st;
}

/* ---- step 3: the P-PIV z-scan -------------------------------------------------------------- */

/* The text of a slab's P(z*) file. */
typedef struct slab {
    double zb, slab, e_star, lo, hi;
} slab;

static rpiv_status print_slab(const void *obj, FILE *fp)
{
    const slab *sl = obj;
    fprintf(fp,
            "# P(z*) of the P-PIV plane z*_B = %.4f: uniform on z*_B +- %g e* "
            "(e* = %g)\n%.9f 1\n%.9f 1\n",
            sl->zb, sl->slab, sl->e_star, sl->lo, sl->hi);
    return RPIV_OK;
}

/* P(z*) of a plane: uniform on the slab z*_B +- slab e*, clipped to the channel. */
static rpiv_status write_slab(demo_ctx *c, double zb, char *path, size_t size)
{
    char rel[128];
    double d = c->p.ppiv_slab * c->p.ppiv_e_star;
    slab sl = {zb, c->p.ppiv_slab, c->p.ppiv_e_star, fmax(0.0, zb - d), fmin(1.0, zb + d)};
    snprintf(rel, sizeof rel, "data/ppiv_pz_%.4f.txt", zb);
    rpiv_status st = demo_path(c, rel, path, size);
    if (st)
        return st;
    return rpiv_report_write_file(path, print_slab, &sl);
}

rpiv_status demo_ppiv(demo_ctx *c)
{
    rpiv_status st = RPIV_OK;
    rpiv_demo_result *r = c->res;
    size_t nz = (size_t)c->p.ppiv_planes, plane = (size_t)c->nx * (size_t)c->ny;
    demo_note(c,
              "step 3/6: P-PIV z-scan, %zu thin sheets (e* = %g) z*_B = z*_OP = %g ... %g, "
              "%d pairs each, sum of correlation",
              nz, c->p.ppiv_e_star, c->p.ppiv_z0, c->p.ppiv_z0 + (double)(nz - 1) * c->p.ppiv_dz,
              c->p.ppiv_pairs);
    c->nz = nz;
    c->zk = malloc((nz + 2) * sizeof *c->zk);
    c->uvol = calloc((nz + 2) * plane, sizeof *c->uvol);
    c->plane_e1 = malloc(nz * sizeof *c->plane_e1);
    if (!c->zk || !c->uvol || !c->plane_e1)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    c->zk[0] = 0;
    c->zk[nz + 1] = 1;
    size_t kmid = 0;
    for (size_t k = 0; k < nz; k++) {
        c->zk[k + 1] = c->p.ppiv_z0 + (double)k * c->p.ppiv_dz;
        if (fabs(c->zk[k + 1] - 0.5) < fabs(c->zk[kmid + 1] - 0.5))
            kmid = k;
    }
    double e1sum = 0, e1max = 0;
    for (size_t k = 0; k < nz; k++) {
        double zb = c->zk[k + 1];
        char label[64];
        snprintf(label, sizeof label, "ppiv_z%.4f", zb);
        series sr = {.label = label, .e = c->e, .npairs = c->p.ppiv_pairs};
        sr.e.sheet.kind = RPIV_SHEET_GAUSS;
        sr.e.sheet.zb_star = zb;
        sr.e.sheet.e_star = c->p.ppiv_e_star;
        sr.e.camera.zop_star = zb;
        sr.e.synth.seed = c->e.synth.seed + 1 + k;
        sr.save_first = c->p.save_images && k == kmid;
        if ((st = write_slab(c, zb, sr.e.synth.pz_profile, sizeof sr.e.synth.pz_profile)) ||
            (st = series_run(c, &sr)) || (st = same_grid(c, sr.final, label)))
            goto out_clear;
        and_fluid(c, sr.final, sr.truth);
        for (size_t q = 0; q < plane; q++)
            c->uvol[(k + 1) * plane + q] = (double)sr.final->u[q] / c->bulk_px;
        rpiv_compare cmp;
        if ((st = rpiv_field_compare(sr.truth, sr.final, RPIV_COMPONENT_U, &cmp)))
            goto out_clear;
        c->plane_e1[k] = cmp.e1;
        e1sum += cmp.e1;
        e1max = fmax(e1max, cmp.e1);
        char name[80], what[160];
        snprintf(name, sizeof name, "%s.txt", label);
        snprintf(what, sizeof what, "P-PIV plane z*_B = z*_OP = %.4f, e* = %g, %d pairs", zb,
                 c->p.ppiv_e_star, c->p.ppiv_pairs);
        if ((st = save_field(c, sr.final, name, what)))
            goto out_clear;
        demo_note(c, "  plane z* = %.4f: E1 vs the analytic duct %.3f %%", zb, 100 * cmp.e1);
        if (k == kmid) {
            c->ppiv_mid = sr.final;
            c->zmid = zb;
            sr.final = NULL;
        }
    out_clear:
        series_clear(&sr);
        if (st)
            return st;
    }
    r->ppiv_planes = (int)nz;
    r->ppiv_pairs = c->p.ppiv_pairs;
    r->ppiv_e1_mean = e1sum / (double)nz;
    r->ppiv_e1_max = e1max;
    r->ppiv_e1_mid = c->plane_e1[kmid];
    return RPIV_OK;
}

/* ---- step 4: the R-PIV series -------------------------------------------------------------- */

rpiv_status demo_rpiv(demo_ctx *c)
{
    rpiv_status st;
    rpiv_demo_result *r = c->res;
    demo_note(c,
              "step 4/6: R-PIV, %d pairs through the refracted sheet, object plane z*_OP = "
              "%g, sum of correlation",
              c->p.rpiv_pairs, c->e.camera.zop_star);
    series sr = {.label = "rpiv", .e = c->e, .npairs = c->p.rpiv_pairs};
    sr.e.piv.uncertainty = 1; /* sigma_u, sigma_v of the ensemble: the report's coverage */
    sr.e.sheet = c->sheet_p;
    sr.snap = c->snap;
    sr.nsnap = c->nsnap;
    sr.snapf = c->snapf;
    sr.save_first = c->p.save_images;
    if ((st = series_run(c, &sr)) || (st = same_grid(c, sr.final, "rpiv")))
        goto out_clear;
    and_fluid(c, sr.final, sr.truth);
    size_t nf = 0, nrep = 0;
    for (size_t q = 0; q < (size_t)c->nx * (size_t)c->ny; q++)
        if (c->fluid[q]) {
            nf++;
            nrep += sr.final->flag[q] == RPIV_FLAG_REPLACED;
        }
    r->rpiv_pairs = c->p.rpiv_pairs;
    r->rpiv_replaced = nf ? (double)nrep / (double)nf : (double)NAN;
    rpiv_compare cmp;
    st = rpiv_field_compare(sr.truth, sr.final, RPIV_COMPONENT_U, &cmp);
    if (st == RPIV_EINVAL) {
        /* the truth at the sheet's peak is zero (a dark sheet): no figure, and the comparison
         * step says why */
        rpiv_errclear();
        st = RPIV_OK;
        cmp.e1 = (double)NAN;
    }
    if (st)
        goto out_clear;
    r->rpiv_e1_truth = cmp.e1;
    char what[160];
    snprintf(what, sizeof what, "R-PIV, %d pairs, z*_OP = %g", c->p.rpiv_pairs,
             c->e.camera.zop_star);
    if ((st = save_field(c, sr.final, "rpiv.txt", what)) ||
        (st = save_field(c, sr.truth, "rpiv_truth.txt", "analytic duct at z*_max(x*)")))
        goto out_clear;
    demo_note(c, "  %.2f %% of the fluid vectors replaced; E1 vs the analytic U at z*_max %.3f %%",
              100 * r->rpiv_replaced, 100 * cmp.e1);
    c->rfield = sr.final;
    c->sample = sr.sample;
    sr.final = NULL;
    sr.sample = NULL;
out_clear:
    series_clear(&sr);
    return st;
}
