/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv plot - the figure of a vector file: a colour map of a quantity, arrows with a
 * reference arrow, the flags in a key, the camera image underneath on request. The figure
 * is rpiv_plot_field's (rpiv/plot.h); this file reads the files and names the output. */
#include "cli.h"

#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/plot.h"

#include <stddef.h>
#include <stdio.h>
#include <string.h>

rpiv_status cmd_plot(int argc, char **argv);

typedef struct plot_opts {
    const char *out, *quantity, *background;
    long every, time;
    double arrow_scale;
} plot_opts;

static const cli_opt options[] = {
    {.name = "output",
     .letter = 'o',
     .kind = CLI_STR,
     .arg = "OUT.png",
     .off = offsetof(plot_opts, out),
     .help = "the figure (required; PNG only)"},
    {.name = "quantity",
     .kind = CLI_STR,
     .arg = "Q",
     .off = offsetof(plot_opts, quantity),
     .help = "colour map of magnitude (default), u, v, peak_ratio, correlation,\n"
             "any per-vector quantity of the file (vorticity, sigma_u...), or none"},
    {.name = "background",
     .kind = CLI_STR,
     .arg = "IMAGE",
     .off = offsetof(plot_opts, background),
     .help = "image A in grey underneath (the colour map half transparent over\n"
             "it; --quantity none for the image alone)"},
    {.name = "every",
     .kind = CLI_LONG,
     .arg = "N",
     .off = offsetof(plot_opts, every),
     .min = 0,
     .max = 100000,
     .help = "an arrow at every N-th point along x and y (0: automatic, at most\n"
             "28 along the longer side)"},
    {.name = "time",
     .kind = CLI_LONG,
     .arg = "K",
     .off = offsetof(plot_opts, time),
     .min = 0,
     .max = 1000000000,
     .help = "the time step of a NetCDF file (.nc) to draw (0: the first)"},
    {.name = "arrow-scale",
     .kind = CLI_DOUBLE,
     .arg = "S",
     .off = offsetof(plot_opts, arrow_scale),
     .min = 1e-6,
     .max = 1e6,
     .help = "factor on the automatic arrow length (1: the 95 % quantile of the\n"
             "speeds spans 0.9 arrow spacing)"},
};

const cli_spec cmd_plot_spec = {
    .name = "plot",
    .usage = "usage: rpiv plot FIELD -o OUT.png [--quantity Q] [--background IMAGE] [--every N]\n"
             "                 [--arrow-scale S] [--time K]\n\n"
             "Draw the vector file FIELD (a text file of rpiv piv, or x y u v [flag] columns\n"
             "such as OpenPIV's; or a NetCDF file, .nc, of rpiv piv or in pivpy's layout, its\n"
             "first time step or --time K) into OUT.png: a colour map of the quantity with a "
             "colour bar\n"
             "and its unit, arrows with a reference arrow and its value, replaced vectors in\n"
             "red and masked points marked, with their counts in a key. Axes in px and px/dt,\n"
             "or mm and m/s when the file has a scale and dt; a y-up file is drawn y up.\n"
             "See docs/formats.md (Figures).\n\noptions:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .common = 1};

rpiv_status cmd_plot(int argc, char **argv)
{
    plot_opts o = {.arrow_scale = 1, .time = -1};
    cli_ctx c;
    int done;
    rpiv_status st;
    cli_ctx_init(&c);
    if ((st = cli_parse(&cmd_plot_spec, &c, &o, argc, argv, &done)) || done)
        return st;
    if (optind >= argc)
        return cli_usage_error("plot", "no vector file given (rpiv plot FIELD -o OUT.png)");
    if (optind + 1 < argc)
        return cli_usage_error("plot", "unexpected argument '%s' (one vector file)",
                               argv[optind + 1]);
    const char *in = argv[optind];
    if (!o.out)
        return cli_usage_error("plot", "no output: give -o OUT.png");
    if ((st = rpiv_plot_path_check(o.out)))
        return st;
    rpiv_field_format fmt = rpiv_field_format_of(in, NULL);
    if (fmt == RPIV_FIELD_DAT || fmt == RPIV_FIELD_VTK)
        return rpiv_fail(RPIV_EINVAL,
                         "%s: rpiv plot reads text (.txt) and NetCDF (.nc) vector files only", in);
    if (o.time >= 0 && fmt != RPIV_FIELD_NC)
        return cli_usage_error("plot", "--time applies to NetCDF files (.nc) only, not %s", in);
    rpiv_plot_field_params p = rpiv_plot_field_params_default();
    if (o.quantity)
        p.quantity = o.quantity;
    p.every = (int)o.every;
    p.arrow_scale = o.arrow_scale;
    if ((st = rpiv_plot_field_params_check(&p, NULL)))
        return st;
    rpiv_field *f = NULL;
    rpiv_image *bg = NULL;
    if ((st = fmt == RPIV_FIELD_NC ? rpiv_field_load_nc(in, o.time > 0 ? (size_t)o.time : 0, &f)
                                   : rpiv_field_load_txt(in, &f)))
        goto cleanup_field;
    if ((st = rpiv_plot_field_params_check(&p, f))) {
        char msg[1200];
        snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
        st = rpiv_fail(st, "%s: %s", in, msg);
        goto cleanup_field;
    }
    if (o.background) {
        int warned = 0;
        if ((st = rpiv_image_load(o.background, 0, &bg, &warned)))
            goto cleanup_field;
        p.background = bg;
    }
    const char *slash = strrchr(in, '/');
    rpiv_plot_field_info info;
    if ((st = rpiv_plot_field(f, o.out, slash ? slash + 1 : in, &p, &info)))
        goto cleanup_image;
    if (!c.quiet)
        printf("rpiv plot: %s -> %s: %s %.4g..%.4g, arrows every %d, reference %g %s\n", in, o.out,
               p.quantity, info.zmin, info.zmax, info.every, info.ref_value,
               info.physical ? "m/s" : "px/dt");
cleanup_image:
    rpiv_image_free(bg);
cleanup_field:
    rpiv_field_free(f);
    return st;
}
