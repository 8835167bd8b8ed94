/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The synthetic-image generator: particles, their motion, their images and the camera noise.
 * docs/model.md explains the model and every reading of the paper it makes. */
#include "synth_impl.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_min.h>
#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>
#include <omp.h>

/* Rows per render/noise band. The noise stream of a band is derived from its number, so this
 * is part of the definition of a pair's pixels: changing it changes the noise (not the
 * particles). It does not depend on the thread count. */
enum { BAND = 32 };

/* Stream tags: particles, and noise of (frame, band). */
#define TAG_PARTICLES 0ULL
#define TAG_NOISE     (1ULL << 40)

/* One particle image in one frame: centre (px), peak (counts) and sigma (px). */
typedef struct spot {
    double x, y, amp, sig;
} spot;

/* ---- seeds ---------------------------------------------------------------------------- */

/* A 64-bit finaliser (the splitmix64 one) so that neighbouring (seed, index, tag) give
 * unrelated streams. GSL's taus2 (L'Ecuyer's maximally equidistributed Tausworthe
 * generator, period 2^88) takes 32 bits of seed. */
static uint64_t mix64(uint64_t z)
{
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static unsigned long stream_seed(unsigned long seed, unsigned long index, uint64_t tag)
{
    uint64_t z = mix64(mix64(mix64((uint64_t)seed) ^ (uint64_t)index) ^ tag);
    return (unsigned long)((z ^ (z >> 32)) & 0xffffffffULL);
}

/* ---- making a generator ----------------------------------------------------------------- */

/* A Poisson count of mean m >= background (see POIS_STEP). */
static double shot(const rpiv_synth *s, double m, gsl_rng *r)
{
    double ex = m - s->e.synth.background;
    int t = ex > 0 ? (int)(ex / POIS_STEP) : 0;
    if (t >= s->npt)
        t = s->npt - 1;
    double rem = ex - t * POIS_STEP, c = 0;
    if (s->ptab[t])
        c = (double)(s->ptab_k0[t] + (long)gsl_ran_discrete(r, s->ptab[t]));
    if (rem > 0)
        c += gsl_ran_poisson(r, rem);
    return c;
}

/* The flow from the spec and the geometry. */
static rpiv_status flow_of_spec(rpiv_synth *s)
{
    int has_amp, has_centre;
    rpiv_status st = rpiv_synth_flow_parse(s->e.synth.flow, &s->flow, &has_amp, &has_centre);
    if (st)
        return st;
    double bulk = rpiv_channel_bulk_ms(&s->e.channel) * s->e.synth.dt_s *
                  s->e.camera.magnification / s->pix_m;
    switch (s->flow.kind) {
    case RPIV_FLOW_DUCT:
        s->flow.y0_star = s->y0s + 0.5 * s->spp;
        s->flow.ystar_per_px = s->spp;
        /* fall through */
    case RPIV_FLOW_POISEUILLE:
        if (!has_amp)
            s->flow.a = bulk;
        break;
    case RPIV_FLOW_POISEUILLE_Y:
        s->flow.height_px = s->h;
        break;
    case RPIV_FLOW_OSEEN:
        if (!has_centre) {
            s->flow.cx = 0.5 * (s->w - 1);
            s->flow.cy = 0.5 * (s->h - 1);
        }
        break;
    case RPIV_FLOW_UNIFORM:
    case RPIV_FLOW_SINE:
        break;
    }
    return RPIV_OK;
}

static rpiv_status flow_check(const rpiv_flow *f)
{
    if (f->kind < RPIV_FLOW_UNIFORM || f->kind > RPIV_FLOW_POISEUILLE_Y)
        return rpiv_fail(RPIV_EINVAL, "synth: unknown flow kind %d", (int)f->kind);
    if (!isfinite(f->a) || !isfinite(f->b) || !isfinite(f->cx) || !isfinite(f->cy) ||
        !isfinite(f->height_px) || !isfinite(f->y0_star) || !isfinite(f->ystar_per_px))
        return rpiv_fail(RPIV_EINVAL, "synth: flow parameters must be finite");
    if ((f->kind == RPIV_FLOW_OSEEN || f->kind == RPIV_FLOW_SINE) && !(f->b > 0))
        return rpiv_fail(RPIV_EINVAL, "synth: flow length b = %g must be > 0", f->b);
    if (f->kind == RPIV_FLOW_POISEUILLE_Y && !(f->height_px > 0))
        return rpiv_fail(RPIV_EINVAL, "synth: flow height_px = %g must be > 0", f->height_px);
    return RPIV_OK;
}

/* Particle region: the image and the margin; for the duct, only the fluid rows. */
static void region_of(rpiv_synth *s)
{
    double m = s->e.synth.margin_px;
    s->reg[0] = -0.5 - m;
    s->reg[1] = -0.5 - m;
    s->reg[2] = s->w - 0.5 + m;
    s->reg[3] = s->h - 0.5 + m;
    if (s->flow.kind != RPIV_FLOW_DUCT)
        return;
    const rpiv_flow *f = &s->flow;
    if (f->ystar_per_px == 0) {
        if (!(f->y0_star > 0 && f->y0_star < 1))
            s->reg[3] = s->reg[1];
        return;
    }
    double ya = (0 - f->y0_star) / f->ystar_per_px, yb = (1 - f->y0_star) / f->ystar_per_px;
    if (ya > yb) {
        double t = ya;
        ya = yb;
        yb = t;
    }
    if (ya > s->reg[1])
        s->reg[1] = ya;
    if (yb < s->reg[3])
        s->reg[3] = yb;
    if (s->reg[3] < s->reg[1])
        s->reg[3] = s->reg[1];
}

rpiv_status rpiv_synth_new(const rpiv_synth_setup *e, const rpiv_flow *flow, rpiv_synth **out)
{
    rpiv_status st;
    *out = NULL;
    if ((st = rpiv_camera_check(&e->camera)) || (st = rpiv_particles_check(&e->particles)) ||
        (st = rpiv_channel_check(&e->channel)) || (st = rpiv_sheet_params_check(&e->sheet)) ||
        (st = rpiv_synth_params_check(&e->synth)))
        return st;
    if (flow && (st = flow_check(flow)))
        return st;
    rpiv_synth *s = calloc(1, sizeof *s);
    if (!s)
        return rpiv_fail(RPIV_ENOMEM, "synth: out of memory");
    s->e = *e;
    const rpiv_camera *cam = &e->camera;
    s->w = e->synth.width_px ? e->synth.width_px : cam->width_px;
    s->h = e->synth.height_px ? e->synth.height_px : cam->height_px;
    s->pix_m = rpiv_camera_pixel_m(cam);
    s->spp = s->pix_m / (cam->magnification * e->channel.h_m);
    s->x0s = e->channel.fov_x0_star + 0.5 * (cam->width_px - s->w) * s->spp;
    s->y0s = e->channel.fov_y0_star + 0.5 * (cam->height_px - s->h) * s->spp;
    s->maxval = ldexp(1.0, e->synth.bits) - 1;
    if ((st = rpiv_sheet_new(&e->sheet, &s->sheet)))
        goto out_free;
    if (e->synth.pz_profile[0] && (st = synth_pz_load(s, e->synth.pz_profile)))
        goto out_free;
    if (flow)
        s->flow = *flow;
    else if ((st = flow_of_spec(s)))
        goto out_free;
    switch (s->flow.kind) {
    case RPIV_FLOW_UNIFORM:
    case RPIV_FLOW_POISEUILLE_Y:
    case RPIV_FLOW_SINE:
        s->invariant = 1; /* depends on y only, and v = 0 (or constant) */
        break;
    case RPIV_FLOW_DUCT:
    case RPIV_FLOW_POISEUILLE:
        s->invariant = e->synth.w_star == 0; /* depends on y and z*, v = 0 */
        break;
    case RPIV_FLOW_OSEEN:
        s->invariant = 0;
        break;
    }
    region_of(s);
    double area = (s->reg[2] - s->reg[0]) * (s->reg[3] - s->reg[1]);
    double np = floor(e->particles.density_ppp * area + 0.5);
    if (np > (double)(SIZE_MAX / 256)) {
        st = rpiv_fail(RPIV_ENOMEM, "synth: %g particles per pair is too many", np);
        goto out_free;
    }
    s->n = (size_t)np;
    double dp0 = e->particles.dp_m;
    s->de0_m = rpiv_imaging_de_m(cam, dp0, 0);
    s->norm = e->synth.peak_counts / rpiv_imaging_peak(cam, dp0 * dp0, s->de0_m, 0);
    if (e->synth.shot_noise && (st = synth_poisson_tables(s)))
        goto out_free;
    *out = s;
    return RPIV_OK;
out_free:
    rpiv_synth_free(s);
    return st;
}

void rpiv_synth_free(rpiv_synth *s)
{
    if (!s)
        return;
    rpiv_sheet_free(s->sheet);
    free(s->pz_z);
    free(s->pz_p);
    free(s->pz_c);
    if (s->ptab)
        for (int t = 0; t < s->npt; t++)
            if (s->ptab[t])
                gsl_ran_discrete_free(s->ptab[t]);
    free(s->ptab);
    free(s->ptab_k0);
    free(s);
}

void rpiv_synth_get_info(const rpiv_synth *s, rpiv_synth_info *info)
{
    memset(info, 0, sizeof *info);
    info->width_px = s->w;
    info->height_px = s->h;
    info->pixel_m = s->pix_m;
    info->star_per_px = s->spp;
    info->x0_star = s->x0s;
    info->y0_star = s->y0s;
    memcpy(info->region, s->reg, sizeof s->reg);
    info->nparticles = s->n;
    info->bulk_px = rpiv_channel_bulk_ms(&s->e.channel) * s->e.synth.dt_s *
                    s->e.camera.magnification / s->pix_m;
    info->de_focus_px = s->de0_m / s->pix_m;
    info->sigma_focus_px = rpiv_imaging_sigma_m(&s->e.camera, s->de0_m) / s->pix_m;
    info->flow = s->flow;
}

/* ---- particles and their motion --------------------------------------------------------- */

rpiv_status rpiv_synth_particles_new(const rpiv_synth *s, unsigned long index,
                                     rpiv_synth_particle **out, size_t *n)
{
    *out = NULL;
    *n = 0;
    rpiv_synth_particle *p = malloc((s->n ? s->n : 1) * sizeof *p);
    gsl_rng *r = gsl_rng_alloc(gsl_rng_taus2);
    if (!p || !r) {
        free(p);
        if (r)
            gsl_rng_free(r);
        return rpiv_fail(RPIV_ENOMEM, "synth: out of memory (%zu particles)", s->n);
    }
    gsl_rng_set(r, stream_seed(s->e.synth.seed, index, TAG_PARTICLES));
    double wx = s->reg[2] - s->reg[0], wy = s->reg[3] - s->reg[1];
    double dp = s->e.particles.dp_m, spread = s->e.particles.dp_sigma_m;
    for (size_t i = 0; i < s->n; i++) {
        p[i].x = s->reg[0] + wx * gsl_rng_uniform(r);
        p[i].y = s->reg[1] + wy * gsl_rng_uniform(r);
        p[i].z = synth_pz_sample(s, r);
        p[i].dp_m = dp + spread * (2 * gsl_rng_uniform(r) - 1);
    }
    gsl_rng_free(r);
    *out = p;
    *n = s->n;
    return RPIV_OK;
}

void rpiv_synth_particles_free(rpiv_synth_particle *p)
{
    free(p);
}

void rpiv_synth_advect(const rpiv_synth *s, const rpiv_synth_particle *mid, double tau,
                       rpiv_synth_particle *out)
{
    const rpiv_flow *f = &s->flow;
    double w = s->e.synth.w_star, u, v;
    *out = *mid;
    out->z = mid->z + tau * w;
    if (s->invariant) {
        rpiv_flow_eval(f, mid->x, mid->y, mid->z, &u, &v);
        out->x = mid->x + tau * u;
        out->y = mid->y + tau * v;
        return;
    }
    /* classical RK4 in the time fraction t (velocity in px per dt), z* moving with w */
    int n = s->e.synth.rk_steps;
    double hs = tau / n, x = mid->x, y = mid->y;
    for (int k = 0; k < n; k++) {
        double t = k * hs, z = mid->z + w * t, zh = z + 0.5 * hs * w, z1 = z + hs * w;
        double u1, v1, u2, v2, u3, v3, u4, v4;
        rpiv_flow_eval(f, x, y, z, &u1, &v1);
        rpiv_flow_eval(f, x + 0.5 * hs * u1, y + 0.5 * hs * v1, zh, &u2, &v2);
        rpiv_flow_eval(f, x + 0.5 * hs * u2, y + 0.5 * hs * v2, zh, &u3, &v3);
        rpiv_flow_eval(f, x + hs * u3, y + hs * v3, z1, &u4, &v4);
        x += hs / 6 * (u1 + 2 * u2 + 2 * u3 + u4);
        y += hs / 6 * (v1 + 2 * v2 + 2 * v3 + v4);
    }
    out->x = x;
    out->y = y;
}

/* ---- the image model -------------------------------------------------------------------- */

void rpiv_synth_image_model(const rpiv_synth *s, const rpiv_synth_particle *p, double *amp_counts,
                            double *de_px, double *sigma_px)
{
    const rpiv_camera *cam = &s->e.camera;
    double xstar = s->x0s + (p->x + 0.5) * s->spp;
    double zd = rpiv_imaging_defocus_m(cam, s->e.channel.h_m, p->z);
    double de = rpiv_imaging_de_m(cam, p->dp_m, zd);
    if (amp_counts) {
        double i0 = rpiv_sheet_eval(s->sheet, xstar, p->z);
        *amp_counts = i0 > 0 ? s->norm * rpiv_imaging_peak(cam, i0 * p->dp_m * p->dp_m, de, zd) : 0;
    }
    if (de_px)
        *de_px = de / s->pix_m;
    if (sigma_px)
        *sigma_px = rpiv_imaging_sigma_m(cam, de) / s->pix_m;
}

static void spot_of(const rpiv_synth *s, const rpiv_synth_particle *p, spot *sp)
{
    sp->x = p->x;
    sp->y = p->y;
    rpiv_synth_image_model(s, p, &sp->amp, NULL, &sp->sig);
}

/* Rows [*y0, *y1] of the image a spot touches; 0 if it is not drawn (too faint, or its box
 * misses the image). */
static int spot_rows(const rpiv_synth *s, const spot *p, int *y0, int *y1)
{
    if (!(p->amp > 0) || p->amp < s->e.synth.cutoff_counts)
        return 0;
    double r = s->e.synth.radius_sigma * p->sig;
    double xl = p->x - r - 0.5, xr = p->x + r + 0.5, yl = p->y - r - 0.5, yr = p->y + r + 0.5;
    if (!(xr >= 0 && xl <= s->w - 1 && yr >= 0 && yl <= s->h - 1))
        return 0;
    *y0 = yl < 0 ? 0 : (int)ceil(yl);
    *y1 = yr > s->h - 1 ? s->h - 1 : (int)floor(yr);
    return *y0 <= *y1;
}

/* Pixel integrals of a unit 1-D Gaussian over pixels i0..i1 (centres at integers). */
static void erf_weights(double c, double sig, int i0, int i1, double *wt)
{
    double k = 1 / (M_SQRT2 * sig), e0 = erf((i0 - 0.5 - c) * k);
    for (int i = i0; i <= i1; i++) {
        double e1 = erf((i + 0.5 - c) * k);
        wt[i - i0] = 0.5 * (e1 - e0);
        e0 = e1;
    }
}

/* Add a band's spots (rows b0 .. b1-1) into buf (band rows x image width). */
static void render_band(const rpiv_synth *s, const spot *sp, size_t cnt, int b0, int b1,
                        double *buf, double *wx, double *wy)
{
    double rad = s->e.synth.radius_sigma;
    for (size_t q = 0; q < cnt; q++) {
        const spot *p = &sp[q];
        double r = rad * p->sig;
        double xl = p->x - r - 0.5, xr = p->x + r + 0.5, yl = p->y - r - 0.5, yr = p->y + r + 0.5;
        int x0 = xl < 0 ? 0 : (int)ceil(xl), x1 = xr > s->w - 1 ? s->w - 1 : (int)floor(xr);
        int y0 = yl < b0 ? b0 : (int)ceil(yl), y1 = yr > b1 - 1 ? b1 - 1 : (int)floor(yr);
        if (x0 > x1 || y0 > y1)
            continue;
        erf_weights(p->x, p->sig, x0, x1, wx);
        erf_weights(p->y, p->sig, y0, y1, wy);
        double scale = p->amp * 2 * M_PI * p->sig * p->sig;
        for (int y = y0; y <= y1; y++) {
            double f = scale * wy[y - y0], *row = buf + (size_t)(y - b0) * (size_t)s->w;
            for (int x = x0; x <= x1; x++)
                row[x] += f * wx[x - x0];
        }
    }
}

/* Background, shot noise, read noise, rounding and saturation. */
static void noise_band(const rpiv_synth *s, const double *buf, size_t npx, float *out, gsl_rng *r)
{
    const rpiv_synth_params *sp = &s->e.synth;
    for (size_t k = 0; k < npx; k++) {
        double v = buf[k];
        if (sp->shot_noise) {
            v = shot(s, sp->background + v, r);
        } else {
            v += sp->background;
        }
        if (sp->read_noise > 0)
            v += gsl_ran_gaussian_ziggurat(r, sp->read_noise);
        v = floor(v + 0.5);
        out[k] = (float)(v < 0 ? 0 : v > s->maxval ? s->maxval : v);
    }
}

/* Per-band copies of the spots to draw, in spot order: list[start[b] .. start[b+1]) (copies,
 * not indices, so that each band reads its spots in sequence). */
static rpiv_status bucket(const rpiv_synth *s, const spot *sp, size_t n, int nb, size_t **start,
                          spot **list)
{
    size_t *st = calloc((size_t)nb + 1, sizeof *st), total = 0;
    if (!st)
        return rpiv_fail(RPIV_ENOMEM, "synth: out of memory");
    int y0, y1;
    for (size_t i = 0; i < n; i++)
        if (spot_rows(s, &sp[i], &y0, &y1))
            for (int b = y0 / BAND; b <= y1 / BAND; b++)
                st[b + 1]++;
    for (int b = 0; b < nb; b++)
        st[b + 1] += st[b];
    total = st[nb];
    spot *li = malloc((total ? total : 1) * sizeof *li);
    size_t *fill = malloc((size_t)nb * sizeof *fill);
    if (!li || !fill) {
        free(st);
        free(li);
        free(fill);
        return rpiv_fail(RPIV_ENOMEM, "synth: out of memory");
    }
    memcpy(fill, st, (size_t)nb * sizeof *fill);
    for (size_t i = 0; i < n; i++)
        if (spot_rows(s, &sp[i], &y0, &y1))
            for (int b = y0 / BAND; b <= y1 / BAND; b++)
                li[fill[b]++] = sp[i];
    free(fill);
    *start = st;
    *list = li;
    return RPIV_OK;
}

/* Draw nf frames: spots sp[f] into out[f] (w x h). With noise, out is overwritten by the
 * noisy, quantised image; without, the spots are added to out. */
static rpiv_status draw(const rpiv_synth *s, spot *const *sp, size_t n, float *const *out, int nf,
                        unsigned long index, int noise)
{
    int nb = (s->h + BAND - 1) / BAND;
    size_t *start[2] = {NULL, NULL};
    spot *list[2] = {NULL, NULL};
    rpiv_status st = RPIV_OK;
    for (int f = 0; f < nf && !st; f++)
        st = bucket(s, sp[f], n, nb, &start[f], &list[f]);
    int items = nf * nb, nomem = 0;
    if (st)
        goto out_free;
#pragma omp parallel reduction(| : nomem)
    {
        size_t w = (size_t)s->w;
        double *buf = malloc(BAND * w * sizeof *buf);
        double *wx = malloc((w + 2) * sizeof *wx), *wy = malloc((BAND + 2) * sizeof *wy);
        gsl_rng *r = noise ? gsl_rng_alloc(gsl_rng_taus2) : NULL;
        int ok = buf && wx && wy && (r || !noise);
        nomem |= !ok;
#pragma omp for schedule(dynamic, 1)
        for (int it = 0; it < items; it++) {
            if (!ok)
                continue;
            int f = it / nb, b = it % nb, b0 = b * BAND, b1 = b0 + BAND > s->h ? s->h : b0 + BAND;
            size_t npx = (size_t)(b1 - b0) * w;
            memset(buf, 0, npx * sizeof *buf);
            render_band(s, list[f] + start[f][b], start[f][b + 1] - start[f][b], b0, b1, buf, wx,
                        wy);
            float *o = out[f] + (size_t)b0 * w;
            if (noise) {
                gsl_rng_set(r, stream_seed(s->e.synth.seed, index,
                                           TAG_NOISE | ((uint64_t)f << 32) | (uint64_t)b));
                noise_band(s, buf, npx, o, r);
            } else {
                for (size_t k = 0; k < npx; k++)
                    o[k] += (float)buf[k];
            }
        }
        free(buf);
        free(wx);
        free(wy);
        if (r)
            gsl_rng_free(r);
    }
    if (nomem)
        st = rpiv_fail(RPIV_ENOMEM, "synth: out of memory (render buffers)");
out_free:
    for (int f = 0; f < 2; f++) {
        free(start[f]);
        free(list[f]);
    }
    return st;
}

static rpiv_status size_ok(const rpiv_synth *s, const rpiv_image *im, const char *what)
{
    if (im->w != s->w || im->h != s->h || !im->px)
        return rpiv_fail(RPIV_ESIZE, "synth: %s is %dx%d, the generator makes %dx%d", what, im->w,
                         im->h, s->w, s->h);
    return RPIV_OK;
}

rpiv_status rpiv_synth_render(const rpiv_synth *s, const rpiv_synth_particle *p, size_t n,
                              rpiv_image *im)
{
    rpiv_status st = size_ok(s, im, "image");
    if (st)
        return st;
    spot *sp = malloc((n ? n : 1) * sizeof *sp);
    if (!sp)
        return rpiv_fail(RPIV_ENOMEM, "synth: out of memory (%zu particles)", n);
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < n; i++)
        spot_of(s, &p[i], &sp[i]);
    spot *const frames[1] = {sp};
    float *const outs[1] = {im->px};
    st = draw(s, frames, n, outs, 1, 0, 0);
    free(sp);
    return st;
}

rpiv_status rpiv_synth_pair(const rpiv_synth *s, unsigned long index, rpiv_image *a, rpiv_image *b)
{
    rpiv_status st;
    if ((st = size_ok(s, a, "frame A")) || (st = size_ok(s, b, "frame B")))
        return st;
    rpiv_synth_particle *p;
    size_t n;
    if ((st = rpiv_synth_particles_new(s, index, &p, &n)))
        return st;
    spot *sp = malloc((n ? 2 * n : 1) * sizeof *sp);
    if (!sp) {
        rpiv_synth_particles_free(p);
        return rpiv_fail(RPIV_ENOMEM, "synth: out of memory (%zu particles)", n);
    }
    spot *sa = sp, *sb = sp + n;
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < n; i++) {
        rpiv_synth_particle q;
        rpiv_synth_advect(s, &p[i], -0.5, &q);
        spot_of(s, &q, &sa[i]);
        rpiv_synth_advect(s, &p[i], 0.5, &q);
        spot_of(s, &q, &sb[i]);
    }
    rpiv_synth_particles_free(p);
    spot *const frames[2] = {sa, sb};
    float *const outs[2] = {a->px, b->px};
    st = draw(s, frames, n, outs, 2, index, 1);
    free(sp);
    a->bits = b->bits = s->e.synth.bits;
    return st;
}

rpiv_status rpiv_synth_pair_double(const rpiv_synth *s, unsigned long index, rpiv_image *ab)
{
    if (ab->w != s->w || ab->h != 2 * s->h || !ab->px)
        return rpiv_fail(RPIV_ESIZE, "synth: double frame is %dx%d, the generator makes %dx%d",
                         ab->w, ab->h, s->w, 2 * s->h);
    rpiv_image a = {s->w, s->h, 0, ab->px};
    rpiv_image b = {s->w, s->h, 0, ab->px + (size_t)s->w * (size_t)s->h};
    rpiv_status st = rpiv_synth_pair(s, index, &a, &b);
    ab->bits = s->e.synth.bits;
    return st;
}

/* ---- ground truth ----------------------------------------------------------------------- */

/* z* of the sheet's peak at x*: the best of a scan of the channel height, refined by Brent's
 * minimiser of -I0 (the default R-PIV shape has a kink at its peak: no parabola fit). */
typedef struct peak_ctx {
    const rpiv_sheet *sheet;
    double xstar;
} peak_ctx;

static double minus_i0(double z, void *user)
{
    const peak_ctx *c = user;
    return -rpiv_sheet_eval(c->sheet, c->xstar, z);
}

static double sheet_peak(const rpiv_synth *s, double xstar)
{
    enum { NZ = 2000 };
    if (s->e.sheet.kind == RPIV_SHEET_UNIFORM)
        return s->e.camera.zop_star;
    int k = 0;
    double best = -1;
    for (int i = 0; i <= NZ; i++) {
        double v = rpiv_sheet_eval(s->sheet, xstar, (double)i / NZ);
        if (v > best) {
            best = v;
            k = i;
        }
    }
    double z = (double)k / NZ;
    if (k == 0 || k == NZ)
        return z;
    peak_ctx c = {s->sheet, xstar};
    gsl_function fn = {minus_i0, &c};
    double lo = (double)(k - 1) / NZ, hi = (double)(k + 1) / NZ;
    if (!(minus_i0(z, &c) < minus_i0(lo, &c) && minus_i0(z, &c) < minus_i0(hi, &c)))
        return z; /* a plateau: keep the first sample of the maximum */
    gsl_min_fminimizer *m = gsl_min_fminimizer_alloc(gsl_min_fminimizer_brent);
    if (!m || gsl_min_fminimizer_set(m, &fn, z, lo, hi)) {
        if (m)
            gsl_min_fminimizer_free(m);
        return z;
    }
    for (int it = 0; it < 200; it++) {
        if (gsl_min_fminimizer_iterate(m))
            break;
        lo = gsl_min_fminimizer_x_lower(m);
        hi = gsl_min_fminimizer_x_upper(m);
        if (gsl_min_test_interval(lo, hi, 1e-12, 0) == GSL_SUCCESS)
            break;
    }
    z = gsl_min_fminimizer_x_minimum(m);
    gsl_min_fminimizer_free(m);
    return z;
}

void rpiv_synth_truth(const rpiv_synth *s, rpiv_field *f)
{
    const rpiv_flow *fl = &s->flow;
    double tz = s->e.synth.truth_z;
    for (int i = 0; i < f->nx; i++) {
        double x = f->x0 + i * f->dx;
        double z = tz >= 0 ? tz : sheet_peak(s, s->x0s + (x + 0.5) * s->spp);
        for (int j = 0; j < f->ny; j++) {
            double y = f->y0 + j * f->dy, u, v;
            size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            rpiv_flow_eval(fl, x, y, z, &u, &v);
            int fluid = 1;
            if (fl->kind == RPIV_FLOW_DUCT) {
                double ys = fl->y0_star + y * fl->ystar_per_px;
                fluid = ys > 0 && ys < 1;
            }
            f->u[k] = (float)u;
            f->v[k] = (float)v;
            f->flag[k] = fluid ? RPIV_FLAG_VALID : RPIV_FLAG_MASKED;
            if (f->peak_ratio)
                f->peak_ratio[k] = 0;
            if (f->corr)
                f->corr[k] = 0;
        }
    }
    f->scale_mm_per_px = s->pix_m / s->e.camera.magnification * 1e3;
    f->dt_s = s->e.synth.dt_s;
}
