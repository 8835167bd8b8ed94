/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_fuzz_rss.c - issue 20 item 4's rule, for every small file the fuzzers keep: an
 * image file under 1 MB is read (page count, then up to four pages) within 100 MB of peak
 * RSS over the process's own, whatever it declares (a 4 KB PNG once made libpng allocate and
 * touch 2 GB). The files: every seed of fuzz/corpus/ and every regression file of
 * tests/data/fuzz-regressions/ (each is read as an image, whatever its kind: a text file
 * must fail as cheaply). Each is read in a child process whose ru_maxrss (wait4) is compared
 * with that of a child that reads nothing. `make fuzz` checks the same rule on the inputs it
 * makes, call by call, over the heap (fuzz_heap_begin in fuzz/fuzz.h; docs/fuzzing.md). */
#include "check.h"
#include "child_rss.h"

#include "rpiv/image.h"

#include <dirent.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define LIMIT_KB (100 * 1024L)
#define FILE_MAX (1024 * 1024L)

static long baseline_kb;
static int nfiles;
static long worst_kb;
static char worst[1024];

/* Read every page (up to four) of path; nothing for NULL. */
static int read_pages(void *arg)
{
    const char *path = arg;
    if (path) {
        int pages = 1;
        if (rpiv_image_count_pages(path, &pages) != RPIV_OK || pages < 1)
            pages = 1;
        for (int p = 0; p < pages && p < 4; p++) {
            rpiv_image *im = NULL;
            if (rpiv_image_load(path, p, &im, NULL) == RPIV_OK)
                rpiv_image_free(im);
        }
    }
    return 0;
}

/* Peak RSS (KiB) of a child that reads path (NULL: nothing); -1 if it did not exit. */
static long child_rss_kb(const char *path)
{
    return ti_child_rss_kb(read_pages, (void *)path, NULL);
}

static void check_file(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode) || st.st_size >= FILE_MAX)
        return;
    long kb = child_rss_kb(path);
    nfiles++;
    if (kb < 0) {
        fprintf(stderr, "%s: the reader did not exit normally\n", path);
        CHECK(kb >= 0);
        return;
    }
    if (kb - baseline_kb > worst_kb) {
        worst_kb = kb - baseline_kb;
        snprintf(worst, sizeof worst, "%s", path);
    }
    if (kb - baseline_kb >= LIMIT_KB) {
        fprintf(stderr, "%s (%lld bytes): peak RSS %ld KiB over the process's %ld KiB\n", path,
                (long long)st.st_size, kb - baseline_kb, baseline_kb);
        CHECK(kb - baseline_kb < LIMIT_KB);
    }
}

/* Every regular file of dir and of its sub-folders (one level). */
static void check_dir(const char *dir, int depth)
{
    DIR *d = opendir(dir);
    CHECK(d != NULL);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.')
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        struct stat st;
        if (stat(path, &st) != 0)
            continue;
        if (S_ISDIR(st.st_mode) && depth > 0)
            check_dir(path, depth - 1);
        else
            check_file(path);
    }
    closedir(d);
}

static void small_files_stay_under_100_mb(void)
{
    const char *src = getenv("RPIV_SOURCE_DIR"), *data = getenv("RPIV_TEST_DATA");
    if (!src || !data) {
        check_skip("RPIV_SOURCE_DIR or RPIV_TEST_DATA not set");
        return;
    }
    baseline_kb = child_rss_kb(NULL);
    CHECK(baseline_kb > 0);
    char dir[1024];
    snprintf(dir, sizeof dir, "%s/fuzz/corpus", src);
    check_dir(dir, 1);
    snprintf(dir, sizeof dir, "%s/fuzz-regressions", data);
    check_dir(dir, 0);
    printf("  %d files under 1 MB; the largest peak RSS over the process's own (%ld KiB): %ld "
           "KiB, %s\n",
           nfiles, baseline_kb, worst_kb, worst);
    CHECK(nfiles >= 150);
}

int main(void)
{
    RUN_TEST(small_files_stay_under_100_mb);
    return check_summary();
}
