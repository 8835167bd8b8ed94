/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv piv - image pairs -> displacement fields: multi-pass deforming FFT PIV, per pair or as
 * an ensemble (sum of correlation). The work is done by the library (rpiv/piv.h,
 * rpiv/ensemble.h); this file maps options onto [piv] keys and names the outputs. */
#include "cli.h"

#include "rpiv/ensemble.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/piv.h"
#include "rpiv/plot.h"
#include "rpiv/version.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>

rpiv_status cmd_piv(int argc, char **argv);

static void help(void)
{
    printf(
        "usage: rpiv piv [--config FILE] [options] PAIRS... -o OUT\n\n"
        "Measure displacement fields from image pairs: multi-pass FFT cross-correlation with\n"
        "symmetric image deformation (cubic B-splines), normalised median validation, and a\n"
        "3-point Gaussian peak fit. With --ensemble, the correlation planes of all pairs are\n"
        "summed before the peak is located (sum of correlation), pass by pass.\n\n"
        "PAIRS: two image files (one pair), one double-frame file, a .txt/.lst list of pairs,\n"
        "or a quoted glob matched and paired by --pairing.\n\n"
        "OUT: -o FILE, or --out DIR for DIR/piv.txt (DIR/ensemble.txt with --ensemble).\n"
        "The format follows the extension: .txt (columns x y u v flag peak_ratio\n"
        "correlation, + x_mm y_mm u_ms v_ms with --scale and --dt), .nc (NetCDF-4; a series of\n"
        "pairs goes into one file along t), .dat (Tecplot), .vtk (legacy VTK). Several pairs\n"
        "and a non-.nc OUT give one file per pair, OUT with _0001, _0002, ... before the\n"
        "extension. x, y are pixel coordinates of frame A (pixel centres at integers), u along\n"
        "+x, v along +y (down), in px; flag 0 valid, 1 replaced, 2 masked.\n\n"
        "options (each also a key of the [piv] section of --config):\n"
        "  --window W[,W...]     window size per pass, W or WxH (64,32,32)      [windows]\n"
        "  --overlap F           window overlap fraction 0..0.95 (0.5)          [overlap]\n"
        "  --step N              grid step in px, instead of --overlap          [step_px]\n"
        "  --ensemble            sum of correlation over all pairs              [ensemble]\n"
        "  --subpixel M          gauss, parabola or centroid (gauss)            [subpixel]\n"
        "  --validate V          median:T (threshold T, default 2) or none      [median_threshold]\n"
        "  --mask FILE           mask image, 0 = masked pixel                   [mask]\n"
        "  --roi X0,Y0,X1,Y1     region of interest, px (X1, Y1 excluded)       [roi]\n"
        "  --background B        subtract the series' min or mean image, or none [background]\n"
        "  --scale MM_PER_PX     physical scale, adds mm and m/s columns        [scale_mm_per_px]\n"
        "  --dt S                pulse separation, s                            [dt_s]\n"
        "  --threads N           OpenMP threads (0 = all cores)                 [threads]\n"
        "other options:\n"
        "  -o, --output OUT      output file (or --out DIR, below)\n"
        "  --out DIR             output folder, made if needed: fields as text files there\n"
        "  --mean-rms            per-pair mode: also write OUT_mean and OUT_rms (mean and\n"
        "                        standard deviation of the valid vectors)\n"
        "  --plot FILE.png       quiver plot of the ensemble field, the mean field\n"
        "                        (--mean-rms) or the first pair's field\n"
        "  --pairing P           glob pairing: ab, consecutive or time-resolved (ab)\n"
        "  --set SEC.KEY=VALUE   override a configuration key; --quiet: no progress\n\n"
        "Algorithm, choices and measured accuracy: docs/piv.md.\n");
}

/* ".txt" etc. if path ends in a known field extension, else NULL. */
static const char *field_ext(const char *path)
{
    static const char *const ok[] = {".txt", ".nc", ".dat", ".vtk"};
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash))
        return NULL;
    for (size_t i = 0; i < sizeof ok / sizeof *ok; i++)
        if (!strcasecmp(dot, ok[i]))
            return dot;
    return NULL;
}

/* OUT with `tag` inserted before the extension (tag "_0001", "_mean"). */
static rpiv_status out_name(const char *out, const char *tag, char *buf, size_t n)
{
    const char *dot = field_ext(out);
    int len = (int)(dot - out);
    if (snprintf(buf, n, "%.*s%s%s", len, out, tag, dot) >= (int)n)
        return rpiv_fail(RPIV_EINVAL, "%s: output path too long", out);
    return RPIV_OK;
}

/* Progress through cli_progress, but only once a run has lasted a second: short runs stay
 * silent on stderr (one line there is then the error, if any). Interruption is checked at
 * every call. */
static int quiet_start(void *user, size_t done, size_t total)
{
    cli_progress *p = user;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    double now = (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
    if (now - p->t0 < 1.0)
        return cli_interrupted();
    return cli_progress_fn(user, done, total);
}

typedef struct run_ctx {
    const char *out;
    size_t npairs;
    int digits;
    const rpiv_meta *meta;
    rpiv_field_series *series; /* .nc with several pairs */
    rpiv_piv_stats *stats;     /* --mean-rms             */
    rpiv_field *first;         /* kept for --plot        */
    size_t nvec, nreplaced;
} run_ctx;

static rpiv_status sink(void *user, size_t i, const rpiv_field *f)
{
    run_ctx *r = user;
    rpiv_status st = RPIV_OK;
    size_t n = (size_t)f->nx * (size_t)f->ny;
    r->nvec += n;
    for (size_t k = 0; k < n; k++)
        r->nreplaced += f->flag[k] == RPIV_FLAG_REPLACED;
    if (r->series)
        st = rpiv_field_series_append(r->series, f, (double)i);
    else if (r->npairs == 1)
        st = rpiv_field_save(f, r->meta, r->out);
    else {
        char tag[32], path[RPIV_PATH_MAX + 32];
        snprintf(tag, sizeof tag, "_%0*zu", r->digits, i + 1);
        if (!(st = out_name(r->out, tag, path, sizeof path)))
            st = rpiv_field_save(f, r->meta, path);
    }
    if (!st && r->stats)
        st = rpiv_piv_stats_add(r->stats, f);
    if (!st && i == 0)
        st = rpiv_field_copy(f, &r->first);
    return st;
}

static rpiv_status add_meta(rpiv_meta *m, const rpiv_piv_params *p, const rpiv_pairs *pairs,
                            const rpiv_piv *pv)
{
    static const char *const sub[] = {"gauss", "parabola", "centroid"};
    static const char *const bg[] = {"none", "min", "mean"};
    char win[256] = "";
    for (int k = 0; k < p->npass; k++)
        snprintf(win + strlen(win), sizeof win - strlen(win), "%s%dx%d", k ? "," : "",
                 p->win_w[k], p->win_h[k]);
    rpiv_status st;
    if ((st = rpiv_meta_add(m, "software", "rpiv %s", RPIV_VERSION_STRING)) ||
        (st = rpiv_meta_add(m, "mode", "%s", p->ensemble ? "ensemble" : "instantaneous")) ||
        (st = rpiv_meta_add(m, "pairs", "%zu", pairs->n)) ||
        (st = rpiv_meta_add(m, "first_pair", "%s %s", pairs->pair[0].path_a,
                            pairs->pair[0].path_b ? pairs->pair[0].path_b : "(double frame)")) ||
        (st = rpiv_meta_add(m, "windows", "%s", win)) ||
        (st = rpiv_meta_add(m, "overlap", "%g", p->overlap)) ||
        (st = rpiv_meta_add(m, "step_px", "%d", p->step_px)) ||
        (st = rpiv_meta_add(m, "subpixel", "%s", sub[p->subpixel])) ||
        (st = rpiv_meta_add(m, "deform", "%s", p->deform ? "cubic B-spline, symmetric" : "off")) ||
        (st = rpiv_meta_add(m, "median_threshold", "%g", p->median_thr)) ||
        (st = rpiv_meta_add(m, "median_eps_px", "%g", p->median_eps)) ||
        (st = rpiv_meta_add(m, "background", "%s", bg[p->background])) ||
        (st = rpiv_meta_add(m, "mask", "%s", p->mask[0] ? p->mask : "none")) ||
        (st = rpiv_meta_add(m, "roi", "%d,%d,%d,%d", p->roi[0], p->roi[1], p->roi[2], p->roi[3])) ||
        (st = rpiv_meta_add(m, "threads", "%d", rpiv_piv_threads(pv))))
        return st;
    return RPIV_OK;
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

rpiv_status cmd_piv(int argc, char **argv)
{
    enum { O_WINDOW = 256, O_OVERLAP, O_STEP, O_ENSEMBLE, O_SUBPIXEL, O_VALIDATE, O_MASK, O_ROI,
           O_BACKGROUND, O_SCALE, O_DT, O_PLOT, O_MEANRMS, O_PAIRING, O_OUTDIR };
    static const struct option opts[] = {
        CLI_COMMON_LONGOPTS,
        {"window", required_argument, 0, O_WINDOW},
        {"windows", required_argument, 0, O_WINDOW},
        {"overlap", required_argument, 0, O_OVERLAP},
        {"step", required_argument, 0, O_STEP},
        {"ensemble", no_argument, 0, O_ENSEMBLE},
        {"subpixel", required_argument, 0, O_SUBPIXEL},
        {"validate", required_argument, 0, O_VALIDATE},
        {"mask", required_argument, 0, O_MASK},
        {"roi", required_argument, 0, O_ROI},
        {"background", required_argument, 0, O_BACKGROUND},
        {"scale", required_argument, 0, O_SCALE},
        {"dt", required_argument, 0, O_DT},
        {"plot", required_argument, 0, O_PLOT},
        {"mean-rms", no_argument, 0, O_MEANRMS},
        {"pairing", required_argument, 0, O_PAIRING},
        {"output", required_argument, 0, 'o'},
        {"out", required_argument, 0, O_OUTDIR},
        {0, 0, 0, 0}};
    /* option -> [piv] key, for the options that are keys */
    static const struct { int opt; const char *key, *name; } keyed[] = {
        {O_WINDOW, "windows", "--window"},       {O_OVERLAP, "overlap", "--overlap"},
        {O_STEP, "step_px", "--step"},           {O_SUBPIXEL, "subpixel", "--subpixel"},
        {O_MASK, "mask", "--mask"},              {O_ROI, "roi", "--roi"},
        {O_BACKGROUND, "background", "--background"},
        {O_SCALE, "scale_mm_per_px", "--scale"}, {O_DT, "dt_s", "--dt"}};
    cli_ctx c;
    const char *out = NULL, *plot = NULL, *outdir = NULL;
    char outbuf[RPIV_PATH_MAX + 32];
    int meanrms = 0, o;
    rpiv_pairing pairing = RPIV_PAIR_AB;
    rpiv_status st = RPIV_OK;
    cli_ctx_init(&c);
    while ((o = getopt_long(argc, argv, CLI_COMMON_SHORTOPTS "o:", opts, NULL)) != -1) {
        if (cli_common_opt(&c, o, optarg, &st)) {
            if (st)
                return st;
            continue;
        }
        int done = 0;
        for (size_t k = 0; k < sizeof keyed / sizeof *keyed; k++)
            if (keyed[k].opt == o) {
                if ((st = rpiv_config_set(&c.exp, "piv", keyed[k].key, optarg, keyed[k].name)))
                    return st;
                done = 1;
            }
        if (done)
            continue;
        switch (o) {
        case 'h':
            help();
            return RPIV_OK;
        case 'o':
            out = optarg;
            break;
        case O_OUTDIR:
            outdir = optarg;
            break;
        case O_ENSEMBLE:
            c.exp.piv.ensemble = 1;
            break;
        case O_VALIDATE:
            if ((st = set_validate(&c, optarg)))
                return st;
            break;
        case O_PLOT:
            plot = optarg;
            break;
        case O_MEANRMS:
            meanrms = 1;
            break;
        case O_PAIRING:
            if (!strcmp(optarg, "ab"))
                pairing = RPIV_PAIR_AB;
            else if (!strcmp(optarg, "consecutive"))
                pairing = RPIV_PAIR_CONSECUTIVE;
            else if (!strcmp(optarg, "time-resolved"))
                pairing = RPIV_PAIR_TIME_RESOLVED;
            else
                return cli_usage_error("piv", "--pairing: '%s' is not ab, consecutive or "
                                       "time-resolved", optarg);
            break;
        default:
            return cli_usage_error("piv", "unknown option '%s'", argv[optind - 1]);
        }
    }
    rpiv_piv_params *p = &c.exp.piv;
    if (!out && outdir) {
        if (snprintf(outbuf, sizeof outbuf, "%s/%s", outdir,
                     p->ensemble ? "ensemble.txt" : "piv.txt") >= (int)sizeof outbuf)
            return cli_usage_error("piv", "--out %s: path too long", outdir);
        out = outbuf;
    }
    if (!out)
        return cli_usage_error("piv", "no output given (-o OUT or --out DIR)");
    if (optind >= argc)
        return cli_usage_error("piv", "no image pairs given");
    if (meanrms && p->ensemble)
        return cli_usage_error("piv", "--mean-rms averages per-pair fields; it does not go "
                               "with --ensemble");
    if ((st = rpiv_piv_params_check(p)))
        return st;

    rpiv_pairs *pairs = NULL;
    rpiv_image *a = NULL, *b = NULL, *mask = NULL, *bga = NULL, *bgb = NULL;
    rpiv_piv *pv = NULL;
    rpiv_field *field = NULL, *mean = NULL, *rms = NULL, *grid = NULL;
    rpiv_meta meta = {0};
    run_ctx r = {0};
    cli_progress prog;
    rpiv_progress pr = {quiet_start, &prog};
    if ((st = rpiv_pairs_from_args(argc - optind, argv + optind, pairing, &pairs)))
        goto out_free;
    /* the frame size, from the first pair */
    if ((st = rpiv_pairs_load(pairs, 0, &a, &b)))
        goto out_free;
    int w = a->w, h = a->h;
    rpiv_image_free(a);
    rpiv_image_free(b);
    a = b = NULL;
    if (p->mask[0] && (st = rpiv_image_load(p->mask, 0, &mask, NULL)))
        goto out_free;
    if ((st = rpiv_piv_new(p, w, h, mask, &pv))) {
        if (st == RPIV_ESIZE) { /* the parameters do not fit the images: a usage error */
            char msg[768];
            snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
            st = rpiv_fail(RPIV_EINVAL, "%s", msg);
        }
        goto out_free;
    }
    /* the output's extension once the inputs are known good, before any long work */
    if (!field_ext(out)) {
        st = cli_usage_error("piv", "-o %s: the extension must be .txt, .nc, .dat or .vtk", out);
        goto out_free;
    }
    if (outdir && out == outbuf && (st = cli_mkdirs(outdir)))
        goto out_free;
    if (p->background != RPIV_BACKGROUND_NONE) {
        cli_progress_init(&prog, "background", c.quiet);
        if ((st = rpiv_piv_background(pairs, p->background, &pr, &bga, &bgb)))
            goto out_free;
    }
    if (bga && (st = rpiv_piv_set_background(pv, bga, bgb)))
        goto out_free;
    rpiv_image_free(bga);
    rpiv_image_free(bgb);
    bga = bgb = NULL;
    if ((st = add_meta(&meta, p, pairs, pv)))
        goto out_free;

    cli_progress_init(&prog, p->ensemble ? "ensemble" : "piv", c.quiet);
    if (p->ensemble) {
        if ((st = rpiv_ensemble_run(pv, pairs, &pr, &field)) ||
            (st = rpiv_field_save(field, &meta, out)))
            goto out_free;
        size_t n = (size_t)field->nx * (size_t)field->ny;
        r.nvec = n;
        for (size_t k = 0; k < n; k++)
            r.nreplaced += field->flag[k] == RPIV_FLAG_REPLACED;
    } else {
        r.out = out;
        r.npairs = pairs->n;
        r.meta = &meta;
        r.digits = 4;
        for (size_t n = pairs->n; n >= 10000; n /= 10)
            r.digits++;
        if ((st = rpiv_piv_grid(pv, rpiv_piv_npass(pv) - 1, &grid)))
            goto out_free;
        if (pairs->n > 1 && !strcasecmp(field_ext(out), ".nc") &&
            (st = rpiv_field_series_open(out, grid, &meta, &r.series)))
            goto out_free;
        if (meanrms && (st = rpiv_piv_stats_new(grid, &r.stats)))
            goto out_free;
        st = rpiv_piv_series(pv, pairs, sink, &r, &pr);
        if (r.series) {
            /* an interruption publishes the fields done so far */
            rpiv_status cs = rpiv_field_series_close(r.series, st && st != RPIV_EINTR);
            r.series = NULL;
            st = st ? st : cs;
        }
        if (st)
            goto out_free;
        if (meanrms) {
            char path[RPIV_PATH_MAX + 32];
            if ((st = rpiv_piv_stats_finish(r.stats, &mean, &rms)) ||
                (st = out_name(out, "_mean", path, sizeof path)) ||
                (st = rpiv_field_save(mean, &meta, path)) ||
                (st = out_name(out, "_rms", path, sizeof path)) ||
                (st = rpiv_field_save(rms, &meta, path)))
                goto out_free;
        }
    }
    if (plot) {
        const rpiv_field *pf = field ? field : (mean ? mean : r.first);
        char title[128];
        snprintf(title, sizeof title, "%s, %zu pair%s", field ? "ensemble" : (mean ? "mean" : "pair 1"),
                 pairs->n, pairs->n == 1 ? "" : "s");
        if ((st = rpiv_plot_quiver(pf, plot, title, NULL)))
            goto out_free;
    }
    if (!c.quiet)
        printf("rpiv piv: %zu pair%s, %s, %zu vectors, %.2f %% replaced -> %s%s\n", pairs->n,
               pairs->n == 1 ? "" : "s", p->ensemble ? "ensemble" : "instantaneous", r.nvec,
               r.nvec ? 100.0 * (double)r.nreplaced / (double)r.nvec : 0.0, out,
               !p->ensemble && pairs->n > 1 && strcasecmp(field_ext(out), ".nc")
                   ? " (one file per pair)" : "");
out_free:
    if (r.series && rpiv_field_series_close(r.series, 1))
        st = st ? st : RPIV_EIO; /* not reached: abort only removes a temporary file */
    rpiv_piv_stats_free(r.stats);
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
    rpiv_image_free(a);
    rpiv_image_free(b);
    rpiv_pairs_free(pairs);
    return st;
}
