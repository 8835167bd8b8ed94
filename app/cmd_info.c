/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv info - describe image files: format, size, bit depth, pages, grey levels. */
#include "cli.h"

#include "rpiv/image.h"

#include <stdio.h>
#include <string.h>

rpiv_status cmd_info(int argc, char **argv);

const cli_spec cmd_info_spec = {
    .name = "info",
    .usage = "usage: rpiv info FILE...\n\n"
             "Print one line per image file: path, format (detected from the file's content),\n"
             "width and height in pixels, bit depth, number of pages, and the minimum, maximum\n"
             "and mean grey level of page 0 (colour images as Rec. 601 luminance).\n"
             "A file that cannot be read gives one error line on stderr; the exit status is\n"
             "then 1, after the other files have been described.\n\noptions:\n"};

static rpiv_status describe(const char *path)
{
    rpiv_image_format fmt;
    rpiv_image *im = NULL;
    int pages = 0, warned = 0;
    rpiv_status st = rpiv_image_format_of(path, &fmt);
    if (!st)
        st = rpiv_image_count_pages(path, &pages);
    if (!st)
        st = rpiv_image_load(path, 0, &im, &warned);
    if (st)
        return st;
    rpiv_image_stats s = rpiv_image_stats_of(im);
    printf("%s: format %s width %d height %d bits %d pages %d min %.9g max %.9g mean %.6f%s\n",
           path, rpiv_image_format_name(fmt), im->w, im->h, im->bits, pages, s.min, s.max, s.mean,
           warned ? " (colour converted to luminance)" : "");
    rpiv_image_free(im);
    return RPIV_OK;
}

rpiv_status cmd_info(int argc, char **argv)
{
    int done;
    rpiv_status pst = cli_parse(&cmd_info_spec, NULL, NULL, argc, argv, &done);
    if (pst || done)
        return pst;
    if (optind >= argc)
        return cli_usage_error("info", "no image file given");
    /* Every file is described; the errors of all but the last failing file are printed
     * here, the last one is returned for main to print, so each bad file gets one line. */
    rpiv_status last = RPIV_OK;
    char pending[1024] = "";
    for (int i = optind; i < argc; i++) {
        rpiv_status st = describe(argv[i]);
        if (!st)
            continue;
        fflush(stdout);
        if (last)
            fprintf(stderr, "rpiv: error: %s\n", pending);
        snprintf(pending, sizeof pending, "%s", rpiv_errmsg());
        last = st;
    }
    fflush(stdout);
    if (last)
        return rpiv_fail(last, "%s", pending);
    return RPIV_OK;
}
