/* SPDX-License-Identifier: GPL-3.0-or-later */
/* fuzz/fuzz.h - libFuzzer helpers: the readers take paths, so each input is written to a
 * per-process file in /dev/shm (or /tmp) first. */
#ifndef RPIV_FUZZ_H
#define RPIV_FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Write data to a scratch file named with suffix (e.g. ".ini"); returns its path. */
static inline const char *fuzz_file(const uint8_t *data, size_t size, const char *suffix)
{
    static char path[128];
    const char *dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    snprintf(path, sizeof path, "%s/rpiv-fuzz-%d%s", dir, (int)getpid(), suffix);
    FILE *fp = fopen(path, "wb");
    if (!fp)
        return NULL;
    if (size)
        fwrite(data, 1, size, fp);
    fclose(fp);
    return path;
}

#endif /* RPIV_FUZZ_H */
