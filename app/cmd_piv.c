/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv piv - image pairs -> displacement fields: multi-pass deforming FFT PIV, per pair or as
 * an ensemble (sum of correlation). The work is done by the library (rpiv/piv.h,
 * rpiv/ensemble.h); this file maps options onto [piv] keys and names the outputs. */
#include "cmd_piv.h"
#include "cli.h"

#include "rpiv/batch.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/mpi.h"
#include "rpiv/pairs.h"
#include "rpiv/piv.h"
#include "rpiv/plot.h"
#include "rpiv/report.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

rpiv_status cmd_piv(int argc, char **argv);

static void help_mpi(void)
{
    printf("\nMPI: 'mpirun -np K rpiv piv ...' deals the pairs out to K ranks (pair i to rank\n"
           "i mod K). Ensemble: the ranks' sums are added (in double) before every pass ends;\n"
           "checkpoints are FILE.rank0 ... FILE.rank<K-1> and resume needs the same K. Per\n"
           "pair: each rank writes the files of its pairs; a .nc series, --mean-rms and --plot\n"
           "are written by rank 0. See docs/cluster.md. MPI support in this build: %s.\n\n"
           "Algorithm, choices and measured accuracy: docs/piv.md.\n",
           rpiv_mpi_built() ? "yes" : "no");
}

/* Parse --validate: "none"/"off", "median", "median:T". */
static rpiv_status set_validate(cli_ctx *c, const char *v)
{
    const char *thr = NULL;
    if (!strcmp(v, "none") || !strcmp(v, "off"))
        thr = "0";
    else if (!strcmp(v, "median"))
        thr = "2";
    else if (!strncmp(v, "median:", 7))
        thr = v + 7;
    else
        return rpiv_fail(RPIV_EINVAL, "--validate: '%s' is not median, median:T or none", v);
    return rpiv_config_set(&c->exp, "piv", "median_threshold", thr, "--validate");
}

/* Options of a long run, besides the [piv] keys. */
typedef struct run_opts {
    const char *out, *plot, *checkpoint, *every, *derived;
    int meanrms, resume, skip_bad, sheet_bias;
    rpiv_pairing pairing;
    unsigned derived_mask; /* --derived parsed */
} run_opts;

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* The median peak ratio of f's unmasked vectors (0 if none). */
static double median_peak_ratio(const rpiv_field *f)
{
    size_t n = (size_t)f->nx * (size_t)f->ny, m = 0;
    float *pr = malloc(n * sizeof *pr);
    if (!pr)
        return 0;
    for (size_t k = 0; k < n; k++)
        if (f->flag[k] != RPIV_FLAG_MASKED)
            pr[m++] = f->peak_ratio[k];
    /* qsort, not an insertion sort: 8 px windows at 0.95 overlap give a million vectors on a
     * 1024 x 1024 pair, and the quadratic sort ran for hours after the field was done */
    qsort(pr, m, sizeof *pr, cmp_float);
    double med = m ? (double)pr[m / 2] : 0;
    free(pr);
    return med;
}

/* Honest warnings on stderr after a run that succeeded (rank 0): the traps the results
 * alone do not show. f: the ensemble field or the first pair's (may be NULL). */
static void warn_run(const rpiv_piv_params *p, const rpiv_pairs *pairs, const rpiv_batch *batch,
                     const run_ctx *r, const rpiv_field *f)
{
    const rpiv_pair_src *q0 = &pairs->pair[0];
    int pages = 1;
    if (!q0->path_b && !rpiv_image_count_pages(q0->path_a, &pages) && pages < 2)
        fprintf(stderr,
                "rpiv piv: warning: %s is one image, read as a double frame: its top half is "
                "frame A and its bottom half frame B; to correlate two frames, give both "
                "files (rpiv piv A B -o OUT)\n",
                q0->path_a);
    if (p->dt_s > 0 && !(p->scale_mm_per_px > 0))
        fprintf(stderr,
                "rpiv piv: warning: --dt without --scale: dt is recorded in the header, but "
                "the columns stay in px per pair interval (no m/s, 1/s); add --scale "
                "MM_PER_PX for physical units\n");
    rpiv_image_stats sa, sb;
    size_t i0;
    if (rpiv_batch_first_stats(batch, &i0, &sa, &sb) && (sa.min == sa.max || sb.min == sb.max))
        fprintf(stderr,
                "rpiv piv: warning: frame %s of the first pair (%s) is %s (grey %g "
                "everywhere): there are no particles to correlate\n",
                sa.min == sa.max ? "A" : "B",
                sa.min == sa.max || !pairs->pair[i0].path_b ? pairs->pair[i0].path_a
                                                            : pairs->pair[i0].path_b,
                (sa.min == sa.max ? sa.max : sb.max) == 0 ? "empty" : "constant",
                sa.min == sa.max ? sa.max : sb.max);
    double change = -1;
    const int reps = p->ensemble ? rpiv_batch_repeats(batch, &change) : 0;
    if (p->ensemble && p->ensemble_refine > 0 && reps >= p->ensemble_refine &&
        change > p->ensemble_refine_tol_px)
        fprintf(stderr,
                "rpiv piv: warning: the ensemble's final pass was repeated %d time%s and its "
                "field still changed by %.4f px RMS in the last (ensemble_refine_tol_px %g): "
                "not converged; raise piv.ensemble_refine (up to 20)%s\n",
                reps, reps == 1 ? "" : "s", change, p->ensemble_refine_tol_px,
                p->ensemble_denoise ? "" : ", or set piv.ensemble_denoise = 1 for a noisy series");
    else if (p->ensemble && !p->ensemble_refine && change > p->refine_tol_px)
        fprintf(stderr,
                "rpiv piv: warning: the ensemble's final pass still changed its field by %.4f px "
                "RMS (more than a pair's convergence, refine_tol_px %g): the listed passes did "
                "not converge it, and its error (which --uncertainty does not include) can be "
                "as large; for planar PIV of a thin sheet, -S piv.ensemble_refine=6 repeats the "
                "final pass (docs/piv.md, \"Ensembles: the final pass repeated\")\n",
                change, p->refine_tol_px);
    if (!r->nvec || (double)r->nreplaced <= 0.10 * (double)r->nvec)
        return;
    double med = f ? median_peak_ratio(f) : 0;
    fprintf(stderr,
            "rpiv piv: warning: %.1f %% of the vectors were replaced (median peak ratio "
            "%.2f): ",
            100.0 * (double)r->nreplaced / (double)r->nvec, med);
    if (med < 1.5)
        fprintf(stderr,
                "the correlation peaks are weak (peak ratio below 1.5): dark, sparse or "
                "uneven images; try --preprocess clahe%s, and larger final windows if the "
                "particles are sparse (--window 64,64,64; docs/preprocess.md)\n",
                p->cbc ? "" : " --cbc 2");
    else
        fprintf(stderr, "the peaks are clear, so the flow likely varies too much within a "
                        "window (strong gradients): try smaller windows (--window 64,32,16) or "
                        "check frame order and --dt\n");
}

/* piv.max_mem_mb against the run's estimated peak (rpiv_piv_mem_estimate; a per-pair run
 * keeps a copy of the first field), before anything large is allocated. */
static rpiv_status check_memory(const rpiv_piv_params *p, int w, int h, int mask, size_t npairs)
{
    const double MB = 1048576.0;
    rpiv_piv_mem m = rpiv_piv_mem_estimate(p, w, h, mask, npairs, !p->ensemble);
    if (m.total / MB <= p->max_mem_mb)
        return RPIV_OK;
    return rpiv_fail(RPIV_ELIMIT,
                     "piv: the run needs about %.0f MB (%dx%d frames %.0f MB, decoding %.0f MB, "
                     "%s %.0f MB, process %.0f MB), above piv.max_mem_mb = %g",
                     m.total / MB, w, h, m.frames / MB, m.load / MB,
                     p->ensemble ? "correlation sums" : "vector fields", m.work / MB, m.base / MB,
                     p->max_mem_mb);
}

/* The work after option parsing, on every rank of the team. */
static rpiv_status run(cli_ctx *c, const run_opts *o, int nargs, char **args, rpiv_mpi *mpi);

/* Everything the options set. */
typedef struct piv_opts {
    cli_ctx c;
    run_opts ro;
    const char *outdir;
} piv_opts;

static rpiv_status set_validate_opt(void *obj, const char *arg)
{
    return set_validate(&((piv_opts *)obj)->c, arg);
}

/* --limits UMIN,UMAX,VMIN,VMAX (px): the four [piv] keys. */
static rpiv_status set_limits(void *obj, const char *arg)
{
    rpiv_piv_params *p = &((piv_opts *)obj)->c.exp.piv;
    double l[4];
    char end;
    if (sscanf(arg, "%lf,%lf,%lf,%lf%c", &l[0], &l[1], &l[2], &l[3], &end) != 4 ||
        !isfinite(l[0]) || !isfinite(l[1]) || !isfinite(l[2]) || !isfinite(l[3]))
        return cli_usage_error("piv", "--limits: '%s' is not UMIN,UMAX,VMIN,VMAX (4 numbers, px)",
                               arg);
    if (!(l[0] < l[1]) && !(l[2] < l[3]))
        return cli_usage_error("piv", "--limits %s: neither UMIN < UMAX nor VMIN < VMAX", arg);
    p->u_min_px = l[0];
    p->u_max_px = l[1];
    p->v_min_px = l[2];
    p->v_max_px = l[3];
    return RPIV_OK;
}

static rpiv_status set_pairing(void *obj, const char *arg)
{
    run_opts *ro = &((piv_opts *)obj)->ro;
    if (!strcmp(arg, "ab"))
        ro->pairing = RPIV_PAIR_AB;
    else if (!strcmp(arg, "consecutive"))
        ro->pairing = RPIV_PAIR_CONSECUTIVE;
    else if (!strcmp(arg, "time-resolved"))
        ro->pairing = RPIV_PAIR_TIME_RESOLVED;
    else
        return cli_usage_error("piv", "--pairing: '%s' is not ab, consecutive or time-resolved",
                               arg);
    return RPIV_OK;
}

#define PIV_KEY(nm, a, k, text)                                                                    \
    {                                                                                              \
        .name = nm, .kind = CLI_KEY, .arg = a, .section = "piv", .key = k, .help = text            \
    }

static const cli_opt options[] = {
    {.kind = CLI_HEAD, .help = "options (each also a key of the [piv] section of --config):"},
    PIV_KEY("window", "W[,W...]", "windows", "window size per pass, W or WxH (64,32,32) [windows]"),
    {.name = "windows", .kind = CLI_KEY, .arg = "W[,W...]", .section = "piv", .key = "windows"},
    PIV_KEY("overlap", "F", "overlap", "window overlap fraction 0..0.95 (0.5) [overlap]"),
    PIV_KEY("step", "N", "step_px", "grid step in px, instead of --overlap [step_px]"),
    {.name = "ensemble",
     .kind = CLI_FLAG,
     .off = offsetof(piv_opts, c.exp.piv.ensemble),
     .help = "sum of correlation over all pairs [ensemble]"},
    PIV_KEY("subpixel", "M", "subpixel",
            "gauss, parabola, centroid, spline or auto (auto: spline for --ensemble, else gauss) "
            "[subpixel]"),
    {.name = "validate",
     .kind = CLI_FN,
     .arg = "V",
     .fn = set_validate_opt,
     .help = "median:T (threshold T, default 2) or none [median_threshold]"},
    PIV_KEY("search-radius", "R", "search_radius_px",
            "passes with a predictor: take the highest correlation peak within R px\n"
            "of the predicted shift; 0 = whole plane, -1 = an eighth of the previous\n"
            "pass's window, at least 2 px (-1; docs/piv.md) [search_radius_px]"),
    PIV_KEY("cbc", "M", "cbc",
            "correlation-based correction: choose each window's peak on its\n"
            "correlation multiplied (1) or summed (2) with its 4 neighbours';\n"
            "0 off (0; docs/piv.md) [cbc]"),
    PIV_KEY("peak-ratio", "R", "peak_ratio_min",
            "also reject vectors whose correlation peak ratio is below R\n"
            "(off; 1.2 to 1.5 usual) [peak_ratio_min]"),
    {.name = "limits",
     .kind = CLI_FN,
     .arg = "UMIN,UMAX,VMIN,VMAX",
     .fn = set_limits,
     .help = "also reject u or v outside these limits, px per pair, image\n"
             "coordinates (v down); MIN >= MAX: that component not tested\n"
             "[u_min_px, u_max_px, v_min_px, v_max_px]"},
    PIV_KEY("std", "K", "std_k",
            "also reject vectors farther than K standard deviations from the\n"
            "mean of the field (off; 3 to 5 usual) [std_k]"),
    PIV_KEY("replace", "M", "replace",
            "rejected vectors replaced by the 3x3 median or by inpaint\n"
            "(Laplace: fills gaps of several vectors smoothly) (median) [replace]"),
    PIV_KEY("smooth", "S", "smooth",
            "smooth the final field by penalised least squares, S in grid\n"
            "steps^4 (off; 0.5 to 5 usual; docs/postprocess.md) [smooth]"),
    PIV_KEY("mask", "FILE", "mask", "mask image, 0 = masked pixel [mask]"),
    PIV_KEY("roi", "X0,Y0,X1,Y1", "roi", "region of interest, px (X1, Y1 excluded) [roi]"),
    PIV_KEY("background", "B", "background",
            "subtract the series' min or mean image, or none [background]"),
    PIV_KEY("scale", "MM_PER_PX", "scale_mm_per_px",
            "physical scale, adds mm and m/s columns [scale_mm_per_px]"),
    PIV_KEY("dt", "S", "dt_s", "pulse separation, s [dt_s]"),
    {.name = "preprocess",
     .kind = CLI_KEY,
     .arg = "LIST",
     .section = "preprocess",
     .key = "ops",
     .help = "image preprocessing, in order: clahe[:TILE], highpass[:SIZE], cap,\n"
             "normalize[:SIZE], invert (docs/preprocess.md) [preprocess.ops]"},
    {.name = "y-up",
     .kind = CLI_FLAG,
     .off = offsetof(piv_opts, c.exp.piv.y_up),
     .help = "output files with the origin at the bottom-left pixel, y and v\n"
             "upward (default: image coordinates, y and v down) [y_up]"},
    {.name = "uncertainty",
     .kind = CLI_FLAG,
     .off = offsetof(piv_opts, c.exp.piv.uncertainty),
     .help = "add sigma_u, sigma_v: the random uncertainty of each vector, 1 sigma\n"
             "(correlation statistics; experimental, docs/uncertainty.md) [uncertainty]"},
    {.kind = CLI_HEAD, .help = "other options:"},
    {.name = "derived",
     .kind = CLI_STR,
     .arg = "LIST",
     .off = offsetof(piv_opts, ro.derived),
     .help = "add derived quantities to the output: vorticity, divergence,\n"
             "strain, swirl, q, or all (physical sign; docs/postprocess.md)"},
    {.name = "sheet-bias",
     .kind = CLI_FLAG,
     .off = offsetof(piv_opts, ro.sheet_bias),
     .help = "add the refracted sheet's bias by the CCM to the ensemble or mean\n"
             "field: bias_u, bias_v, u_corrected, v_corrected, bias_u_std,\n"
             "bias_v_std, z_ref ([sheet] and [bias] keys; docs/bias.md)"},
    {.name = "output",
     .letter = 'o',
     .kind = CLI_STR,
     .arg = "OUT",
     .off = offsetof(piv_opts, ro.out),
     .help = "output file (required, or --out)"},
    {.name = "out",
     .kind = CLI_STR,
     .arg = "DIR",
     .off = offsetof(piv_opts, outdir),
     .help = "output folder: DIR/piv.txt, or DIR/ensemble.txt with --ensemble"},
    {.name = "mean-rms",
     .kind = CLI_FLAG,
     .off = offsetof(piv_opts, ro.meanrms),
     .help = "per-pair mode: also write OUT_mean and OUT_rms (mean and\n"
             "standard deviation of the valid vectors)"},
    {.name = "plot",
     .kind = CLI_STR,
     .arg = "FILE.png",
     .off = offsetof(piv_opts, ro.plot),
     .help = "figure (PNG, as 'rpiv plot' draws it) of the ensemble field, the\n"
             "mean field (--mean-rms) or the first pair's field"},
    {.name = "pairing",
     .kind = CLI_FN,
     .arg = "P",
     .fn = set_pairing,
     .help = "glob pairing: ab, consecutive or time-resolved (ab)"},
    {.name = "skip-bad",
     .kind = CLI_FLAG,
     .off = offsetof(piv_opts, ro.skip_bad),
     .help = "skip a pair that cannot be read (warning on stderr,\n"
             "listed in the output header) instead of stopping"},
    {.kind = CLI_HEAD, .help = "long ensemble runs:"},
    {.name = "checkpoint",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = offsetof(piv_opts, ro.checkpoint),
     .help = "save the summed correlation planes, the pass and the pairs\n"
             "done to FILE (atomically) at every pass start, every\n"
             "--checkpoint-every pairs and when stopped (SIGINT/SIGTERM,\n"
             "an unreadable pair); removed when the run completes"},
    {.name = "checkpoint-every",
     .kind = CLI_STR,
     .arg = "N",
     .off = offsetof(piv_opts, ro.every),
     .help = "pairs between checkpoints (100)"},
    {.name = "resume",
     .kind = CLI_FLAG,
     .off = offsetof(piv_opts, ro.resume),
     .help = "continue from --checkpoint FILE (same pairs and options;\n"
             "the result is bit-identical to an uninterrupted run); no\n"
             "FILE: start from the beginning"},
};

const cli_spec cmd_piv_spec = {
    .name = "piv",
    .usage =
        "usage: rpiv piv [--config FILE] [options] PAIRS... -o OUT\n\n"
        "Measure displacement fields from image pairs: multi-pass FFT cross-correlation with\n"
        "symmetric image deformation (cubic B-splines), normalised median validation, and a\n"
        "3-point Gaussian peak fit. With --ensemble, the correlation planes of all pairs are\n"
        "summed before the peak is located (sum of correlation), pass by pass.\n\n"
        "PAIRS: two image files (one pair), one double-frame file, a .txt/.lst list of pairs,\n"
        "or a quoted glob matched and paired by --pairing.\n\n"
        "OUT: the format follows the extension: .txt (columns x y u v flag peak_ratio\n"
        "correlation, + x_mm y_mm u_ms v_ms with --scale and --dt), .nc (NetCDF-4; a series of\n"
        "pairs goes into one file along t), .dat (Tecplot), .vtk (legacy VTK). Several pairs\n"
        "and a non-.nc OUT give one file per pair, OUT with _0001, _0002, ... before the\n"
        "extension. x, y are pixel coordinates of frame A (pixel centres at integers), u along\n"
        "+x, v along +y (down; up with --y-up), in px; flag 0 valid, 1 replaced, 2 masked.\n"
        "Every format holds the same quantities with their units in its header\n"
        "(docs/formats.md).\n\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .more = help_mpi,
    .common = 1};

rpiv_status cmd_piv(int argc, char **argv)
{
    piv_opts po = {.ro = {.pairing = RPIV_PAIR_AB}};
    char outbuf[RPIV_PATH_MAX + 32];
    int done;
    rpiv_status st;
    cli_ctx_init(&po.c);
    if ((st = cli_parse(&cmd_piv_spec, &po.c, &po, argc, argv, &done)) || done)
        return st;
    cli_ctx c = po.c;
    run_opts ro = po.ro;
    const char *outdir = po.outdir;
    rpiv_piv_params *p = &c.exp.piv;
    if (!ro.out && outdir) { /* --out DIR: DIR/piv.txt or DIR/ensemble.txt */
        if (snprintf(outbuf, sizeof outbuf, "%s/%s", outdir,
                     p->ensemble ? "ensemble.txt" : "piv.txt") >= (int)sizeof outbuf)
            return cli_usage_error("piv", "--out %s: path too long", outdir);
        if ((st = cli_mkdirs(outdir)))
            return st;
        ro.out = outbuf;
    }
    if (!ro.out)
        return cli_usage_error("piv", "no output given (-o OUT or --out DIR)");
    if (rpiv_field_format_of(ro.out, NULL) == RPIV_FIELD_UNKNOWN)
        return cli_usage_error("piv", "-o %s: the extension must be .txt, .nc, .dat or .vtk",
                               ro.out);
    if (optind >= argc)
        return cli_usage_error("piv", "no image pairs given");
    if (ro.meanrms && p->ensemble)
        return cli_usage_error("piv", "--mean-rms averages per-pair fields; it does not go "
                                      "with --ensemble");
    if ((ro.checkpoint || ro.every || ro.resume) && !p->ensemble)
        return cli_usage_error("piv", "--checkpoint, --checkpoint-every and --resume are for "
                                      "--ensemble runs (per-pair runs write each pair's file as it "
                                      "is done)");
    if ((ro.every || ro.resume) && !ro.checkpoint)
        return cli_usage_error("piv", "%s needs --checkpoint FILE",
                               ro.resume ? "--resume" : "--checkpoint-every");
    if (ro.every) {
        long every;
        if ((st = cli_parse_int("--checkpoint-every", ro.every, 1, 1000000000L, &every)))
            return st;
    }
    if (ro.checkpoint && !ro.checkpoint[0])
        return cli_usage_error("piv", "--checkpoint: empty file name");
    if (ro.every) {
        long v;
        if ((st = cli_parse_int("--checkpoint-every", ro.every, 1, 1000000000L, &v)))
            return st;
    }
    if (ro.sheet_bias && !p->ensemble && !ro.meanrms)
        return cli_usage_error("piv", "--sheet-bias applies to a converged field: give it "
                                      "with --ensemble or --mean-rms");
    if ((st = rpiv_piv_params_check(p)))
        return st;
    if (ro.sheet_bias && (st = rpiv_experiment_check(&c.exp)))
        return st;
    if (ro.derived && rpiv_field_derive_parse(ro.derived, &ro.derived_mask))
        return cli_usage_error("piv", "--%s", rpiv_errmsg());

    rpiv_mpi *mpi = NULL;
    if ((st = rpiv_mpi_new(NULL, NULL, &mpi)))
        return st;
    st = run(&c, &ro, argc - optind, argv + optind, mpi);
    rpiv_mpi_free(mpi);
    return st;
}

/* --sheet-bias: the CCM's bias of every vector of f, added as quantities (docs/bias.md);
 * npairs: the pairs of f's planes (an ensemble's; 1 for a mean of instantaneous fields), the
 * noise of [bias] window_interp's plane unless [bias] window_pairs gives it. */
static rpiv_status sheet_bias(const cli_ctx *c, rpiv_field *f, size_t npairs)
{
    cli_progress prog;
    rpiv_progress pr = cli_progress_of(&prog);
    cli_progress_init(&prog, "sheet bias", c->quiet);
    return rpiv_config_sheet_bias(&c->exp, f, npairs, c->threads, &pr);
}

static rpiv_status run(cli_ctx *c, const run_opts *o, int nargs, char **args, rpiv_mpi *mpi)
{
    rpiv_piv_params *p = &c->exp.piv;
    const char *out = o->out;
    if (o->plot) { /* before any work: a figure is a .png */
        rpiv_status pst = rpiv_plot_path_check(o->plot);
        if (pst)
            return pst;
    }
    int root = rpiv_mpi_rank(mpi) == 0, w = 0, h = 0;
    rpiv_pairs *pairs = NULL;
    rpiv_batch *batch = NULL;
    rpiv_image *mask = NULL, *bga = NULL, *bgb = NULL;
    rpiv_piv *pv = NULL;
    rpiv_field *field = NULL, *mean = NULL, *rms = NULL, *grid = NULL;
    rpiv_meta meta = {0};
    run_ctx r = {0};
    cli_progress prog;
    rpiv_progress pr = cli_progress_of(&prog);
    rpiv_batch_params bp = rpiv_batch_params_default();
    bp.checkpoint = o->checkpoint;
    bp.resume = o->resume;
    bp.skip_bad = o->skip_bad;
    bp.on_skip = cmdpiv_warn_skip;
    if (o->every) { /* checked with the options: cannot fail here */
        long every = 0;
        if (cli_parse_int("--checkpoint-every", o->every, 1, 1000000000L, &every) == RPIV_OK)
            bp.checkpoint_every = (size_t)every;
    }
    /* each step that may fail on one rank alone is agreed on before the next collective */
    rpiv_status st = rpiv_pairs_from_args(nargs, args, o->pairing, &pairs);
    if (!st)
        st = rpiv_batch_new(pairs, &bp, mpi, &batch);
    if ((st = rpiv_mpi_agree(mpi, st)) || (st = rpiv_batch_size(batch, &w, &h)))
        goto out_free;
    if (p->mask[0])
        st = rpiv_image_load(p->mask, 0, &mask, NULL);
    if ((st = rpiv_mpi_agree(mpi, st)))
        goto out_free;
    if ((st = check_memory(p, w, h, mask != NULL, pairs->n)))
        goto out_free;
    if (p->background != RPIV_BACKGROUND_NONE) {
        cli_progress_init(&prog, "background", c->quiet || !root);
        if ((st = rpiv_batch_background(batch, p->background, w, h, &pr, &bga, &bgb)))
            goto out_free;
    }
    if ((st = rpiv_piv_new(p, w, h, mask, &pv))) {
        if (st == RPIV_ESIZE) { /* the parameters do not fit the images: a usage error */
            char msg[768];
            snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
            st = rpiv_fail(RPIV_EINVAL, "%s", msg);
        }
    }
    if (!st && bga)
        st = rpiv_piv_set_background(pv, bga, bgb);
    rpiv_image_free(bga);
    rpiv_image_free(bgb);
    bga = bgb = NULL;
    if (!st)
        st = cmdpiv_add_meta(&meta, p, pairs, pv);
    if (!st && rpiv_mpi_size(mpi) > 1)
        st = rpiv_meta_add(&meta, "mpi_ranks", "%d", rpiv_mpi_size(mpi));
    if (!st && o->sheet_bias) {
        const rpiv_ccm_bias_params *sb = &c->exp.bias;
        st = rpiv_meta_add(
            &meta, "sheet_bias", "depth %s, variation %s%s%s, rel_thickness %g, dz %g",
            rpiv_ccm_depth_names[sb->depth], rpiv_ccm_vary_names[sb->vary],
            sb->vary == RPIV_CCM_VARY_PROFILE ? " " : "",
            sb->vary == RPIV_CCM_VARY_PROFILE ? sb->profile : "", sb->rel_thickness, sb->dz);
    }
    r.out = out;
    r.y_up = p->y_up;
    r.height = h;
    r.derived = o->derived_mask;
    r.npairs = pairs ? pairs->n : 0;
    r.meta = &meta;
    r.digits = 4;
    for (size_t n = r.npairs; n >= 10000; n /= 10)
        r.digits++;
    r.nc_series = r.npairs > 1 && rpiv_field_format_of(out, NULL) == RPIV_FIELD_NC;
    if (!st && !p->ensemble && root) {
        if ((st = rpiv_piv_grid(pv, rpiv_piv_npass(pv) - 1, &grid)))
            goto out_agree;
        if (r.nc_series) {
            rpiv_field *tmp;
            const rpiv_field *g;
            if (!(st = cmdpiv_oriented(&r, grid, &tmp, &g)))
                st = rpiv_field_series_open(out, g, &meta, &r.series);
            rpiv_field_free(tmp);
            if (st)
                goto out_agree;
        }
        if (o->meanrms && (st = rpiv_series_stats_new(grid, &r.stats)))
            goto out_agree;
    }
out_agree:
    if ((st = rpiv_mpi_agree(mpi, st)))
        goto out_free;

    cli_progress_init(&prog, p->ensemble ? "ensemble" : "piv", c->quiet || !root);
    rpiv_piv_set_cancel(pv, &pr); /* SIGINT/SIGTERM inside a long pair, too */
    if (p->ensemble) {
        if ((st = rpiv_batch_ensemble(batch, pv, &pr, &field)))
            goto out_free;
        if (root && o->sheet_bias && (st = sheet_bias(c, field, r.npairs)))
            goto out_free;
        if (root && ((st = cmdpiv_add_skipped(&meta, batch, pairs)) ||
                     (st = cmdpiv_save(&r, field, &meta, out))))
            goto out_free;
        r.nvec = (size_t)field->nx * (size_t)field->ny;
        r.nreplaced = rpiv_field_count(field, RPIV_FLAG_REPLACED);
    } else {
        st = rpiv_batch_series(batch, pv, cmdpiv_local_sink, cmdpiv_root_sink, &r, &pr);
        if (r.series) {
            rpiv_field_series *s = r.series;
            r.series = NULL;
            if (st == RPIV_EINTR) {
                st = cmdpiv_series_partial(s, out);
            } else {
                rpiv_status cs = rpiv_field_series_close(s, st != RPIV_OK);
                st = st ? st : cs;
            }
        }
        if (st)
            goto out_free;
        if (o->meanrms && root) {
            char path[RPIV_PATH_MAX + 32];
            if ((st = cmdpiv_add_skipped(&meta, batch, pairs)) ||
                (st = rpiv_series_stats_finish(r.stats, &mean, &rms)) ||
                (o->sheet_bias && (st = sheet_bias(c, mean, 1))) ||
                (st = cmdpiv_out_name(out, "_mean", path, sizeof path)) ||
                (st = cmdpiv_save(&r, mean, &meta, path)) ||
                (st = cmdpiv_out_name(out, "_rms", path, sizeof path)) ||
                (st = cmdpiv_save_as(&r, rms, &meta, path, 1)))
                goto out_free;
        }
    }
    if (!root)
        goto out_free;
    if (o->plot) { /* the figure of the file it shows, as written (y-up with --y-up) */
        const rpiv_field *pf = field ? field : (mean ? mean : r.first);
        char shown[RPIV_PATH_MAX + 32], title[RPIV_PATH_MAX + 64], tag[32];
        snprintf(shown, sizeof shown, "%s", out);
        if (!field && mean)
            st = cmdpiv_out_name(out, "_mean", shown, sizeof shown);
        else if (!field && pairs->n > 1 && !r.nc_series) {
            snprintf(tag, sizeof tag, "_%0*zu", r.digits, r.first_index + 1);
            st = cmdpiv_out_name(out, tag, shown, sizeof shown);
        }
        const char *slash = strrchr(shown, '/');
        snprintf(title, sizeof title, "%s", slash ? slash + 1 : shown);
        if (!field && !mean && r.nc_series)
            snprintf(title + strlen(title), sizeof title - strlen(title), ", t = %zu",
                     r.first_index);
        rpiv_field *tmp = NULL;
        const rpiv_field *g = pf;
        rpiv_plot_field_params pp = rpiv_plot_field_params_default();
        if (!st)
            st = cmdpiv_oriented(&r, pf, &tmp, &g);
        if (!st)
            st = rpiv_plot_field(g, o->plot, title, &pp, NULL);
        rpiv_field_free(tmp);
        if (st)
            goto out_free;
    }
    if (!c->quiet) {
        int pass;
        size_t done, nskip = rpiv_batch_nskipped(batch);
        if (o->resume && rpiv_batch_resumed(batch, &pass, &done))
            fprintf(stderr, "rpiv piv: resumed from %s: pass %d, %zu pair%s already summed\n",
                    o->checkpoint, pass + 1, done, done == 1 ? "" : "s");
        else if (o->resume)
            fprintf(stderr, "rpiv piv: no checkpoint %s: started from the beginning\n",
                    o->checkpoint);
        char skipped[48] = "";
        if (nskip)
            snprintf(skipped, sizeof skipped, " (%zu skipped)", nskip);
        printf("rpiv piv: %zu pair%s%s, %s, %zu vectors, %.2f %% replaced -> %s%s\n", pairs->n,
               pairs->n == 1 ? "" : "s", skipped, p->ensemble ? "ensemble" : "instantaneous",
               r.nvec, r.nvec ? 100.0 * (double)r.nreplaced / (double)r.nvec : 0.0, out,
               !p->ensemble && pairs->n > 1 && rpiv_field_format_of(out, NULL) != RPIV_FIELD_NC
                   ? " (one file per pair)"
                   : "");
        if (nskip)
            fprintf(stderr,
                    "rpiv piv: %zu unreadable pair%s skipped (listed in the output "
                    "header)\n",
                    nskip, nskip == 1 ? "" : "s");
    }
    warn_run(p, pairs, batch, &r, field ? field : r.first);
out_free:
    if (r.series && rpiv_field_series_close(r.series, 1))
        st = st ? st : RPIV_EIO; /* not reached: abort only removes a temporary file */
    rpiv_series_stats_free(r.stats);
    rpiv_field_free(r.first);
    rpiv_field_free(grid);
    rpiv_field_free(field);
    rpiv_field_free(mean);
    rpiv_field_free(rms);
    rpiv_meta_clear(&meta);
    rpiv_piv_free(pv);
    rpiv_image_free(mask);
    rpiv_image_free(bga);
    rpiv_image_free(bgb);
    rpiv_batch_free(batch);
    rpiv_pairs_free(pairs);
    return st;
}
