/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field_ascii.c - Tecplot ASCII and legacy VTK writers. */
#include "field_impl.h"

rpiv_status field_write_tecplot(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                const char *path)
{
    (void)f, (void)meta, (void)fp;
    return rpiv_fail(RPIV_EINVAL, "%s: Tecplot output not implemented yet", path);
}

rpiv_status field_write_vtk(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                            const char *path)
{
    (void)f, (void)meta, (void)fp;
    return rpiv_fail(RPIV_EINVAL, "%s: VTK output not implemented yet", path);
}
