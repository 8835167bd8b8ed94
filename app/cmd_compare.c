/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv compare - E1 (Eq. "E1"), RMS and largest difference between two profiles or two
 * vector files. */
#include "cli.h"

#include "rpiv/field.h"
#include "rpiv/report.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status cmd_compare(int argc, char **argv);

typedef struct opts {
    cli_ctx c;
    const char *png, *cname;
    rpiv_component comp;
} opts;

static rpiv_status set_component(void *obj, const char *arg)
{
    opts *o = obj;
    o->cname = arg;
    if (!strcmp(arg, "u"))
        o->comp = RPIV_COMPONENT_U;
    else if (!strcmp(arg, "v"))
        o->comp = RPIV_COMPONENT_V;
    else if (!strcmp(arg, "mag"))
        o->comp = RPIV_COMPONENT_MAG;
    else
        return cli_usage_error("compare", "--component: '%s' is not u, v or mag", arg);
    return RPIV_OK;
}

static const cli_opt options[] = {
    {.name = "component",
     .kind = CLI_FN,
     .arg = "C",
     .fn = set_component,
     .help = "vector files: compare u, v or mag (|(u,v)|, default)"},
    {.name = "png",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = offsetof(opts, png),
     .help = "plot both profiles, or the map of REF - CMP, into FILE (PNG)"},
};

const cli_spec cmd_compare_spec = {
    .name = "compare",
    .usage = "usage: rpiv compare REF CMP [--component u|v|mag] [--png FILE]\n\n"
             "Compare CMP with the reference REF and print E1 (Eq. \"E1\" of the paper: RMS of\n"
             "REF - CMP over the mean of REF), the RMS and the largest absolute difference.\n"
             "Both are profiles (two columns: alpha value; CMP is interpolated linearly onto\n"
             "REF's alpha within the range they share, which is rescaled to 0..1) or both\n"
             "vector text files on the same grid (columns x y u v [flag ...]; points masked\n"
             "in either file are left out).\n\noptions:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .common = 1};

/* Prefix the library's message with the two file names. */
static rpiv_status name_files(rpiv_status st, const char *ref, const char *cmp)
{
    char msg[512];
    snprintf(msg, sizeof msg, "%s", rpiv_errmsg()); /* rpiv_fail writes the same buffer */
    return rpiv_fail(st, "%s vs %s: %s", ref, cmp, msg);
}

static void print_result(const rpiv_compare *r)
{
    printf("E1 %.6g\nRMS %.6g\nmax %.6g\nn %zu\n", r->e1, r->rms, r->max_abs, r->n);
}

static rpiv_status compare_profiles(const char *ref_path, const char *cmp_path, const char *png)
{
    rpiv_profile *ref = NULL, *cmp = NULL;
    rpiv_compare r;
    rpiv_status st = rpiv_profile_load(ref_path, &ref);
    if (!st)
        st = rpiv_profile_load(cmp_path, &cmp);
    if (st)
        goto out;
    if ((st = rpiv_profile_compare(ref, cmp, &r))) {
        st = name_files(st, ref_path, cmp_path);
        goto out;
    }
    print_result(&r);
    printf("range %.10g %.10g\n", r.alpha0, r.alpha1);
    if (png)
        st = rpiv_report_compare_profiles(png, ref, cmp, ref_path, cmp_path, &r);
out:
    rpiv_profile_free(ref);
    rpiv_profile_free(cmp);
    return st;
}

static rpiv_status compare_fields(const char *ref_path, const char *cmp_path, rpiv_component c,
                                  const char *cname, const char *png)
{
    rpiv_field *ref = NULL, *cmp = NULL;
    rpiv_compare r;
    rpiv_status st = rpiv_field_load_txt(ref_path, &ref);
    if (!st)
        st = rpiv_field_load_txt(cmp_path, &cmp);
    if (st)
        goto out;
    if ((st = rpiv_field_compare(ref, cmp, c, &r))) {
        st = name_files(st, ref_path, cmp_path);
        goto out;
    }
    printf("component %s\n", cname);
    print_result(&r);
    if (png)
        st = rpiv_report_compare_fields(png, ref, cmp, c, cname, &r);
out:
    rpiv_field_free(ref);
    rpiv_field_free(cmp);
    return st;
}

rpiv_status cmd_compare(int argc, char **argv)
{
    opts o = {.comp = RPIV_COMPONENT_MAG};
    int done;
    rpiv_status st;
    cli_ctx_init(&o.c);
    if ((st = cli_parse(&cmd_compare_spec, &o.c, &o, argc, argv, &done)) || done)
        return st;
    const char *png = o.png, *cname = o.cname;
    rpiv_component comp = o.comp;
    if (argc - optind != 2)
        return cli_usage_error("compare", "need two files, REF and CMP (got %d)", argc - optind);
    const char *ref = argv[optind], *cmp = argv[optind + 1];
    int nref, ncmp;
    if ((st = rpiv_text_columns(ref, &nref)) || (st = rpiv_text_columns(cmp, &ncmp)))
        return st;
    if (nref == 2 || nref == 3) {
        if (ncmp < 2 || ncmp > 3)
            return rpiv_fail(RPIV_EFORMAT, "%s: %d columns, but %s is a profile (alpha value)", cmp,
                             ncmp, ref);
        if (cname)
            return cli_usage_error("compare",
                                   "--component applies to vector files, and %s is "
                                   "a profile",
                                   ref);
        return compare_profiles(ref, cmp, png);
    }
    if (nref < 2)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: 1 column: neither a profile (alpha value) nor a "
                         "vector file (x y u v ...)",
                         ref);
    if (ncmp < 4)
        return rpiv_fail(RPIV_EFORMAT, "%s: %d columns, but %s is a vector file (x y u v ...)", cmp,
                         ncmp, ref);
    return compare_fields(ref, cmp, comp, cname ? cname : "mag", png);
}
