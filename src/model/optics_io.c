/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Text tables of the ray tracer's results, each with the parameters that made it. */
#include "rpiv/optics.h"

#include "base/atomic.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

/* "nan" on every platform, %.*g otherwise. */
static void num(FILE *fp, double v, const char *sep)
{
    if (isnan(v))
        fprintf(fp, "nan%s", sep);
    else
        fprintf(fp, "%.8g%s", v, sep);
}

static void header(FILE *fp, const char *what, const rpiv_laser *l, const rpiv_prism *p)
{
    fprintf(fp, "# rpiv raytrace %s\n", what);
    fprintf(fp,
            "# laser: beam_diameter_mm %g expander %g divergence_mrad %g lens_focal_mm %g "
            "lens_distance_mm %g bundle_mm %g rays %ld\n",
            l->beam_d_m * 1e3, l->expander, l->divergence_rad * 1e3, l->lens_f_m * 1e3,
            l->lens_dist_m * 1e3, l->bundle_m * 1e3, l->nrays);
    fprintf(fp, "# beta1_deg %g beta1_side %s polarisation %s\n", l->beta1_deg,
            rpiv_beta1_side_name(l->beta1_side), rpiv_polar_name(l->polar));
    fprintf(fp, "# prism: inclination_deg %g thickness_mm %g n_pmma %g n_water %g n_air %g\n",
            p->theta_p_deg, p->thickness_m * 1e3, p->n_pmma, p->n_water, p->n_air);
}

static void result_header(FILE *fp, const char *what, const rpiv_optics_result *r)
{
    const rpiv_optics_stats *s = &r->stats;
    const rpiv_optics_axis *a = &r->axis;
    header(fp, what, &r->laser, &r->prism);
    fprintf(fp, "# channel height_mm %g; bins dz* %g; smoothing sigma z* %g\n", r->h_m * 1e3,
            r->dz_star, r->smooth_star);
    fprintf(fp,
            "# axis: incidence on the floor %.6f deg (critical %.6f), elevation in the water "
            "%.6f deg%s\n",
            a->theta_i * 180 / M_PI, a->theta_c * 180 / M_PI, a->elevation * 180 / M_PI,
            a->transmitted ? "" : " (axis totally reflected)");
    fprintf(fp,
            "# power / Ig: transmitted %.6f reflected_face %.6f reflected_floor %.6f "
            "total_internal_reflection %.6f missed %.6g\n",
            s->transmitted, s->refl_face, s->refl_floor, s->tir, s->missed);
}

rpiv_status rpiv_optics_save_profile(const rpiv_optics_result *r, size_t k, const char *path)
{
    atomic_file t; /* unique temporary name, fsync, rename, fsync of the folder */
    rpiv_status st = atomic_begin(&t, path, 1);
    if (st)
        return st;
    result_header(t.fp, "profile", r);
    const double *p = r->inten + k * r->nz;
    double mx = 0;
    for (size_t j = 0; j < r->nz; j++)
        mx = fmax(mx, p[j]);
    fprintf(t.fp, "# x* %g\n# columns: z* I(Ig/h) I0*\n", r->xstar[k]);
    for (size_t j = 0; j < r->nz; j++) {
        num(t.fp, r->zstar[j], " ");
        num(t.fp, p[j], " ");
        num(t.fp, mx > 0 ? p[j] / mx : 0, "\n");
    }
    return atomic_commit(&t);
}

rpiv_status rpiv_optics_save_metrics(const rpiv_optics_result *r, const char *path)
{
    atomic_file t;
    rpiv_status st = atomic_begin(&t, path, 1);
    if (st)
        return st;
    result_header(t.fp, "metrics", r);
    fprintf(t.fp, "# columns: x* z*_inf z*_max z*_sup e* I_max(Ig/h)\n");
    for (size_t k = 0; k < r->nx; k++) {
        rpiv_sheet_metrics m;
        if (rpiv_sheet_metrics_of(r->zstar, r->inten + k * r->nz, r->nz, &m)) {
            rpiv_errclear();
            m.zinf = m.zmax = m.zsup = m.e = (double)NAN;
            m.imax = 0;
            for (size_t j = 0; j < r->nz; j++)
                m.imax = fmax(m.imax, r->inten[k * r->nz + j]);
        }
        num(t.fp, r->xstar[k], " ");
        num(t.fp, m.zinf, " ");
        num(t.fp, m.zmax, " ");
        num(t.fp, m.zsup, " ");
        num(t.fp, m.e, " ");
        num(t.fp, m.imax, "\n");
    }
    return atomic_commit(&t);
}

rpiv_status rpiv_optics_save_sweep(const rpiv_laser *l, const rpiv_prism *p, double xstar,
                                   const rpiv_optics_sweep_row *rows, size_t n, const char *path,
                                   const double *profiles, const rpiv_optics_opts *o,
                                   const char *profiles_path)
{
    atomic_file t;
    rpiv_status st = atomic_begin(&t, path, 1);
    if (st)
        return st;
    header(t.fp, "beta1 sweep", l, p);
    fprintf(t.fp, "# x* %g; I*_peak = I_peak / I_peak(beta1 = 2 deg)\n", xstar);
    fprintf(t.fp, "# columns: beta1_deg e* z*_inf z*_max z*_sup It/Ig I_peak(Ig/h) I*_peak "
                  "elevation_deg\n");
    for (size_t i = 0; i < n; i++) {
        const rpiv_optics_sweep_row *q = rows + i;
        num(t.fp, q->beta1_deg, " ");
        num(t.fp, q->e, " ");
        num(t.fp, q->zinf, " ");
        num(t.fp, q->zmax, " ");
        num(t.fp, q->zsup, " ");
        num(t.fp, q->it_ig, " ");
        num(t.fp, q->ipeak, " ");
        num(t.fp, q->ipeak_star, " ");
        num(t.fp, q->elevation_deg, "\n");
    }
    if ((st = atomic_commit(&t)) || !profiles)
        return st;
    if ((st = atomic_begin(&t, profiles_path, 1)))
        return st;
    header(t.fp, "beta1 sweep profiles I0*(z*)", l, p);
    fprintf(t.fp, "# x* %g\n# columns: z*", xstar);
    for (size_t i = 0; i < n; i++)
        fprintf(t.fp, " beta1=%g", rows[i].beta1_deg);
    fputc('\n', t.fp);
    size_t nz = rpiv_optics_nbins(o);
    double dz = 1.0 / (double)nz;
    for (size_t j = 0; j < nz; j++) {
        num(t.fp, ((double)j + 0.5) * dz, "");
        for (size_t i = 0; i < n; i++) {
            fputc(' ', t.fp);
            num(t.fp, profiles[i * nz + j], "");
        }
        fputc('\n', t.fp);
    }
    return atomic_commit(&t);
}

rpiv_status rpiv_optics_save_sensitivity(const rpiv_laser *l, const rpiv_prism *p,
                                         const rpiv_optics_sens_row *rows, size_t n, double cutoff,
                                         const char *path)
{
    atomic_file t;
    rpiv_optics_axis ax;
    rpiv_status st = rpiv_optics_axis_of(l, p, &ax);
    if (st || (st = atomic_begin(&t, path, 1)))
        return st;
    header(t.fp, "one-ray sensitivity to eta = n_pmma / n_water (paper fig. 10)", l, p);
    fprintf(t.fp,
            "# axis ray: incidence on the floor %.6f deg, eta0 %.6f; totally reflected for "
            "deta > %.6f\n",
            ax.theta_i * 180 / M_PI, p->n_pmma / p->n_water, cutoff);
    fprintf(t.fp, "# columns: deta theta_t_deg T dtheta_t/theta_t0 dT/T0 transmitted\n");
    for (size_t i = 0; i < n; i++) {
        const rpiv_optics_sens_row *q = rows + i;
        num(t.fp, q->deta, " ");
        num(t.fp, q->theta_t * 180 / M_PI, " ");
        num(t.fp, q->T, " ");
        num(t.fp, q->dtheta_rel, " ");
        num(t.fp, q->dT_rel, " ");
        fprintf(t.fp, "%d\n", q->transmitted);
    }
    return atomic_commit(&t);
}
