/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv calib - light-sheet profile and depth of focus from images of targets on an inclined
 * plate, and such target images rendered from the model (calib.h; docs/calib.md). */
#include "cli.h"

#include "rpiv/calib.h"
#include "rpiv/image.h"
#include "rpiv/report.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status cmd_calib(int argc, char **argv);

enum mode { SHEET, DOF, RENDER_SHEET, RENDER_DOTS };

typedef struct job {
    cli_ctx c;
    enum mode mode;
    rpiv_calib_geom geom;
    double smooth;
    int smooth_set, no_floor, png;
    double dot_d, pitch, refl;
    int refl_set;
    double *xs, *feet;
    size_t nx, nfeet;
    const char *dark_image, *dir, *profile, *output, *size;
    rpiv_calib_render_params rp;
    int dark_set;
    const char *sub; /* the sub-command as given */
    char name[48];   /* "calib <sub>", in messages */
} job;

static rpiv_status push(double **arr, size_t *n, double v)
{
    double *t = realloc(*arr, (*n + 1) * sizeof *t);
    if (!t)
        return rpiv_fail(RPIV_ENOMEM, "calib: out of memory");
    t[(*n)++] = v;
    *arr = t;
    return RPIV_OK;
}

static rpiv_status parse_ints(const char *opt, const char *arg, int n, int *out)
{
    char *end;
    const char *s = arg;
    for (int i = 0; i < n; i++) {
        errno = 0;
        long v = strtol(s, &end, 10);
        if (end == s || errno || v < 0 || v > 1000000 || (i + 1 < n ? *end != ',' : *end != '\0'))
            return rpiv_fail(RPIV_EINVAL, "%s: '%s' is not %d non-negative integers a,b%s", opt,
                             arg, n, n > 2 ? ",..." : "");
        out[i] = (int)v;
        s = end + 1;
    }
    return RPIV_OK;
}

/* Options: which modes accept each (bit 1 << mode), the rows' scope. */
#define M_AN  ((1 << SHEET) | (1 << DOF))
#define M_RE  ((1 << RENDER_SHEET) | (1 << RENDER_DOTS))
#define M_ALL (M_AN | M_RE)

static rpiv_status check(void *obj, const cli_opt *o, const char *typed)
{
    const job *j = obj;
    if (!((o->scope >> j->mode) & 1))
        return cli_usage_error(j->name, "option '%s' does not apply to %s", typed, j->sub);
    return RPIV_OK;
}

static rpiv_status set_angle(void *obj, const char *arg)
{
    job *j = obj;
    double v;
    rpiv_status st = cli_parse_double("--plate-angle", arg, -90, 90, &v);
    j->geom.angle_deg = j->rp.angle_deg = v;
    return st;
}

static rpiv_status set_height(void *obj, const char *arg)
{
    job *j = obj;
    double v;
    rpiv_status st = cli_parse_double("--plate-height", arg, 0, 1e4, &v);
    j->geom.plate_height_m = j->rp.plate_height_m = v * 1e-3;
    return st;
}

static rpiv_status set_foot(void *obj, const char *arg)
{
    job *j = obj;
    double v;
    rpiv_status st = cli_parse_double("--foot-px", arg, -1e6, 1e6, &v);
    return st ? st : push(&j->feet, &j->nfeet, v);
}

static rpiv_status set_x(void *obj, const char *arg)
{
    job *j = obj;
    double v;
    rpiv_status st = cli_parse_double("--x", arg, -1e6, 1e6, &v);
    return st ? st : push(&j->xs, &j->nx, v);
}

static rpiv_status set_scale(void *obj, const char *arg)
{
    job *j = obj;
    double v;
    rpiv_status st = cli_parse_double("--scale", arg, 1e-3, 1e6, &v);
    j->geom.scale_px_m = j->rp.scale_px_m = v * 1e3;
    return st;
}

static rpiv_status set_rows(void *obj, const char *arg)
{
    job *j = obj;
    int rows[2] = {0, 0};
    rpiv_status st = parse_ints("--rows", arg, 2, rows);
    if (!st) {
        j->geom.row0 = rows[0];
        j->geom.row1 = rows[1];
    }
    return st;
}

static rpiv_status set_dark(void *obj, const char *arg)
{
    job *j = obj;
    double v;
    rpiv_status st = cli_parse_double("--dark", arg, -1e9, 1e9, &v);
    j->geom.dark = j->rp.dark = v;
    j->dark_set = 1;
    return st;
}

static rpiv_status set_region(void *obj, const char *arg)
{
    job *j = obj;
    int reg[4] = {0, 0, 0, 0};
    rpiv_status st = parse_ints("--dark-region", arg, 4, reg);
    if (!st) {
        j->geom.dark_x = reg[0];
        j->geom.dark_y = reg[1];
        j->geom.dark_w = reg[2];
        j->geom.dark_h = reg[3];
    }
    return st;
}

static rpiv_status set_smooth(void *obj, const char *arg)
{
    job *j = obj;
    j->smooth_set = 1;
    return cli_parse_double("--smooth", arg, 0, 100, &j->smooth);
}

static rpiv_status set_dot(void *obj, const char *arg)
{
    job *j = obj;
    double v;
    rpiv_status st = cli_parse_double("--dot-diameter", arg, 1e-4, 100, &v);
    j->dot_d = j->rp.dot_d_m = v * 1e-3;
    return st;
}

static rpiv_status set_pitch(void *obj, const char *arg)
{
    job *j = obj;
    double v;
    rpiv_status st = cli_parse_double("--pitch", arg, 1e-4, 100, &v);
    j->pitch = j->rp.pitch_m = v * 1e-3;
    return st;
}

static rpiv_status set_refl(void *obj, const char *arg)
{
    job *j = obj;
    rpiv_status st = cli_parse_double("--reflectance", arg, 0, 0.999, &j->refl);
    j->rp.reflectance = j->refl;
    j->refl_set = 1;
    return st;
}

static rpiv_status set_seed(void *obj, const char *arg)
{
    job *j = obj;
    long v;
    rpiv_status st = cli_parse_int("--seed", arg, 0, 2147483647L, &v);
    j->rp.seed = (unsigned long)v;
    return st;
}

#define FN(nm, a, f, modes, text)                                                                  \
    {                                                                                              \
        .name = nm, .kind = CLI_FN, .arg = a, .fn = f, .scope = modes, .help = text                \
    }
#define RENDER(nm, a, field, lo, modes, text)                                                      \
    {                                                                                              \
        .name = nm, .kind = CLI_DOUBLE, .arg = a, .off = offsetof(job, rp.field), .min = lo,       \
        .max = 1e9, .scope = modes, .help = text                                                   \
    }

static const cli_opt options[] = {
    {.kind = CLI_HEAD, .help = "options (analysis; those marked * apply to the renderings too):"},
    FN("plate-angle", "DEG", set_angle, M_ALL,
       "* plate inclination from the floor (45); negative: the plate\n"
       "rises toward decreasing x; 0: detect from the plate's extent"),
    FN("plate-height", "MM", set_height, M_ALL,
       "* height of the plate's top edge (channel height), for 0 above"),
    FN("foot-px", "PX", set_foot, M_ALL,
       "* column of the plate foot (z* = 0); once for all images or once\n"
       "per image; default: detected from the plate's edge"),
    FN("x", "X*", set_x, (1 << SHEET) | (1 << RENDER_SHEET),
       "* sheet: x* of the plate foot, once per image (default: from\n"
       "channel.fov_x0 and the foot column)"),
    FN("scale", "PX_PER_MM", set_scale, M_ALL,
       "* object-space image scale (default camera M / pixel pitch)"),
    FN("rows", "Y0,Y1", set_rows, M_AN, "rows averaged along the span (all)"),
    FN("dark", "LEVEL", set_dark, M_ALL, "* dark level (0; render: 100)"),
    {.name = "dark-image",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = offsetof(job, dark_image),
     .scope = M_AN,
     .help = "dark level from an image"},
    FN("dark-region", "X,Y,W,H", set_region, M_AN, "dark level from a region of each image"),
    FN("smooth", "PX", set_smooth, M_AN,
       "sheet: Gaussian smoothing of the profile (0); dof: of the image\n"
       "for detecting the dots (0.7)"),
    {.name = "no-floor",
     .kind = CLI_FLAG,
     .off = offsetof(job, no_floor),
     .scope = 1 << SHEET,
     .help = "sheet: do not subtract the profile's minimum (plate glow)"},
    FN("dot-diameter", "MM", set_dot, (1 << DOF) | (1 << RENDER_DOTS),
       "* dof: the target's dot diameter (0.0625)"),
    FN("pitch", "MM", set_pitch, (1 << DOF) | (1 << RENDER_DOTS),
       "* dof: the target's dot pitch (0.125)"),
    FN("reflectance", "R", set_refl, (1 << DOF) | (1 << RENDER_DOTS),
       "* dof: dot reflectance for the model (default: the one that\n"
       "matches the measured peak; render: 0.1)"),
    {.name = "out",
     .kind = CLI_STR,
     .arg = "DIR",
     .off = offsetof(job, dir),
     .scope = M_AN,
     .help = "output folder (output.dir)"},
    {.name = "profile",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = offsetof(job, profile),
     .scope = 1 << SHEET,
     .help = "sheet: the profile file (DIR/calib_sheet_profile.txt)"},
    {.name = "png",
     .kind = CLI_FLAG,
     .off = offsetof(job, png),
     .scope = M_AN,
     .help = "also write PNG plots"},
    {.kind = CLI_HEAD, .help = "\noptions (render):"},
    {.name = "output",
     .letter = 'o',
     .kind = CLI_STR,
     .arg = "FILE",
     .off = offsetof(job, output),
     .scope = M_RE,
     .help = "the image (.tif 16-bit, .png)"},
    {.name = "size",
     .kind = CLI_STR,
     .arg = "WxH",
     .off = offsetof(job, size),
     .scope = M_RE,
     .help = "image size (camera sensor)"},
    RENDER("level", "L", level, 1e-6, M_RE,
           "fluorescence at I0 = 1 / white level above dark (3000)"),
    RENDER("background", "B", background, 0, M_RE, "floor outside the plate above dark (150)"),
    RENDER("glow", "G", glow, 0, 1 << RENDER_SHEET, "sheet: plate emission outside the sheet (0)"),
    RENDER("noise", "N", noise, 0, M_RE, "Gaussian noise sigma, grey (0)"),
    FN("seed", "S", set_seed, M_RE, "noise seed (1)"),
};

const cli_spec cmd_calib_spec = {
    .name = "calib",
    .usage =
        "usage: rpiv calib sheet [options] IMAGE...\n"
        "       rpiv calib dof --dot-diameter MM --pitch MM [options] IMAGE...\n"
        "       rpiv calib render-sheet [options] -o FILE.tif\n"
        "       rpiv calib render-dots [options] -o FILE.tif\n\n"
        "Calibration from images of a target on a plate inclined in the channel (fluid at\n"
        "rest), seen from below: image x runs along the flow, y along the span. A plate point\n"
        "at column X is at height z* = (X - X_foot) tan(angle) / (s h), s = M / pixel pitch.\n\n"
        "sheet   fluorescent plate in the laser sheet, one image per plate position: profile\n"
        "        I0*(z*) and z*_inf, z*_max, z*_sup, e* (at 0.25 max) for each plate, the lines\n"
        "        z*_max(x*), e*(x*) through all plates and the mean shape I0*(z+), written as a\n"
        "        sheet profile file (sheet.kind = selfsim, sheet.profile = FILE).\n"
        "dof     dotted target (black dots on white): each dot's grey level I* relative to the\n"
        "        local mean, averaged along the span; DOF* = full width at half maximum of\n"
        "        (1/I* - 1) against z*, z*_OP = its maximum; compared with the imaging model.\n"
        "render-sheet, render-dots   the target image the model predicts for the configured\n"
        "        camera, channel and sheet (to check a set-up, or to test the analysis).\n\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .epilog = "\nThe camera, channel (h, fov_x0) and, for render-sheet, the sheet come from the\n"
              "configuration. See docs/calib.md.\n",
    .common = 1,
    .check = check};

static rpiv_status parse(job *j, int argc, char **argv, int *done)
{
    cli_spec spec = cmd_calib_spec;
    spec.name = j->name;
    rpiv_status st = cli_parse(&spec, &j->c, j, argc, argv, done);
    if (st || *done)
        return st;
    if (!j->dir)
        j->dir = j->c.exp.output.dir;
    return RPIV_OK;
}

static rpiv_status out_path(char *buf, const char *dir, const char *name)
{
    if ((size_t)snprintf(buf, RPIV_PATH_MAX, "%s/%s", dir, name) >= RPIV_PATH_MAX)
        return rpiv_fail(RPIV_EINVAL, "%s/%s: path too long", dir, name);
    return RPIV_OK;
}

/* ---- images ------------------------------------------------------------------------------ */

typedef struct images {
    size_t n;
    rpiv_image **im;
    rpiv_calib_shot *shot;
    rpiv_image *dark;
} images;

static void images_free(images *s)
{
    for (size_t i = 0; i < s->n; i++)
        rpiv_image_free(s->im[i]);
    free(s->im);
    free(s->shot);
    rpiv_image_free(s->dark);
}

static rpiv_status load_images(job *j, int nargs, char **args, const char *name, images *s)
{
    rpiv_status st;
    if (nargs < 1)
        return cli_usage_error(name, "no image given");
    size_t n = (size_t)nargs;
    if (j->nfeet > 1 && j->nfeet != n)
        return cli_usage_error(name, "%zu --foot-px for %zu images (give one, or one per image)",
                               j->nfeet, n);
    if (j->nx && j->nx != n)
        return cli_usage_error(name, "%zu --x for %zu images (give one per image)", j->nx, n);
    s->im = calloc(n, sizeof *s->im);
    s->shot = calloc(n, sizeof *s->shot);
    if (!s->im || !s->shot)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", name);
    s->n = n;
    for (size_t i = 0; i < n; i++) {
        int warned = 0;
        if ((st = rpiv_image_load(args[i], 0, &s->im[i], &warned)))
            return st;
        if (warned && !j->c.quiet)
            fprintf(stderr, "rpiv: warning: %s: colour image converted to grey\n", args[i]);
        s->shot[i] =
            (rpiv_calib_shot){s->im[i], j->nfeet ? j->feet[j->nfeet > 1 ? i : 0] : (double)NAN,
                              j->nx ? j->xs[i] : (double)NAN};
    }
    if (j->dark_image && (st = rpiv_image_load(j->dark_image, 0, &s->dark, NULL)))
        return st;
    return RPIV_OK;
}

/* ---- sheet ------------------------------------------------------------------------------- */

static rpiv_status run_sheet(job *j, int nargs, char **args)
{
    images s = {0, NULL, NULL, NULL};
    rpiv_calib_sheet_result *r = NULL;
    rpiv_calib_sheet_params p = rpiv_calib_sheet_params_default();
    p.geom = j->geom;
    if (j->smooth_set)
        p.smooth_px = j->smooth;
    p.subtract_floor = !j->no_floor;
    rpiv_status st = rpiv_calib_sheet_params_check(&p);
    if (st || (st = load_images(j, nargs, args, "calib sheet", &s)))
        goto out;
    if ((st = rpiv_calib_sheet_run(&p, &j->c.exp.camera, &j->c.exp.channel, s.shot, s.n, s.dark,
                                   &r)))
        goto out;
    if ((st = cli_mkdirs(j->dir)))
        goto out;
    for (size_t i = 0; i < r->nplates; i++) {
        const rpiv_calib_sheet_plate *pl = &r->plate[i];
        printf("%s: foot %.2f px, angle %.2f deg, x*_foot %.4f; along the plate z*_inf %.4f "
               "z*_max %.4f z*_sup %.4f e* %.4f; sheet at x* = %.4f: z*_inf %.4f z*_max %.4f "
               "z*_sup %.4f e* %.4f\n",
               args[i], pl->foot_px, pl->angle_deg, pl->x_foot, pl->raw.zinf, pl->raw.zmax,
               pl->raw.zsup, pl->raw.e, pl->x_max, pl->at.zinf, pl->at.zmax, pl->at.zsup, pl->at.e);
    }
    printf("self-similar sheet: z*_max = %.4f + %.5f x* (inclination %.3f deg), e* = %.4f + "
           "%.5f x*%s\n",
           r->zm0, r->zm1, rpiv_sheet_incl_deg(r->zm1), r->e0, r->e1,
           r->nplates > 1 ? "" : " (one plate: no slopes)");
    const char *prof = j->profile;
    char ppath[RPIV_PATH_MAX];
    if (!prof) {
        if ((st = out_path(ppath, j->dir, "calib_sheet_profile.txt")))
            goto out;
        prof = ppath;
    }
    if ((st = rpiv_calib_sheet_save_profile(r, prof)) ||
        (st = rpiv_report_calib_sheet_tables(r, j->dir)))
        goto out;
    if (j->png && (st = rpiv_report_calib_sheet(r, j->dir)))
        goto out;
    if (!j->c.quiet)
        printf("wrote %s (sheet.kind = selfsim, sheet.profile = %s); tables%s in %s/ "
               "(calib_sheet_*)\n",
               prof, prof, j->png ? " and plots" : "", j->dir);
out:
    rpiv_calib_sheet_result_free(r);
    images_free(&s);
    return st;
}

/* ---- dof --------------------------------------------------------------------------------- */

static rpiv_status run_dof(job *j, int nargs, char **args)
{
    images s = {0, NULL, NULL, NULL};
    rpiv_calib_dof_result *r = NULL;
    rpiv_calib_focus model;
    memset(&model, 0, sizeof model);
    rpiv_calib_dof_params p = rpiv_calib_dof_params_default();
    p.geom = j->geom;
    if (j->dot_d > 0)
        p.dot_d_m = j->dot_d;
    if (j->pitch > 0)
        p.pitch_m = j->pitch;
    if (j->smooth_set)
        p.smooth_px = j->smooth;
    rpiv_status st = rpiv_calib_dof_params_check(&p);
    if (st || (st = load_images(j, nargs, args, "calib dof", &s)))
        goto out;
    if ((st = rpiv_calib_dof_run(&p, &j->c.exp.camera, &j->c.exp.channel, s.shot, s.n, s.dark, &r)))
        goto out;
    if ((st = cli_mkdirs(j->dir)))
        goto out;
    const rpiv_calib_focus *c = &r->curve;
    for (size_t i = 0; i < r->nshots; i++)
        printf("%s: foot %.2f px, angle %.2f deg\n", args[i], r->foot_px[i], r->angle_deg[i]);
    printf("%zu dots in %zu columns, z* %.3f..%.3f; peak 1/I* %.3f\n", r->ndots, c->n, c->z[0],
           c->z[c->n - 1], c->inv_max);
    printf("z*_OP %.4f (half-maximum midpoint %.4f), DOF* %.4f (half maximum at z* %.4f and "
           "%.4f); FWHM of 1/I* alone %.4f, of the darkness 1 - I* %.4f\n",
           c->zop, c->zmid, c->dof, c->zlo, c->zhi, c->dof_raw, c->dof_contrast);
    /* the imaging model for this camera and target, with the dots' reflectance given or
     * matched to the measured peak */
    rpiv_camera cam = j->c.exp.camera;
    cam.zop_star = c->zop;
    double refl = j->refl;
    rpiv_status ms = RPIV_OK;
    if (!j->refl_set)
        ms = rpiv_calib_dof_reflectance(&p, &cam, j->c.exp.channel.h_m, c->inv_max, &refl);
    if (ms == RPIV_OK)
        ms = rpiv_calib_dof_model(&p, &cam, j->c.exp.channel.h_m, refl, 0.005, &model);
    if (ms == RPIV_OK)
        printf("model (f# %g, M %g, s0 %g mm; dot reflectance %.3f%s): DOF* %.4f, peak 1/I* "
               "%.3f\n",
               cam.fnumber, cam.magnification, cam.s0_m * 1e3, refl,
               j->refl_set ? "" : " matching the measured peak", model.dof, model.inv_max);
    else
        printf("model: not available (%s)\n", rpiv_errmsg());
    if ((st = rpiv_report_calib_dof_tables(r, model.n ? &model : NULL, j->dir)))
        goto out;
    if (j->png && (st = rpiv_report_calib_dof(c, model.n ? &model : NULL, 0, j->dir)))
        goto out;
    if (!j->c.quiet)
        printf("tables%s in %s/ (calib_dof_*)\n", j->png ? " and plot" : "", j->dir);
out:
    rpiv_calib_focus_free(&model);
    rpiv_calib_dof_result_free(r);
    images_free(&s);
    return st;
}

/* ---- render ------------------------------------------------------------------------------ */

static rpiv_status run_render(job *j, const char *name)
{
    const rpiv_experiment *e = &j->c.exp;
    int w = e->camera.width_px, h = e->camera.height_px;
    if (!j->output)
        return cli_usage_error(name, "missing -o FILE");
    if (rpiv_image_save_check(j->output)) /* before the rendering, not after */
        return cli_usage_error(name, "-o %s: the extension must be .tif, .tiff or .png", j->output);
    if (j->size) {
        rpiv_status st = cli_parse_size("--size", j->size, 8, 65536, &w, &h);
        if (st)
            return st;
    }
    if (j->nfeet > 1 || j->nx > 1)
        return cli_usage_error(name, "one --foot-px and one --x at most");
    if (j->nfeet)
        j->rp.foot_px = j->feet[0];
    if (j->nx)
        j->rp.x_foot = j->xs[0];
    rpiv_image *im = NULL;
    rpiv_sheet *sheet = NULL;
    rpiv_status st = rpiv_image_new(w, h, &im);
    if (st)
        return st;
    if (j->mode == RENDER_SHEET) {
        if (!(st = rpiv_sheet_new(&e->sheet, &sheet)))
            st = rpiv_calib_render_sheet(&j->rp, &e->camera, &e->channel, sheet, im);
    } else {
        st = rpiv_calib_render_dots(&j->rp, &e->camera, &e->channel, im);
    }
    if (!st)
        st = rpiv_image_save(im, j->output);
    if (!st && !j->c.quiet)
        printf("wrote %s (%dx%d): %s on a %g deg plate, foot at column %g, z*_OP %g\n", j->output,
               w, h, j->mode == RENDER_SHEET ? "fluorescent plate" : "dotted target",
               j->rp.angle_deg, j->rp.foot_px, e->camera.zop_star);
    rpiv_sheet_free(sheet);
    rpiv_image_free(im);
    return st;
}

rpiv_status cmd_calib(int argc, char **argv)
{
    static const char *const names[] = {"sheet", "dof", "render-sheet", "render-dots"};
    if (argc < 2 || argv[1][0] == '-') {
        if (argc >= 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
            cli_help(&cmd_calib_spec);
            return RPIV_OK;
        }
        if (argc >= 2)
            return cli_usage_error("calib",
                                   "unknown option '%s' before the SUBCOMMAND (sheet, "
                                   "dof, render-sheet, render-dots)",
                                   argv[1]);
        return cli_usage_error("calib", "missing SUBCOMMAND (sheet, dof, render-sheet, "
                                        "render-dots)");
    }
    job j;
    memset(&j, 0, sizeof j);
    cli_ctx_init(&j.c);
    j.geom = rpiv_calib_geom_default();
    j.rp = rpiv_calib_render_params_default();
    int found = 0;
    for (int m = 0; m < 4; m++)
        if (!strcmp(argv[1], names[m])) {
            j.mode = (enum mode)m;
            found = 1;
        }
    if (!found)
        return cli_usage_error("calib", "unknown subcommand '%s'", argv[1]);
    j.sub = argv[1];
    snprintf(j.name, sizeof j.name, "calib %s", argv[1]);
    const char *name = j.name;
    int done = 0;
    rpiv_status st = parse(&j, argc - 1, argv + 1, &done);
    if (st || done)
        goto out;
    if ((st = rpiv_experiment_check(&j.c.exp)))
        goto out;
    int nargs = argc - 1 - optind;
    char **args = argv + 1 + optind;
    switch (j.mode) {
    case SHEET:
        st = run_sheet(&j, nargs, args);
        break;
    case DOF:
        st = run_dof(&j, nargs, args);
        break;
    case RENDER_SHEET:
    case RENDER_DOTS:
        if (nargs > 0) {
            st = cli_usage_error(name, "unexpected argument '%s'", args[0]);
            break;
        }
        st = run_render(&j, name);
        break;
    }
out:
    free(j.xs);
    free(j.feet);
    return st;
}
