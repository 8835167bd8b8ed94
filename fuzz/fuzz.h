/* SPDX-License-Identifier: GPL-3.0-or-later */
/* fuzz/fuzz.h - libFuzzer helpers: the readers take paths, so each input is written to a
 * per-process file in /dev/shm (or /tmp) first; FUZZ_CHECK states an invariant (a failed one
 * prints what broke and aborts, which libFuzzer reports as a crash). */
#ifndef RPIV_FUZZ_H
#define RPIV_FUZZ_H

#include "rpiv/error.h"
#include "rpiv/image.h"

#include <dirent.h>
#include <math.h>
#include <sanitizer/allocator_interface.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define FUZZ_CHECK(cond, ...)                                                                      \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fprintf(stderr, "fuzz invariant failed: %s (%s:%d): ", #cond, __FILE__, __LINE__);     \
            fprintf(stderr, __VA_ARGS__);                                                          \
            fprintf(stderr, "\n");                                                                 \
            abort();                                                                               \
        }                                                                                          \
    } while (0)

static char fuzz_scratch[96];

/* Remove the scratch folder's files and the folder (at exit; it holds no subfolder). */
static inline void fuzz_cleanup(void)
{
    DIR *d = opendir(fuzz_scratch);
    if (!d)
        return;
    struct dirent *e;
    char p[512];
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
            snprintf(p, sizeof p, "%s/%s", fuzz_scratch, e->d_name);
            unlink(p);
        }
    }
    closedir(d);
    rmdir(fuzz_scratch);
}

/* The scratch folder of this process: /dev/shm (or /tmp)/rpiv-fuzz-PID, removed at exit. */
static inline const char *fuzz_dir(void)
{
    if (!fuzz_scratch[0]) {
        const char *base = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
        snprintf(fuzz_scratch, sizeof fuzz_scratch, "%s/rpiv-fuzz-%d", base, (int)getpid());
        if (mkdir(fuzz_scratch, 0700) == 0)
            atexit(fuzz_cleanup);
    }
    return fuzz_scratch;
}

/* Write data to a scratch file named "input<suffix>" (e.g. ".ini"); returns its path. */
static inline const char *fuzz_file(const uint8_t *data, size_t size, const char *suffix)
{
    static char path[160];
    snprintf(path, sizeof path, "%s/input%s", fuzz_dir(), suffix);
    FILE *fp = fopen(path, "wb");
    if (!fp)
        return NULL;
    if (size && fwrite(data, 1, size, fp) != size) {
        fclose(fp);
        return NULL;
    }
    if (fclose(fp) != 0)
        return NULL;
    return path;
}

/* The heap a call takes (issue 20 item 4: an image file under 1 MB is read within 100 MB).
 * fuzz_heap_begin() starts watching and returns the live heap (ASan's count of bytes allocated
 * and not freed); every allocation then updates the high-water mark; fuzz_heap_end() checks
 * that the mark stayed within limit bytes over the start, naming what was called. Exact and
 * per call, unlike libFuzzer's -rss_limit_mb, which samples the whole process (its corpus
 * included) once a second. Freed blocks in ASan's quarantine are not counted. */
static size_t fuzz_heap_mark;
static int fuzz_heap_watch;

static inline void fuzz_heap_malloc_hook(const volatile void *p, size_t n)
{
    (void)p;
    (void)n;
    if (fuzz_heap_watch) {
        size_t now = __sanitizer_get_current_allocated_bytes();
        if (now > fuzz_heap_mark)
            fuzz_heap_mark = now;
    }
}

static inline void fuzz_heap_free_hook(const volatile void *p)
{
    (void)p;
}

static inline size_t fuzz_heap_begin(void)
{
    static int installed;
    if (!installed) {
        FUZZ_CHECK(__sanitizer_install_malloc_and_free_hooks(fuzz_heap_malloc_hook,
                                                             fuzz_heap_free_hook) > 0,
                   "cannot install the allocation hooks");
        installed = 1;
    }
    fuzz_heap_mark = __sanitizer_get_current_allocated_bytes();
    fuzz_heap_watch = 1;
    return fuzz_heap_mark;
}

#define FUZZ_HEAP_LIMIT ((size_t)100 << 20)

static inline void fuzz_heap_end(size_t start, const char *path, const char *what)
{
    fuzz_heap_watch = 0;
    FUZZ_CHECK(fuzz_heap_mark - start < FUZZ_HEAP_LIMIT, "%s: %s took %zu bytes of heap", path,
               what, fuzz_heap_mark - start);
}

/* A failed call leaves a non-empty message that names `what` (a path or key). */
static inline void fuzz_check_failure(rpiv_status st, const char *what)
{
    const char *m = rpiv_errmsg();
    FUZZ_CHECK(st > 0, "status %d", (int)st);
    FUZZ_CHECK(m && m[0], "status %d with an empty message", (int)st);
    FUZZ_CHECK(strstr(m, what) != NULL, "message does not name %s: %s", what, m);
}

/* A loaded image has a sane size and finite grey levels within its bit depth. */
static inline void fuzz_check_image(const rpiv_image *im, const char *path)
{
    FUZZ_CHECK(im && im->px, "%s: OK without an image", path);
    FUZZ_CHECK(im->w >= 1 && im->h >= 1, "%s: size %dx%d", path, im->w, im->h);
    FUZZ_CHECK((uint64_t)im->w * (uint64_t)im->h <= ((uint64_t)1 << 31), "%s: %dx%d", path, im->w,
               im->h);
    FUZZ_CHECK((im->bits >= 1 && im->bits <= 16) || im->bits == 32, "%s: bits %d", path, im->bits);
    /* integer sources keep their levels: 0 .. 2^bits - 1 (luminance may round up a hair) */
    double top = im->bits <= 16 ? ldexp(1.0, im->bits) - 1.0 : (double)3.4e38f;
    size_t n = (size_t)im->w * (size_t)im->h;
    for (size_t i = 0; i < n; i++) {
        double v = (double)im->px[i];
        FUZZ_CHECK(isfinite(v), "%s: pixel %zu is %g", path, i, v);
        if (im->bits <= 16)
            FUZZ_CHECK(v >= 0 && v <= top * (1 + 1e-6), "%s: pixel %zu = %g outside 0..%g", path, i,
                       v, top);
    }
}

#endif /* RPIV_FUZZ_H */
