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
    rpiv_status st = rpiv_experiment_check(e);
    if (st)
        return st;
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
    if ((st = rpiv_ccm_model_check(&m)) || (st = rpiv_ccm_work_new(&p, &w)))
        goto out_free;
    st = rpiv_ccm_predict(&m, w, out);
    if (scale_px)
        *scale_px = m.scale_px;
out_free:
    rpiv_ccm_work_free(w);
    rpiv_sheet_free(sheet);
    rpiv_ccm_curve_free(presence);
    return st;
}

const char *rpiv_version_string(void)
{
    return RPIV_VERSION_STRING;
}
