/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field_nc.c - NetCDF-4 vector fields and series. */
#include "field_impl.h"

rpiv_status field_save_nc(const rpiv_field *f, const rpiv_meta *meta, const char *path)
{
    (void)f, (void)meta;
    return rpiv_fail(RPIV_EINVAL, "%s: NetCDF output not implemented yet", path);
}
