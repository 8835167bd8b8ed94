/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/base/atomic.c - the one way librpiv and the rpiv program write a file: under a unique
 * temporary name in the target's folder, fsync'd, renamed over the target, the folder fsync'd.
 * A failure at any step removes the temporary file and leaves the old file intact. */
#include "atomic.h"
#include "hash.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* The temporary name of path: path.tmp-<pid>-<hex> when that fits in a file name (255 bytes),
 * else, for names of 224 bytes and more, the short .rpiv-<hash of the name>.tmp-<pid>-<hex>
 * in the same folder (issue 20 item 10: names of 240-255 bytes could not be written). */
#define TMP_SUFFIX_MAX 31 /* ".tmp-" + a 10-digit pid + "-" + 8 hex digits + 7 spare */
#define NAME_MAX_BYTES 255

static const char *base_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

static size_t short_prefix(const char *path, char *out, size_t cap)
{
    const char *base = base_of(path);
    return (size_t)snprintf(out, cap, "%.*s.rpiv-%016llx", (int)(base - path), path,
                            (unsigned long long)hash_bytes(HASH0, base, strlen(base)));
}

static void tmp_name(char *out, size_t cap, const char *path, long pid, unsigned long r)
{
    if (strlen(base_of(path)) + TMP_SUFFIX_MAX <= NAME_MAX_BYTES) {
        snprintf(out, cap, "%s.tmp-%ld-%08lx", path, pid, r);
        return;
    }
    size_t n = short_prefix(path, out, cap);
    if (n < cap)
        snprintf(out + n, cap - n, ".tmp-%ld-%08lx", pid, r);
}

rpiv_status atomic_begin(atomic_file *af, const char *path, int want_stream)
{
    memset(af, 0, sizeof *af);
    size_t len = strlen(path);
    af->path = strdup(path);
    af->tmp = malloc(len + 64);
    if (!af->path || !af->tmp) {
        free(af->path);
        free(af->tmp);
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    }
    /* O_EXCL makes the name ours; the suffix only has to make collisions unlikely. Unlike
     * mkstemp, open() applies the umask to 0666, so the result has the usual mode. */
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    unsigned long seed = (unsigned long)ts.tv_nsec ^ ((unsigned long)getpid() << 16);
    int fd = -1, err = 0;
    for (int attempt = 0; attempt < 100 && fd < 0; attempt++) {
        seed = seed * 6364136223846793005UL + 1442695040888963407UL;
        tmp_name(af->tmp, len + 64, path, (long)getpid(), (seed >> 32) & 0xfffffffful);
        fd = open(af->tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        err = errno;
        if (fd < 0 && err != EEXIST)
            break;
    }
    if (fd < 0) {
        free(af->path);
        free(af->tmp);
        return rpiv_fail(RPIV_EIO, "%s: cannot create a temporary file in its folder: %s", path,
                         strerror(err));
    }
    if (want_stream) {
        af->fp = fdopen(fd, "w");
        if (!af->fp) {
            err = errno;
            close(fd);
            unlink(af->tmp);
            free(af->path);
            free(af->tmp);
            return rpiv_fail(RPIV_EIO, "%s: cannot open a stream: %s", path, strerror(err));
        }
    } else {
        close(fd);
    }
    return RPIV_OK;
}

static void atomic_release(atomic_file *af)
{
    free(af->path);
    free(af->tmp);
    af->path = af->tmp = NULL;
    af->fp = NULL;
}

void atomic_abort(atomic_file *af)
{
    if (af->fp)
        fclose(af->fp);
    if (af->tmp)
        unlink(af->tmp);
    atomic_release(af);
}

/* fsync a file by name (NetCDF closes its own descriptor). */
static int fsync_path(const char *p, int dir)
{
    int fd = open(p, (dir ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
    if (fd < 0)
        return -1;
    int r = fsync(fd);
    /* some file systems refuse fsync on a directory; the rename is done, so ignore that */
    if (r != 0 && dir && (errno == EINVAL || errno == EBADF))
        r = 0;
    close(fd);
    return r;
}

rpiv_status atomic_commit(atomic_file *af)
{
    int err = 0;
    if (af->fp) {
        if (fflush(af->fp) != 0 || ferror(af->fp))
            err = errno ? errno : EIO;
        if (!err && fsync(fileno(af->fp)) != 0)
            err = errno;
        if (fclose(af->fp) != 0 && !err)
            err = errno ? errno : EIO;
        af->fp = NULL;
    } else if (fsync_path(af->tmp, 0) != 0) {
        err = errno;
    }
    if (!err && rename(af->tmp, af->path) != 0)
        err = errno;
    if (err) {
        rpiv_status st = rpiv_fail(RPIV_EIO, "%s: cannot write: %s", af->path, strerror(err));
        atomic_abort(af);
        return st;
    }
    /* make the rename durable: fsync the folder */
    char *dir = strdup(af->path);
    if (dir) {
        char *slash = strrchr(dir, '/');
        if (!slash)
            strcpy(dir, ".");
        else if (slash == dir)
            dir[1] = '\0';
        else
            *slash = '\0';
        (void)fsync_path(dir, 1);
        free(dir);
    }
    atomic_release(af);
    return RPIV_OK;
}

/* Remove the temporary files a killed run left next to path: path.tmp-<pid>-<hex> (what
 * atomic_begin names them), and path.tmp<pid> of earlier versions. */
void atomic_remove_stale(const char *path)
{
    char dir[4096], name[4096];
    const char *slash = strrchr(path, '/'), *base = slash ? slash + 1 : path;
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else
        snprintf(dir, sizeof dir, "%.*s", (int)(slash - path) + (slash == path), path);
    size_t nb = strlen(base);
    DIR *d = opendir(dir);
    if (!d)
        return;
    for (struct dirent *de; (de = readdir(d));)
        if (!strncmp(de->d_name, base, nb) && !strncmp(de->d_name + nb, ".tmp", 4) &&
            snprintf(name, sizeof name, "%s/%s", dir, de->d_name) < (int)sizeof name)
            remove(name);
    closedir(d);
    /* the short names of long ones */
    char prefix[4096];
    size_t np = short_prefix(path, prefix, sizeof prefix);
    if (np < sizeof prefix && (d = opendir(dir))) {
        const char *pb = base_of(prefix);
        size_t npb = strlen(pb);
        for (struct dirent *de; (de = readdir(d));)
            if (!strncmp(de->d_name, pb, npb) && !strncmp(de->d_name + npb, ".tmp", 4) &&
                snprintf(name, sizeof name, "%s/%s", dir, de->d_name) < (int)sizeof name)
                remove(name);
        closedir(d);
    }
}
