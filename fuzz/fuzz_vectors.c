/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz the text readers of `rpiv compare`: rpiv_text_columns (which decides profile or vector
 * file), rpiv_field_load_txt and rpiv_profile_load, on the same input.
 * Invariants: a field that loads has nx, ny >= 1, finite origin, positive finite steps and
 * finite u, v; compared with itself its E1 and RMS are 0; written back as rpiv text and read
 * again it gives the same grid and bit-identical u, v and flags (grids whose step is below
 * 1e-4 of the coordinates are left out: the text keeps 10 digits). A profile that loads has
 * n >= 2, strictly increasing finite alpha and finite values. A failure names the file. */
#include "fuzz.h"
#include "rpiv/field.h"

static void check_field(const rpiv_field *f, const char *path)
{
    FUZZ_CHECK(f->nx >= 1 && f->ny >= 1, "%s: grid %dx%d", path, f->nx, f->ny);
    FUZZ_CHECK(isfinite(f->x0) && isfinite(f->y0) && f->dx > 0 && f->dy > 0 && isfinite(f->dx) &&
                   isfinite(f->dy),
               "%s: origin (%g, %g) step (%g, %g)", path, f->x0, f->y0, f->dx, f->dy);
    FUZZ_CHECK(isfinite(f->scale_mm_per_px) && f->scale_mm_per_px >= 0 && isfinite(f->dt_s) &&
                   f->dt_s >= 0,
               "%s: scale %g mm/px, dt %g s", path, f->scale_mm_per_px, f->dt_s);
    size_t n = (size_t)f->nx * (size_t)f->ny;
    for (size_t k = 0; k < n; k++)
        FUZZ_CHECK(isfinite(f->u[k]) && isfinite(f->v[k]) && isfinite(f->peak_ratio[k]) &&
                       isfinite(f->corr[k]),
                   "%s: point %zu: u %g v %g", path, k, (double)f->u[k], (double)f->v[k]);
}

static void round_trip(const rpiv_field *f)
{
    double ext = fmax(1.0, fmax(fmax(fabs(f->x0), fabs(f->x0 + (f->nx - 1) * f->dx)),
                                fmax(fabs(f->y0), fabs(f->y0 + (f->ny - 1) * f->dy))));
    if (f->dx < 1e-4 * ext || f->dy < 1e-4 * ext)
        return;
    char path[256];
    snprintf(path, sizeof path, "%s/round_trip.txt", fuzz_dir());
    rpiv_status st = rpiv_field_save(f, NULL, path);
    FUZZ_CHECK(st == RPIV_OK, "save: %s", rpiv_errmsg());
    rpiv_field *g = NULL;
    st = rpiv_field_load_txt(path, &g);
    FUZZ_CHECK(st == RPIV_OK, "reload: %s", rpiv_errmsg());
    FUZZ_CHECK(g->nx == f->nx && g->ny == f->ny, "grid %dx%d back as %dx%d", f->nx, f->ny, g->nx,
               g->ny);
    FUZZ_CHECK(fabs(g->x0 - f->x0) <= 1e-9 * ext && fabs(g->y0 - f->y0) <= 1e-9 * ext,
               "origin (%.17g, %.17g) back as (%.17g, %.17g)", f->x0, f->y0, g->x0, g->y0);
    size_t n = (size_t)f->nx * (size_t)f->ny;
    for (size_t k = 0; k < n; k++)
        FUZZ_CHECK(g->u[k] == f->u[k] && g->v[k] == f->v[k] && g->flag[k] == f->flag[k] &&
                       g->peak_ratio[k] == f->peak_ratio[k] && g->corr[k] == f->corr[k],
                   "point %zu: (%.9g, %.9g, %d) back as (%.9g, %.9g, %d)", k, (double)f->u[k],
                   (double)f->v[k], f->flag[k], (double)g->u[k], (double)g->v[k], g->flag[k]);
    rpiv_field_free(g);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready;
    if (!ready) {
        rpiv_init();
        ready = 1;
    }
    const char *path = fuzz_file(data, size, ".txt");
    if (!path)
        return 0;
    int ncol = -1;
    rpiv_status st = rpiv_text_columns(path, &ncol);
    if (st == RPIV_OK)
        FUZZ_CHECK(ncol >= 0, "%d columns", ncol);
    else
        fuzz_check_failure(st, path);

    rpiv_field *f = (rpiv_field *)&f;
    st = rpiv_field_load_txt(path, &f);
    if (st == RPIV_OK) {
        check_field(f, path);
        rpiv_compare r;
        if (rpiv_field_compare(f, f, RPIV_COMPONENT_MAG, &r) == RPIV_OK)
            FUZZ_CHECK(r.e1 == 0 && r.rms == 0 && r.max_abs == 0 && r.n >= 1,
                       "self-comparison: E1 %g RMS %g max %g", r.e1, r.rms, r.max_abs);
        round_trip(f);
        rpiv_field_free(f);
    } else {
        FUZZ_CHECK(f == NULL, "failure left a field");
        fuzz_check_failure(st, path);
    }

    rpiv_profile *p = (rpiv_profile *)&p;
    st = rpiv_profile_load(path, &p);
    if (st == RPIV_OK) {
        FUZZ_CHECK(p->n >= 2, "%zu points", p->n);
        for (size_t i = 0; i < p->n; i++) {
            FUZZ_CHECK(isfinite(p->alpha[i]) && isfinite(p->value[i]), "point %zu", i);
            FUZZ_CHECK(i == 0 || p->alpha[i] > p->alpha[i - 1], "alpha not increasing at %zu", i);
        }
        /* compared with itself: every sample is used, the difference is rounding at most */
        double vmax = 0;
        for (size_t i = 0; i < p->n; i++)
            vmax = fmax(vmax, fabs(p->value[i]));
        rpiv_compare r;
        if (rpiv_profile_compare(p, p, &r) == RPIV_OK)
            FUZZ_CHECK(r.n == p->n && isfinite(r.e1) && r.e1 >= 0 && r.rms <= 1e-12 * vmax &&
                           r.max_abs <= 1e-12 * vmax,
                       "self-comparison: n %zu of %zu, E1 %g RMS %g max %g (values up to %g)", r.n,
                       p->n, r.e1, r.rms, r.max_abs, vmax);
        rpiv_profile_free(p);
    } else {
        FUZZ_CHECK(p == NULL, "failure left a profile");
        fuzz_check_failure(st, path);
    }
    return 0;
}
