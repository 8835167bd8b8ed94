/* SPDX-License-Identifier: GPL-3.0-or-later */
/* What the figures of the report module share: output paths, the finite-series filter, the
 * even pick, the sheet-profile figure (calib, raytrace, demo), and the atomic text writer. */
#include "fig_impl.h"

#include "rpiv/report.h"

#include "base/atomic.h"

#include <math.h>
#include <stdio.h>

rpiv_status fig_path(char *buf, const char *dir, const char *name)
{
    if ((size_t)snprintf(buf, RPIV_PATH_MAX, "%s/%s", dir, name) >= RPIV_PATH_MAX)
        return rpiv_fail(RPIV_EINVAL, "%s/%s: path too long", dir, name);
    return RPIV_OK;
}

size_t fig_keep_finite(rpiv_plot_series *s, size_t n)
{
    size_t m = 0;
    for (size_t k = 0; k < n; k++) {
        int any = 0;
        for (size_t i = 0; i < s[k].n && !any; i++)
            any = isfinite(s[k].x[i]) && isfinite(s[k].y[i]);
        if (any)
            s[m++] = s[k];
    }
    return m;
}

size_t rpiv_report_pick(size_t s, size_t ns, size_t n)
{
    return ns > 1 ? s * (n - 1) / (ns - 1) : 0;
}

rpiv_status rpiv_report_sheet_profiles(const char *path, const char *title, const char *xlabel,
                                       const rpiv_plot_series *series, size_t n, double xmax)
{
    rpiv_plot_opts o = rpiv_plot_opts_default();
    if (xmax > 0) {
        o.xmin = 0;
        o.xmax = xmax;
    }
    o.ymin = 0;
    o.ymax = 1;
    return rpiv_plot_lines(path, title, xlabel, "z*", series, n, &o);
}

rpiv_status rpiv_report_write_file(const char *path, rpiv_report_writer write, const void *obj)
{
    atomic_file af;
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    if ((st = write(obj, af.fp))) {
        atomic_abort(&af);
        return st;
    }
    return atomic_commit(&af);
}
