/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/piv.h"

#include <math.h>

const char *const rpiv_subpixel_names[] = {"gauss", "parabola", "centroid", "spline", "auto", NULL};
const char *const rpiv_background_names[] = {"none", "min", "mean", NULL};
const char *const rpiv_replace_names[] = {"median", "inpaint", NULL};

rpiv_piv_params rpiv_piv_params_default(void)
{
    return (rpiv_piv_params){.npass = 3,
                             .win_w = {64, 32, 32},
                             .win_h = {64, 32, 32},
                             .overlap = 0.5,
                             .step_px = 0,
                             .ensemble = 0,
                             .subpixel = RPIV_SUBPIXEL_AUTO,
                             .median_thr = 2.0,
                             .median_eps = 0.1,
                             .median_lines = 1,
                             .search_radius = -1,
                             .cbc = 0,
                             .background = RPIV_BACKGROUND_NONE,
                             .roi = {0, 0, 0, 0},
                             .mask = "",
                             .threads = 0,
                             .scale_mm_per_px = 0,
                             .dt_s = 0,
                             .deform = 1,
                             .max_mem_mb = 4096,
                             .refine_max = 10,
                             .refine_tol_px = 0.02,
                             .refine_filter = 0,
                             .refine_denoise = 1,
                             .refine_denoise_order = 4,
                             .refine_notch = 6,
                             .refine_stop = 1,
                             .refine_defer = 0,
                             .edge_curvature = -1,
                             .spline_check = 1,
                             .ensemble_refine = 0,
                             .ensemble_refine_tol_px = 0.002,
                             .ensemble_denoise = 1,
                             .prep = rpiv_preprocess_params_default()};
}

rpiv_status rpiv_piv_params_check(const rpiv_piv_params *p)
{
    rpiv_status st = rpiv_preprocess_params_check(&p->prep);
    if (st)
        return st;
    if (p->npass < 1 || p->npass > RPIV_PIV_MAX_PASSES)
        return rpiv_fail(RPIV_EINVAL, "piv.windows: %d passes outside 1..%d", p->npass,
                         RPIV_PIV_MAX_PASSES);
    for (int i = 0; i < p->npass; i++)
        if (p->win_w[i] < 8 || p->win_h[i] < 8 || p->win_w[i] > 1024 || p->win_h[i] > 1024)
            return rpiv_fail(RPIV_EINVAL, "piv.windows: window %dx%d of pass %d outside 8..1024",
                             p->win_w[i], p->win_h[i], i + 1);
    if (!(p->overlap >= 0 && p->overlap <= 0.95))
        return rpiv_fail(RPIV_EINVAL, "piv.overlap: %g outside 0..0.95", p->overlap);
    if (p->step_px < 0 || p->step_px > 1024)
        return rpiv_fail(RPIV_EINVAL, "piv.step_px: %d outside 0..1024", p->step_px);
    if (p->subpixel < RPIV_SUBPIXEL_GAUSS || p->subpixel > RPIV_SUBPIXEL_AUTO)
        return rpiv_fail(RPIV_EINVAL, "piv.subpixel: unknown estimator %d", (int)p->subpixel);
    if (!(p->median_thr >= 0 && p->median_thr <= 100))
        return rpiv_fail(RPIV_EINVAL, "piv.median_threshold: %g outside 0..100", p->median_thr);
    if (!(p->median_eps >= 0 && p->median_eps <= 10))
        return rpiv_fail(RPIV_EINVAL, "piv.median_eps_px: %g outside 0..10", p->median_eps);
    if (!(p->scale_mm_per_px >= 0 && isfinite(p->scale_mm_per_px)) ||
        !(p->dt_s >= 0 && isfinite(p->dt_s)))
        return rpiv_fail(RPIV_EINVAL, "piv: scale and dt must be >= 0");
    if (p->median_lines != 0 && p->median_lines != 1)
        return rpiv_fail(RPIV_EINVAL, "piv.median_lines: %d is not 0 or 1", p->median_lines);
    if (p->threads < 0)
        return rpiv_fail(RPIV_EINVAL, "piv.threads: %d < 0", p->threads);
    if (p->cbc < 0 || p->cbc > 2)
        return rpiv_fail(RPIV_EINVAL, "piv.cbc: %d is not 0, 1 or 2", p->cbc);
    if (p->cbc && p->ensemble)
        return rpiv_fail(RPIV_EINVAL, "piv.cbc: the correlation-based correction is for "
                                      "instantaneous fields (an ensemble sums the planes already)");
    if (p->search_radius < -1 || p->search_radius > RPIV_PEAK_MAX_SIZE / 2)
        return rpiv_fail(RPIV_EINVAL, "piv.search_radius_px: %d outside -1..%d", p->search_radius,
                         RPIV_PEAK_MAX_SIZE / 2);
    if (p->refine_max < 0 || p->refine_max > 20)
        return rpiv_fail(RPIV_EINVAL, "piv.refine_max: %d outside 0..20", p->refine_max);
    if (!(p->refine_tol_px >= 0 && p->refine_tol_px <= 10))
        return rpiv_fail(RPIV_EINVAL, "piv.refine_tol_px: %g outside 0..10", p->refine_tol_px);
    if (p->refine_denoise != 0 && p->refine_denoise != 1)
        return rpiv_fail(RPIV_EINVAL, "piv.refine_denoise: %d is not 0 or 1", p->refine_denoise);
    if (p->refine_stop != 0 && p->refine_stop != 1)
        return rpiv_fail(RPIV_EINVAL, "piv.refine_stop: %d is not 0 or 1", p->refine_stop);
    if (p->refine_defer != 0 && p->refine_defer != 1)
        return rpiv_fail(RPIV_EINVAL, "piv.refine_defer: %d is not 0 or 1", p->refine_defer);
    if (p->refine_notch != 0 && (p->refine_notch < 2 || p->refine_notch > RPIV_PIV_NOTCH_MAX))
        return rpiv_fail(RPIV_EINVAL, "piv.refine_notch: %d is not 0 (off) or 2..%d",
                         p->refine_notch, RPIV_PIV_NOTCH_MAX);
    if (p->refine_denoise_order != 2 && p->refine_denoise_order != 4)
        return rpiv_fail(RPIV_EINVAL, "piv.refine_denoise_order: %d is not 2 or 4",
                         p->refine_denoise_order);
    if (p->ensemble_refine < 0 || p->ensemble_refine > 20)
        return rpiv_fail(RPIV_EINVAL, "piv.ensemble_refine: %d outside 0..20", p->ensemble_refine);
    if (!(p->ensemble_refine_tol_px >= 0 && p->ensemble_refine_tol_px <= 10))
        return rpiv_fail(RPIV_EINVAL, "piv.ensemble_refine_tol_px: %g outside 0..10",
                         p->ensemble_refine_tol_px);
    if (p->ensemble_denoise != 0 && p->ensemble_denoise != 1)
        return rpiv_fail(RPIV_EINVAL, "piv.ensemble_denoise: %d is not 0 or 1",
                         p->ensemble_denoise);
    if (p->spline_check != 0 && p->spline_check != 1)
        return rpiv_fail(RPIV_EINVAL, "piv.spline_check: %d is not 0 or 1", p->spline_check);
    if (p->edge_curvature < -1 || p->edge_curvature > 1)
        return rpiv_fail(RPIV_EINVAL, "piv.edge_curvature: %d is not -1, 0 or 1",
                         p->edge_curvature);
    if (!(p->refine_filter >= 0 && p->refine_filter <= 0.5))
        return rpiv_fail(RPIV_EINVAL, "piv.refine_filter: %g outside 0..0.5", p->refine_filter);
    if (!(p->peak_ratio_min >= 0 && p->peak_ratio_min <= 100))
        return rpiv_fail(RPIV_EINVAL, "piv.peak_ratio_min: %g outside 0..100", p->peak_ratio_min);
    if (!isfinite(p->u_min_px) || !isfinite(p->u_max_px) || !isfinite(p->v_min_px) ||
        !isfinite(p->v_max_px))
        return rpiv_fail(RPIV_EINVAL, "piv: velocity limits must be finite");
    if (!(p->std_k >= 0 && p->std_k <= 100))
        return rpiv_fail(RPIV_EINVAL, "piv.std_k: %g outside 0..100", p->std_k);
    if (p->replace != 0 && p->replace != 1)
        return rpiv_fail(RPIV_EINVAL, "piv.replace: %d is not 0 (median) or 1 (inpaint)",
                         p->replace);
    if (!(p->smooth >= 0 && p->smooth <= 1e6))
        return rpiv_fail(RPIV_EINVAL, "piv.smooth: %g outside 0..1e6", p->smooth);
    if (p->uncertainty != 0 && p->uncertainty != 1)
        return rpiv_fail(RPIV_EINVAL, "piv.uncertainty: %d is not 0 or 1", p->uncertainty);
    if (!(p->max_mem_mb > 0))
        return rpiv_fail(RPIV_EINVAL, "piv.max_mem_mb: %g must be > 0", p->max_mem_mb);
    return RPIV_OK;
}
