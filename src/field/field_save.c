/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_save.c - saving a field in the format its file name's extension names,
 * atomically (base/atomic.h). A new output format is one row of `formats` and its writer. */
#include "field_impl.h"

#include <string.h>
#include <strings.h>

typedef rpiv_status (*stream_writer)(const rpiv_field *, const rpiv_meta *, FILE *, const char *);

static const struct {
    const char *ext; /* with its dot */
    rpiv_field_format format;
    stream_writer write; /* NULL: NetCDF, which writes by file name */
} formats[] = {
    {".txt", RPIV_FIELD_TXT, field_write_txt},
    {".nc", RPIV_FIELD_NC, NULL},
    {".dat", RPIV_FIELD_DAT, field_write_tecplot},
    {".vtk", RPIV_FIELD_VTK, field_write_vtk},
};
#define NFORMATS (sizeof formats / sizeof formats[0])

/* The extension of path's last component, with its dot, or "" (a leading dot is a hidden
 * file's name, not an extension). */
static const char *ext_of(const char *path)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    return dot && dot != base ? dot : "";
}

static size_t format_index(const char *ext)
{
    size_t k = 0;
    while (k < NFORMATS && strcasecmp(ext, formats[k].ext) != 0)
        k++;
    return k;
}

rpiv_field_format rpiv_field_format_of(const char *path, const char **ext)
{
    const char *e = ext_of(path);
    size_t k = format_index(e);
    if (ext)
        *ext = e;
    return k < NFORMATS ? formats[k].format : RPIV_FIELD_UNKNOWN;
}

rpiv_status rpiv_field_save(const rpiv_field *f, const rpiv_meta *meta, const char *path)
{
    const char *ext = ext_of(path);
    size_t k = format_index(ext);
    if (k == NFORMATS)
        return rpiv_fail(RPIV_EINVAL,
                         "%s: unknown vector file extension '%s' (use .txt, .nc, .dat or .vtk)",
                         path, ext);
    if (!formats[k].write)
        return field_save_nc(f, meta, path);
    atomic_file af;
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    st = formats[k].write(f, meta, af.fp, path);
    if (st) {
        atomic_abort(&af);
        return st;
    }
    return atomic_commit(&af);
}
