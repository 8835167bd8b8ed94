/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/config/config_map.c - the experiment mapped onto the modules' own parameters, and the
 * parameter files written from it. */
#include "rpiv/config.h"

#include "base/atomic.h"
#include "base/text.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_synth_setup rpiv_config_synth_setup(const rpiv_experiment *e)
{
    rpiv_synth_setup s;
    s.camera = e->camera;
    s.particles = e->particles;
    s.channel = e->channel;
    s.sheet = e->sheet;
    s.synth = e->synth;
    return s;
}

rpiv_status rpiv_config_synth_new(const rpiv_experiment *e, const rpiv_flow *flow, rpiv_synth **out)
{
    rpiv_synth_setup s = rpiv_config_synth_setup(e);
    return rpiv_synth_new(&s, flow, out);
}

rpiv_ccm_model rpiv_config_ccm_model(const rpiv_experiment *e, double dt_s)
{
    rpiv_ccm_model m = rpiv_ccm_model_default();
    m.camera = e->camera;
    m.h_m = e->channel.h_m;
    m.dp_m = e->particles.dp_m;
    m.scale_px = rpiv_ccm_scale_px(&e->camera, &e->channel, dt_s);
    m.pixel_box = e->bias.pixel_box;
    if (e->bias.window_model && e->piv.npass >= 1) { /* the final window (docs/ccm.md) */
        m.window_w = e->piv.win_w[e->piv.npass - 1];
        m.window_h = e->piv.win_h[e->piv.npass - 1];
        m.window_deform = e->piv.deform ? (e->bias.window_interp ? 2 : 1) : 0;
        m.window_pairs = e->bias.window_pairs;
    }
    return m;
}

rpiv_status rpiv_config_save_synth(const rpiv_experiment *e, const rpiv_synth *s, const char *path)
{
    atomic_file af; /* unique temporary name, fsync, rename, fsync of the folder */
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    FILE *fp = af.fp;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    const rpiv_flow *f = &in.flow;
    fprintf(fp,
            "# rpiv synth: the complete parameters of these pairs (rpiv synth --config FILE\n"
            "# makes them again). Derived figures:\n"
            "#   seed %lu, pairs %d (files pair_00001 = index 0)\n"
            "#   image %d x %d px, x* %.6f .. %.6f, y* %.6f .. %.6f (%.9g h per px)\n"
            "#   particles per pair %zu in x %.3f .. %.3f px, y %.3f .. %.3f px\n"
            "#   bulk displacement U_b dt M / pixel = %.6f px\n"
            "#   in-focus d_e = %.6f px, sigma = %.6f px\n"
            "#   flow %s: a %.9g, b %.9g, centre (%.6g, %.6g), y* at row 0 %.9g, y* per px %.9g\n",
            e->synth.seed, e->synth.pairs, in.width_px, in.height_px, in.x0_star,
            in.x0_star + in.width_px * in.star_per_px, in.y0_star,
            in.y0_star + in.height_px * in.star_per_px, in.star_per_px, in.nparticles, in.region[0],
            in.region[2], in.region[1], in.region[3], in.bulk_px, in.de_focus_px, in.sigma_focus_px,
            rpiv_synth_flow_name(f->kind), f->a, f->b, f->cx, f->cy, f->y0_star, f->ystar_per_px);
    st = rpiv_config_write(e, fp);
    if (st) {
        atomic_abort(&af);
        return rpiv_fail(RPIV_EIO, "%s: cannot write", path);
    }
    return atomic_commit(&af);
}

rpiv_status rpiv_config_ccm_measurements(const rpiv_experiment *e, const char *path,
                                         double scale_px, double ystar, rpiv_ccm_curve **out)
{
    *out = NULL;
    /* the first line tells an rpiv vector file; anything else (or nothing) is a curve, and
     * the curve reader reports what is wrong with it */
    FILE *fp = fopen(path, "r");
    char *line = NULL;
    size_t cap = 0;
    long lineno = 0;
    rpiv_status lst = RPIV_OK;
    int is_field = fp && text_getline(fp, &line, &cap, path, &lineno, &lst) >= 0 &&
                   strncmp(line, "# rpiv vector field", 19) == 0;
    free(line);
    if (fp)
        fclose(fp);
    if (!is_field)
        return rpiv_ccm_curve_load(path, out);
    rpiv_field *f = NULL;
    rpiv_synth *s = NULL;
    rpiv_status st = rpiv_field_load_txt(path, &f);
    if (!st)
        st = rpiv_config_synth_new(e, NULL, &s);
    if (!st) {
        rpiv_synth_info in;
        rpiv_synth_get_info(s, &in);
        rpiv_ccm_geometry g = {in.x0_star, in.y0_star, in.star_per_px};
        st = rpiv_ccm_profile_of_field(f, &g, scale_px, ystar, out);
    }
    rpiv_synth_free(s);
    rpiv_field_free(f);
    return st;
}

rpiv_status rpiv_config_sheet_bias(const rpiv_experiment *e, rpiv_field *f, size_t npairs,
                                   int threads, const rpiv_progress *progress)
{
    rpiv_sheet *sheet = NULL;
    rpiv_ccm_curve *presence = NULL;
    rpiv_synth *s = NULL;
    rpiv_status st = rpiv_experiment_check(e);
    if (st)
        return st;
    rpiv_ccm_model m = rpiv_config_ccm_model(e, e->piv.dt_s > 0 ? e->piv.dt_s : e->synth.dt_s);
    if (m.window_w > 0 && !(m.window_pairs > 0)) /* [bias] window_pairs 0: the field's own */
        m.window_pairs = (double)npairs;
    rpiv_ccm_params p = rpiv_ccm_params_default();
    p.subpixel = e->piv.subpixel;
    rpiv_ccm_bias_params bp = e->bias;
    bp.threads = threads;
    if (e->synth.pz_profile[0]) {
        if ((st = rpiv_ccm_curve_load(e->synth.pz_profile, &presence)))
            goto out_free;
        m.presence = (rpiv_ccm_func){rpiv_ccm_curve_fn, presence};
    }
    if ((st = rpiv_sheet_new(&e->sheet, &sheet)) || (st = rpiv_config_synth_new(e, NULL, &s)))
        goto out_free;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    rpiv_ccm_geometry g = {in.x0_star, in.y0_star, in.star_per_px};
    st = rpiv_ccm_bias_field(f, &m, sheet, &g, &bp, &p, progress);
out_free:
    rpiv_synth_free(s);
    rpiv_sheet_free(sheet);
    rpiv_ccm_curve_free(presence);
    return st;
}
