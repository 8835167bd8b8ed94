/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/config/config_bind.c - flat entry points for bindings (the Python package over ctypes):
 * an experiment on the heap, set key by key with rpiv_config_set, and the jobs that need
 * several of its sections at once (the traced sheet, the CCM's prediction) as single calls. */
#include "rpiv/config.h"
#include "rpiv/version.h"

#include <stdlib.h>

rpiv_status rpiv_experiment_new(rpiv_experiment **out)
{
    *out = malloc(sizeof **out);
    if (!*out)
        return rpiv_fail(RPIV_ENOMEM, "experiment: out of memory");
    **out = rpiv_experiment_default();
    return RPIV_OK;
}

void rpiv_experiment_free(rpiv_experiment *e)
{
    free(e);
}

rpiv_piv_params *rpiv_experiment_piv(rpiv_experiment *e)
{
    return &e->piv;
}

rpiv_status rpiv_config_raytrace(const rpiv_experiment *e, const double *xstar, size_t nx,
                                 const rpiv_optics_opts *o, const rpiv_progress *progress,
                                 rpiv_optics_result **out)
{
    *out = NULL;
    rpiv_status st;
    if ((st = rpiv_laser_check(&e->laser)) || (st = rpiv_prism_check(&e->prism)) ||
        (st = rpiv_channel_check(&e->channel)) || (st = rpiv_optics_opts_check(o)))
        return st;
    if (!xstar || nx < 1)
        return rpiv_fail(RPIV_EINVAL, "raytrace: no station x* given");
    return rpiv_optics_trace(&e->laser, &e->prism, e->channel.h_m, xstar, nx, o, progress, out);
}

rpiv_status rpiv_config_ccm_predict(const rpiv_experiment *e, double dt_s, double xstar,
                                    double ystar, double zop_star, rpiv_ccm_peak *out,
                                    double *scale_px)
{
    rpiv_sheet *sheet = NULL;
    rpiv_ccm_curve *presence = NULL;
    rpiv_ccm_work *w = NULL;
    rpiv_ccm_model *mk = NULL;
    double *buf = NULL;
    rpiv_status st = rpiv_experiment_check(e);
    if (st)
        return st;
    if (e->bias.window_area < 0 || e->bias.window_area > 64)
        return rpiv_fail(RPIV_EINVAL, "bias: window_area %d outside 0..64", e->bias.window_area);
    rpiv_ccm_model m = rpiv_config_ccm_model(e, dt_s > 0 ? dt_s : e->synth.dt_s);
    rpiv_ccm_params p = rpiv_ccm_params_default();
    p.subpixel = e->piv.subpixel;
    m.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &ystar};
    if (zop_star >= 0)
        m.camera.zop_star = zop_star;
    if (e->synth.pz_profile[0]) {
        if ((st = rpiv_ccm_curve_load(e->synth.pz_profile, &presence)))
            goto out_free;
        m.presence = (rpiv_ccm_func){rpiv_ccm_curve_fn, presence};
    }
    if ((st = rpiv_sheet_new(&e->sheet, &sheet)))
        goto out_free;
    rpiv_ccm_sheet_at at = {sheet, xstar};
    m.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
    if ((st = rpiv_ccm_model_check(&m)) || (st = rpiv_ccm_work_new(&p, &w)) ||
        (st = rpiv_ccm_predict(&m, w, out)))
        goto out_free;
    if (scale_px)
        *scale_px = m.scale_px;
    /* [bias] window_area >= 2: the window's area average (docs/ccm.md, "The engine's window"):
     * the model at nx x ny sub-positions of equal area of the final window, the duct at each
     * one's y*, the sheet at its x*, the deformation following the flow's quadratic variation
     * as the engine's predictor does (an interior window); the centre's continuous peak stays
     * in out->dx, dy, value */
    const int nx = e->bias.window_area, ny = nx;
    if (m.window_w > 0 && m.window_h > 0 && nx >= 2) {
        size_t n = (size_t)nx * (size_t)ny;
        double spp = rpiv_camera_pixel_m(&e->camera) / (e->camera.magnification * e->channel.h_m);
        mk = malloc(n * sizeof *mk);
        buf = malloc(n * (3 * sizeof *buf + sizeof(rpiv_ccm_sheet_at)));
        if (!mk || !buf) {
            st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu sub-positions", n);
            goto out_free;
        }
        double *ox = buf, *oy = ox + n, *yk = oy + n;
        rpiv_ccm_sheet_at *atk = (rpiv_ccm_sheet_at *)(yk + n);
        for (size_t k = 0; k < n; k++) {
            int a = (int)(k % (size_t)nx), b = (int)(k / (size_t)nx);
            ox[k] = ((a + 0.5) / nx - 0.5) * m.window_w;
            oy[k] = ((b + 0.5) / ny - 0.5) * m.window_h;
            yk[k] = ystar + oy[k] * spp;
            atk[k] = (rpiv_ccm_sheet_at){sheet, xstar + ox[k] * spp};
            mk[k] = m;
            mk[k].u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &yk[k]};
            mk[k].illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &atk[k]};
        }
        /* a quadratic needs 3 sub-positions along each axis; fewer follow the plane */
        rpiv_ccm_area_opts o = rpiv_ccm_area_opts_default();
        o.quadratic = nx >= 3 && ny >= 3;
        rpiv_ccm_peak pa;
        if ((st = rpiv_ccm_predict_area(mk, ox, oy, n, &o, w, &pa)))
            goto out_free;
        out->dx_sub = pa.dx_sub;
        out->dy_sub = pa.dy_sub;
    }
out_free:
    free(buf);
    free(mk);
    rpiv_ccm_work_free(w);
    rpiv_sheet_free(sheet);
    rpiv_ccm_curve_free(presence);
    return st;
}

const char *rpiv_version_string(void)
{
    return RPIV_VERSION_STRING;
}
