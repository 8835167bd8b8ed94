/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/synth.h"

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
                               .double_frame = 0};
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
    if (!(p->peak_counts > 0) || !(p->background >= 0) || !(p->read_noise >= 0))
        return rpiv_fail(RPIV_EINVAL, "synth: peak, background and noise must be >= 0");
    if (!(p->margin_px >= 0 && p->margin_px <= 1024))
        return rpiv_fail(RPIV_EINVAL, "synth.margin_px: %g outside 0..1024", p->margin_px);
    return RPIV_OK;
}
