/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv derive - derived quantities (vorticity, divergence, strain, swirling strength, Q) of
 * an existing vector file, written with the field to a new file (rpiv_field_derive). */
#include "cli.h"

#include "rpiv/field.h"

#include <stddef.h>
#include <stdio.h>
#include <string.h>

rpiv_status cmd_derive(int argc, char **argv);

typedef struct opts {
    cli_ctx c;
    const char *out, *list;
    double dt, scale;
} opts;

static const cli_opt options[] = {
    {.name = "output",
     .letter = 'o',
     .kind = CLI_STR,
     .arg = "OUT",
     .off = offsetof(opts, out),
     .help = "output file: .txt, .nc, .dat or .vtk (required)"},
    {.name = "derived",
     .kind = CLI_STR,
     .arg = "LIST",
     .off = offsetof(opts, list),
     .help = "vorticity, divergence, strain, swirl, q, comma-separated, or\n"
             "all (all)"},
    {.name = "dt",
     .kind = CLI_DOUBLE,
     .arg = "S",
     .off = offsetof(opts, dt),
     .min = 1e-12,
     .max = 1e6,
     .help = "pulse separation, s (replaces the file's): with a scale, the\n"
             "files add the values per second"},
    {.name = "scale",
     .kind = CLI_DOUBLE,
     .arg = "MM_PER_PX",
     .off = offsetof(opts, scale),
     .min = 1e-12,
     .max = 1e6,
     .help = "physical scale, mm/px (replaces the file's)"},
};

const cli_spec cmd_derive_spec = {
    .name = "derive",
    .usage = "usage: rpiv derive FIELD -o OUT [--derived LIST] [--dt S] [--scale MM_PER_PX]\n\n"
             "Add derived quantities to a vector file (.txt: rpiv's own, or columns x y u v\n"
             "[flag] on a regular grid; .nc: its first field) and write it to OUT: vorticity,\n"
             "divergence, shear_strain, normal_strain, swirling_strength, q_criterion, by the\n"
             "least-squares stencil over +-2 grid steps (shorter next to masked points), with\n"
             "the physical sign (counter-clockwise as seen on the image is positive vorticity,\n"
             "in image or y-up files alike), in 1/dt (1/dt^2 for Q); with scale and dt the\n"
             "files add them per second. See docs/postprocess.md.\n\noptions:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .common = 1};

rpiv_status cmd_derive(int argc, char **argv)
{
    opts o = {0};
    int done;
    rpiv_status st;
    cli_ctx_init(&o.c);
    if ((st = cli_parse(&cmd_derive_spec, &o.c, &o, argc, argv, &done)) || done)
        return st;
    if (argc - optind != 1)
        return cli_usage_error("derive", "need one vector file FIELD (got %d)", argc - optind);
    if (!o.out)
        return cli_usage_error("derive", "no output given (-o OUT)");
    if (rpiv_field_format_of(o.out, NULL) == RPIV_FIELD_UNKNOWN)
        return cli_usage_error("derive", "-o %s: the extension must be .txt, .nc, .dat or .vtk",
                               o.out);
    unsigned what;
    if ((st = rpiv_field_derive_parse(o.list ? o.list : "all", &what)))
        return cli_usage_error("derive", "--derived: %s", rpiv_errmsg() + strlen("derived: "));
    if (!what)
        return cli_usage_error("derive", "--derived: nothing to derive");
    const char *in = argv[optind];
    const rpiv_field_format fmt = rpiv_field_format_of(in, NULL);
    if (fmt == RPIV_FIELD_DAT || fmt == RPIV_FIELD_VTK)
        return rpiv_fail(RPIV_EINVAL,
                         "%s: rpiv derive reads text (.txt) and NetCDF (.nc) vector files only",
                         in);
    rpiv_field *f = NULL;
    rpiv_meta meta = {0};
    /* a NetCDF series: its first field */
    if ((st = fmt == RPIV_FIELD_NC ? rpiv_field_load_nc(in, 0, &f) : rpiv_field_load_txt(in, &f)))
        return st;
    if (o.dt > 0)
        f->dt_s = o.dt;
    if (o.scale > 0)
        f->scale_mm_per_px = o.scale;
    if (!(st = rpiv_field_derive(f, what)) &&
        !(st = rpiv_meta_add(&meta, "derived_from", "%s", in)) &&
        !(st = rpiv_meta_add(&meta, "derived_stencil", "least squares, +-2 grid steps")))
        st = rpiv_field_save(f, &meta, o.out);
    if (!st && f->dt_s > 0 && !(f->scale_mm_per_px > 0))
        fprintf(stderr, "rpiv derive: warning: dt is set but no scale: the quantities stay in 1/dt "
                        "(per pair interval); give --scale MM_PER_PX for the columns per second\n");
    if (!st && !o.c.quiet)
        printf("rpiv derive: %s -> %s (%d x %d vectors)\n", in, o.out, f->nx, f->ny);
    rpiv_meta_clear(&meta);
    rpiv_field_free(f);
    return st;
}
