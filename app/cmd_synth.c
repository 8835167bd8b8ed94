/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv synth - synthetic PIV image pairs from the paper's particle-image model, with their
 * ground truth on the PIV grid and the complete parameters. */
#include "cli.h"

#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/mpi.h"
#include "rpiv/piv.h"
#include "rpiv/series.h"
#include "rpiv/synth.h"

#include <dirent.h>
#include <errno.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

rpiv_status cmd_synth(int argc, char **argv);
static rpiv_status run(const rpiv_experiment *e, int quiet, int overwrite, const rpiv_mpi *mpi);

/* Command-line values that override the configuration, applied after it is read. */
typedef struct synth_opts {
    cli_ctx c;
    const char *pairs, *out, *flow, *sheet, *seed, *size;
    int double_frame, overwrite;
} synth_opts;

#define SYNTH_STR(nm, a, field, text)                                                              \
    {                                                                                              \
        .name = nm, .kind = CLI_STR, .arg = a, .off = offsetof(synth_opts, field), .help = text    \
    }

static const cli_opt options[] = {
    SYNTH_STR("pairs", "N", pairs, "number of pairs (synth.pairs)"),
    SYNTH_STR("out", "DIR", out, "output folder (output.dir)"),
    SYNTH_STR("flow", "SPEC", flow,
              "uniform:U,V | duct[:A] | poiseuille[:A] | poiseuille-y:A |\n"
              "oseen:A,RC[,CX,CY] | sine:A,L, in px over dt (synth.flow);\n"
              "duct and poiseuille default to the bulk U_b dt M / pixel"),
    SYNTH_STR("sheet", "KIND", sheet,
              "ppiv (Gaussian sheet), rpiv (refracted self-similar sheet) or\n"
              "volume (uniform illumination) (sheet.kind)"),
    SYNTH_STR("seed", "S", seed, "random seed, 0..4294967295 (synth.seed)"),
    SYNTH_STR("size", "WxH", size,
              "image size, a window of the sensor centred on the field of\n"
              "view (synth.width_px, synth.height_px)"),
    {.name = "double-frame",
     .kind = CLI_FLAG,
     .off = offsetof(synth_opts, double_frame),
     .help = "write A above B in one file (synth.double_frame)"},
    {.name = "overwrite",
     .kind = CLI_FLAG,
     .off = offsetof(synth_opts, overwrite),
     .help = "write into a folder that is not empty, removing the pair\n"
             "files of an earlier run first (without it: an error)"},
};

const cli_spec cmd_synth_spec = {
    .name = "synth",
    .usage =
        "usage: rpiv synth [--config F] [--pairs N] [--out DIR] [--flow SPEC]\n"
        "                  [--sheet ppiv|rpiv|volume] [--seed S] [--size WxH] [--double-frame]\n\n"
        "Make N synthetic image pairs of the experiment (the paper's particle-image model,\n"
        "docs/model.md): DIR/pair_00001_a.tif and _b.tif (16-bit TIFF; one file\n"
        "pair_00001.tif, A above B, with --double-frame), DIR/truth.txt (the displacement of\n"
        "the flow on the grid of the [piv] section, in the format of 'rpiv piv') and\n"
        "DIR/synth.ini (every parameter and the seed: 'rpiv synth --config DIR/synth.ini'\n"
        "makes the same files again). The options below override --config and --set\n"
        "(--set S.K=V sets one key, e.g. --set particles.density_ppp=0.02; the results do\n"
        "not depend on --threads).\n\noptions:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .epilog =
        "\nUnder MPI ('mpirun -np K rpiv synth ...') pair i is made by rank i mod K; rank 0\n"
        "writes truth.txt and synth.ini. The files are the same for any K (docs/cluster.md).\n",
    .common = 1};

static rpiv_status apply(const synth_opts *o, rpiv_experiment *e)
{
    rpiv_status st;
    long v;
    if (o->pairs) {
        if ((st = cli_parse_int("--pairs", o->pairs, 1, 10000000, &v)))
            return st;
        e->synth.pairs = (int)v;
    }
    if (o->seed) {
        if ((st = cli_parse_int("--seed", o->seed, 0, 4294967295L, &v)))
            return st;
        e->synth.seed = (unsigned long)v;
    }
    if (o->size) {
        int w, h;
        if ((st = cli_parse_size("--size", o->size, 8, 65536, &w, &h)))
            return st;
        e->synth.width_px = w;
        e->synth.height_px = h;
    }
    if (o->flow) {
        rpiv_flow f;
        int has_amp, has_centre;
        if (strlen(o->flow) >= sizeof e->synth.flow)
            return cli_usage_error("synth", "--flow: spec too long");
        if ((st = rpiv_synth_flow_parse(o->flow, &f, &has_amp, &has_centre)))
            return cli_usage_error("synth", "--flow: %s", rpiv_errmsg());
        strcpy(e->synth.flow, o->flow);
    }
    if (o->sheet) {
        if (!strcmp(o->sheet, "ppiv"))
            e->sheet.kind = RPIV_SHEET_GAUSS;
        else if (!strcmp(o->sheet, "rpiv"))
            e->sheet.kind = RPIV_SHEET_SELFSIM;
        else if (!strcmp(o->sheet, "volume"))
            e->sheet.kind = RPIV_SHEET_UNIFORM;
        else
            return cli_usage_error("synth", "--sheet: '%s' is not ppiv, rpiv or volume", o->sheet);
    }
    if (o->out) {
        if (strlen(o->out) >= sizeof e->output.dir)
            return cli_usage_error("synth", "--out: path too long");
        strcpy(e->output.dir, o->out);
    }
    if (o->double_frame)
        e->synth.double_frame = 1;
    return RPIV_OK;
}

/* The grid of the final pass of `rpiv piv` for this image size and the [piv] section. */
static rpiv_status piv_grid(const rpiv_synth *s, const rpiv_experiment *e, rpiv_field **out)
{
    rpiv_synth_info in;
    rpiv_piv *pv = NULL;
    rpiv_synth_get_info(s, &in);
    rpiv_status st = rpiv_piv_new(&e->piv, in.width_px, in.height_px, NULL, &pv);
    if (!st)
        st = rpiv_piv_grid(pv, rpiv_piv_npass(pv) - 1, out);
    rpiv_piv_free(pv);
    return st;
}

/* Write truth.txt on the grid f. */
static rpiv_status write_truth(const rpiv_synth *s, const rpiv_experiment *e, rpiv_field *f,
                               const char *path)
{
    rpiv_meta m = {0};
    rpiv_status st;
    rpiv_synth_truth(s, f);
    if ((st = rpiv_meta_add(&m, "source", "rpiv synth ground truth")) ||
        (st = rpiv_meta_add(&m, "flow", "%s", e->synth.flow)) ||
        (st = rpiv_meta_add(&m, "seed", "%lu", e->synth.seed)))
        goto out;
    if (e->synth.truth_z >= 0)
        st = rpiv_meta_add(&m, "truth_z", "%.17g", e->synth.truth_z);
    else
        st = rpiv_meta_add(&m, "truth_z", "sheet peak z*_max(x*)");
    if (!st)
        st = rpiv_field_save(f, &m, path);
out:
    rpiv_meta_clear(&m);
    return st;
}

/* Pair i of the generator written as TIFF files into dir. */
typedef struct pair_job {
    const rpiv_synth *s;
    const char *dir;
    int dbl;
    rpiv_image *a, *b;
} pair_job;

static rpiv_status write_pair(void *user, size_t i)
{
    pair_job *j = user;
    char path[RPIV_PATH_MAX + 64];
    rpiv_status st;
    if (j->dbl) {
        if ((st = rpiv_synth_pair_double(j->s, (unsigned long)i, j->a)))
            return st;
        snprintf(path, sizeof path, "%s/pair_%05zu.tif", j->dir, i + 1);
        return rpiv_image_save_tiff16(j->a, path);
    }
    if ((st = rpiv_synth_pair(j->s, (unsigned long)i, j->a, j->b)))
        return st;
    snprintf(path, sizeof path, "%s/pair_%05zu_a.tif", j->dir, i + 1);
    if ((st = rpiv_image_save_tiff16(j->a, path)))
        return st;
    snprintf(path, sizeof path, "%s/pair_%05zu_b.tif", j->dir, i + 1);
    return rpiv_image_save_tiff16(j->b, path);
}

/* Generate and write this rank's pairs (the series' loop deals them out), reporting progress. */
static rpiv_status write_pairs(const rpiv_synth *s, const rpiv_experiment *e, const char *dir,
                               int quiet, const rpiv_mpi *mpi)
{
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    pair_job j = {s, dir, e->synth.double_frame, NULL, NULL};
    rpiv_status st = rpiv_image_new(in.width_px, j.dbl ? 2 * in.height_px : in.height_px, &j.a);
    if (!st && !j.dbl)
        st = rpiv_image_new(in.width_px, in.height_px, &j.b);
    cli_progress pr;
    cli_progress_init(&pr, "synth", quiet);
    rpiv_progress prog = cli_progress_of(&pr);
    if (!st)
        st = rpiv_series_each((size_t)e->synth.pairs, mpi, write_pair, &j, &prog, "synth");
    rpiv_image_free(j.a);
    rpiv_image_free(j.b);
    return st;
}

rpiv_status cmd_synth(int argc, char **argv)
{
    synth_opts o = {0};
    int done;
    rpiv_status st;
    cli_ctx_init(&o.c);
    if ((st = cli_parse(&cmd_synth_spec, &o.c, &o, argc, argv, &done)) || done)
        return st;
    cli_ctx c = o.c;
    if (optind < argc)
        return cli_usage_error("synth", "unexpected argument '%s'", argv[optind]);
    rpiv_experiment *e = &c.exp;
    if ((st = apply(&o, e)) || (st = rpiv_experiment_check(e)))
        return st;
    rpiv_mpi *mpi = NULL;
    if ((st = rpiv_mpi_new(NULL, NULL, &mpi)))
        return st;
    st = run(e, c.quiet, o.overwrite, mpi);
    rpiv_mpi_free(mpi);
    return st;
}

/* 1 if name is one of the pair files rpiv synth writes: pair_NNNNN.tif, pair_NNNNN_a.tif or
 * pair_NNNNN_b.tif (five digits or more). */
static int is_pair_file(const char *name)
{
    if (strncmp(name, "pair_", 5))
        return 0;
    const char *c = name + 5;
    size_t nd = strspn(c, "0123456789");
    if (nd < 5)
        return 0;
    c += nd;
    return !strcmp(c, ".tif") || !strcmp(c, "_a.tif") || !strcmp(c, "_b.tif");
}

/* An existing output folder: refused when it holds anything, unless overwrite; then the
 * pair files of an earlier run are removed, so that none is left over from a run with more
 * pairs (truth.txt and synth.ini are replaced atomically, other files are left). */
static rpiv_status prepare_dir(const char *dir, int overwrite)
{
    DIR *d = opendir(dir);
    if (!d)
        return errno == ENOENT ? RPIV_OK
                               : rpiv_fail(RPIV_EIO, "%s: cannot read: %s", dir, strerror(errno));
    rpiv_status st = RPIV_OK;
    char path[RPIV_PATH_MAX + 300];
    for (struct dirent *de; !st && (de = readdir(d));) {
        if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
            continue;
        if (!overwrite)
            st = rpiv_fail(RPIV_EINVAL,
                           "synth: --out %s is not empty (--overwrite replaces an earlier run's "
                           "pairs)",
                           dir);
        else if (is_pair_file(de->d_name) &&
                 snprintf(path, sizeof path, "%s/%s", dir, de->d_name) < (int)sizeof path &&
                 unlink(path) != 0)
            st = rpiv_fail(RPIV_EIO, "%s: cannot remove: %s", path, strerror(errno));
    }
    closedir(d);
    return st;
}

/* The work after option parsing, on every rank of the team: each step that may fail on one
 * rank alone is agreed on, so that all ranks stop together. */
static rpiv_status run(const rpiv_experiment *e, int quiet, int overwrite, const rpiv_mpi *mpi)
{
    const char *dir = e->output.dir;
    int root = rpiv_mpi_rank(mpi) == 0;
    rpiv_synth *s = NULL;
    rpiv_field *grid = NULL;
    char path[RPIV_PATH_MAX + 64];
    rpiv_status st = rpiv_config_synth_new(e, NULL, &s);
    if (!st)
        st = piv_grid(s, e, &grid);
    if (!st && root)
        st = prepare_dir(dir, overwrite);
    if ((st = rpiv_mpi_agree(mpi, st)))
        goto out;
    st = cli_mkdirs(dir);
    if (!st && root) {
        snprintf(path, sizeof path, "%s/synth.ini", dir);
        if (!(st = rpiv_config_save_synth(e, s, path))) {
            snprintf(path, sizeof path, "%s/truth.txt", dir);
            st = write_truth(s, e, grid, path);
        }
    }
    if ((st = rpiv_mpi_agree(mpi, st)))
        goto out;
    if ((st = rpiv_mpi_agree(mpi, write_pairs(s, e, dir, quiet || !root, mpi))))
        goto out;
    if (!quiet && root) {
        rpiv_synth_info in;
        rpiv_synth_get_info(s, &in);
        printf("rpiv synth: %d pair%s of %dx%d px, %zu particles each, flow %s, seed %lu -> %s\n",
               e->synth.pairs, e->synth.pairs == 1 ? "" : "s", in.width_px, in.height_px,
               in.nparticles, e->synth.flow, e->synth.seed, dir);
    }
out:
    rpiv_field_free(grid);
    rpiv_synth_free(s);
    return st;
}
