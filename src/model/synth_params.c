/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/synth.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the largest displacement amplitude a flow spec takes, px over dt */
#define RPIV_FLOW_MAX_PX 10000.0

rpiv_synth_params rpiv_synth_params_default(void)
{
    return (rpiv_synth_params){.width_px = 0,
                               .height_px = 0,
                               .pairs = 500,
                               .seed = 1,
                               .dt_s = 1e-3,
                               .bits = 16,
                               .peak_counts = 1000,
                               .background = 100,
                               .read_noise = 5,
                               .shot_noise = 1,
                               .margin_px = 16,
                               .w_star = 0,
                               .double_frame = 0,
                               .flow = "duct",
                               .truth_z = -1,
                               .pz_profile = "",
                               .radius_sigma = 4,
                               .cutoff_counts = 1e-3,
                               .rk_steps = 4};
}

rpiv_status rpiv_synth_params_check(const rpiv_synth_params *p)
{
    if (p->width_px < 0 || p->height_px < 0 || p->width_px > 65536 || p->height_px > 65536)
        return rpiv_fail(RPIV_EINVAL, "synth: image size %dx%d outside 0..65536", p->width_px,
                         p->height_px);
    if (p->pairs < 1 || p->pairs > 10000000)
        return rpiv_fail(RPIV_EINVAL, "synth.pairs: %d outside 1..1e7", p->pairs);
    if (!(p->dt_s > 0 && p->dt_s < 100))
        return rpiv_fail(RPIV_EINVAL, "synth.dt_s: %g outside (0, 100)", p->dt_s);
    if (p->bits != 8 && p->bits != 12 && p->bits != 16)
        return rpiv_fail(RPIV_EINVAL, "synth.bits: %d is not 8, 12 or 16", p->bits);
    if (!(p->peak_counts > 0 && p->peak_counts <= 1e9))
        return rpiv_fail(RPIV_EINVAL, "synth.peak_counts: %g outside (0, 1e9]", p->peak_counts);
    if (!(p->background >= 0 && p->background <= 1e9))
        return rpiv_fail(RPIV_EINVAL, "synth.background: %g outside 0..1e9", p->background);
    if (!(p->read_noise >= 0 && p->read_noise <= 1e9))
        return rpiv_fail(RPIV_EINVAL, "synth.read_noise: %g outside 0..1e9", p->read_noise);
    if (!(p->margin_px >= 0 && p->margin_px <= 1024))
        return rpiv_fail(RPIV_EINVAL, "synth.margin_px: %g outside 0..1024", p->margin_px);
    if (!(p->w_star >= -1 && p->w_star <= 1))
        return rpiv_fail(RPIV_EINVAL, "synth.w: %g outside -1..1", p->w_star);
    if (!(p->truth_z >= -1 && p->truth_z <= 1))
        return rpiv_fail(RPIV_EINVAL, "synth.truth_z: %g outside -1..1 (< 0: the sheet's peak)",
                         p->truth_z);
    if (!(p->radius_sigma >= 1 && p->radius_sigma <= 20))
        return rpiv_fail(RPIV_EINVAL, "synth.radius_sigma: %g outside 1..20", p->radius_sigma);
    if (!(p->cutoff_counts >= 0 && p->cutoff_counts <= 1e9))
        return rpiv_fail(RPIV_EINVAL, "synth.cutoff_counts: %g outside 0..1e9", p->cutoff_counts);
    if (p->rk_steps < 1 || p->rk_steps > 1000)
        return rpiv_fail(RPIV_EINVAL, "synth.rk_steps: %d outside 1..1000", p->rk_steps);
    if (!memchr(p->flow, '\0', sizeof p->flow) ||
        !memchr(p->pz_profile, '\0', sizeof p->pz_profile))
        return rpiv_fail(RPIV_EINVAL, "synth: flow or pz_profile is not a terminated string");
    rpiv_flow f;
    int has_amp, has_centre;
    rpiv_status st = rpiv_synth_flow_parse(p->flow, &f, &has_amp, &has_centre);
    if (st) {
        char msg[768];
        snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
        return rpiv_fail(st, "synth.flow: %s", msg);
    }
    return RPIV_OK;
}

/* The flow names, their kinds and how many numbers each takes (min..max). */
static const struct {
    const char *name;
    rpiv_flow_kind kind;
    int nmin, nmax;
} flows[] = {
    {"uniform", RPIV_FLOW_UNIFORM, 2, 2},       {"duct", RPIV_FLOW_DUCT, 0, 1},
    {"poiseuille", RPIV_FLOW_POISEUILLE, 0, 1}, {"poiseuille-y", RPIV_FLOW_POISEUILLE_Y, 1, 1},
    {"oseen", RPIV_FLOW_OSEEN, 2, 4},           {"sine", RPIV_FLOW_SINE, 2, 2},
};

const char *rpiv_synth_flow_name(rpiv_flow_kind kind)
{
    for (size_t k = 0; k < sizeof flows / sizeof flows[0]; k++)
        if (flows[k].kind == kind)
            return flows[k].name;
    return "?";
}

rpiv_synth_setup rpiv_synth_setup_default(void)
{
    rpiv_synth_setup s;
    memset(&s, 0, sizeof s);
    s.camera = rpiv_camera_default();
    s.particles = rpiv_particles_default();
    s.channel = rpiv_channel_default();
    s.sheet = rpiv_sheet_params_default();
    s.synth = rpiv_synth_params_default();
    return s;
}

rpiv_status rpiv_synth_flow_parse(const char *spec, rpiv_flow *flow, int *has_amp, int *has_centre)
{
    static const char *const usage =
        "uniform:U,V | duct[:A] | poiseuille[:A] | poiseuille-y:A | oseen:A,RC[,CX,CY] | sine:A,L";
    const char *colon = strchr(spec, ':');
    size_t len = colon ? (size_t)(colon - spec) : strlen(spec);
    size_t k = 0, nflows = sizeof flows / sizeof flows[0];
    while (k < nflows && !(strlen(flows[k].name) == len && !strncmp(flows[k].name, spec, len)))
        k++;
    if (k == nflows)
        return rpiv_fail(RPIV_EINVAL, "flow '%s': unknown flow (expected %s)", spec, usage);
    double v[4] = {0, 0, 0, 0};
    int n = 0;
    if (colon) {
        const char *c = colon + 1;
        for (;;) {
            char *end;
            errno = 0;
            double x = strtod(c, &end);
            if (end == c || errno || !isfinite(x) || n == 4)
                return rpiv_fail(RPIV_EINVAL, "flow '%s': bad number list (expected %s)", spec,
                                 usage);
            v[n++] = x;
            if (*end == '\0')
                break;
            if (*end != ',')
                return rpiv_fail(RPIV_EINVAL, "flow '%s': bad number list (expected %s)", spec,
                                 usage);
            c = end + 1;
        }
    }
    if (n < flows[k].nmin || n > flows[k].nmax || (flows[k].kind == RPIV_FLOW_OSEEN && n == 3))
        return rpiv_fail(RPIV_EINVAL, "flow '%s': %s takes %d to %d numbers, got %d (expected %s)",
                         spec, flows[k].name, flows[k].nmin, flows[k].nmax, n, usage);
    /* finite is not enough: oseen:1e300,1 gave inf displacements (issue 20 item 9) */
    int has_len = flows[k].kind == RPIV_FLOW_OSEEN || flows[k].kind == RPIV_FLOW_SINE;
    for (int i = 0; i < n; i++) {
        double lo = -RPIV_FLOW_MAX_PX, hi = RPIV_FLOW_MAX_PX;
        const char *what = "a displacement";
        if (i == 1 && has_len) {
            lo = 1e-3;
            hi = 1e6;
            what = flows[k].kind == RPIV_FLOW_OSEEN ? "the core radius" : "the wavelength";
        } else if (i >= 2) {
            lo = -1e6;
            hi = 1e6;
            what = "a centre coordinate";
        }
        if (!(v[i] >= lo && v[i] <= hi))
            return rpiv_fail(RPIV_EINVAL, "flow '%s': number %d (%s, px) %g outside %g..%g", spec,
                             i + 1, what, v[i], lo, hi);
    }
    memset(flow, 0, sizeof *flow);
    flow->kind = flows[k].kind;
    flow->a = v[0];
    flow->b = v[1];
    *has_amp = n > 0;
    *has_centre = 0;
    if (flow->kind == RPIV_FLOW_OSEEN) {
        if (!(v[1] > 0))
            return rpiv_fail(RPIV_EINVAL, "flow '%s': the core radius must be > 0", spec);
        if (n == 4) {
            flow->cx = v[2];
            flow->cy = v[3];
            *has_centre = 1;
        }
    }
    if (flow->kind == RPIV_FLOW_SINE && !(v[1] > 0))
        return rpiv_fail(RPIV_EINVAL, "flow '%s': the wavelength must be > 0", spec);
    return RPIV_OK;
}
