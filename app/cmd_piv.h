/* SPDX-License-Identifier: GPL-3.0-or-later */
/* app/cmd_piv.h - rpiv piv's outputs (app/cmd_piv_out.c): the files' names, orientation and
 * metadata, and the sinks the batch hands each pair's field to. */
#ifndef RPIV_APP_CMD_PIV_H
#define RPIV_APP_CMD_PIV_H

#include "rpiv/batch.h"
#include "rpiv/field.h"
#include "rpiv/pairs.h"
#include "rpiv/piv.h"
#include "rpiv/report.h"

#include <stddef.h>

typedef struct run_ctx {
    const char *out;
    size_t npairs;
    int digits;
    int nc_series; /* several pairs into one .nc (rank 0)          */
    const rpiv_meta *meta;
    rpiv_field_series *series; /* .nc with several pairs (rank 0)              */
    rpiv_series_stats *stats;  /* --mean-rms (rank 0)                          */
    rpiv_field *first;         /* kept for --plot (rank 0)                     */
    size_t first_index;
    size_t nvec, nreplaced;
    int y_up, height; /* --y-up: files turned y-up for images `height` px high */
    unsigned derived; /* --derived: RPIV_DERIVE_* added to every field written     */
} run_ctx;

/* OUT with `tag` inserted before the extension (tag "_0001", "_mean"). */
rpiv_status cmdpiv_out_name(const char *out, const char *tag, char *buf, size_t n);
/* An interrupted .nc series: the fields done so far into OUT_partial.nc; RPIV_EINTR. */
rpiv_status cmdpiv_series_partial(rpiv_field_series *s, const char *out);
/* f as written: itself, or with --y-up or --derived a copy in *tmp (freed by the caller). */
rpiv_status cmdpiv_oriented(const run_ctx *r, const rpiv_field *f, rpiv_field **tmp,
                            const rpiv_field **out);
/* Save f as oriented; rms: f holds standard deviations, which keep their sign y-up. */
rpiv_status cmdpiv_save_as(const run_ctx *r, const rpiv_field *f, const rpiv_meta *meta,
                           const char *path, int rms);
rpiv_status cmdpiv_save(const run_ctx *r, const rpiv_field *f, const rpiv_meta *meta,
                        const char *path);
/* The batch's sinks (user: a run_ctx): pair i's own file on the rank that made it; on rank 0
 * every field in pair order (counts, the .nc series, statistics, the first). */
rpiv_status cmdpiv_local_sink(void *user, size_t i, const rpiv_field *f);
rpiv_status cmdpiv_root_sink(void *user, size_t i, const rpiv_field *f);
/* --skip-bad: say which pair is left out. */
void cmdpiv_warn_skip(void *user, size_t index, const char *msg);
/* The header's lines: the skipped pairs; the run's parameters and files. */
rpiv_status cmdpiv_add_skipped(rpiv_meta *m, const rpiv_batch *b, const rpiv_pairs *pairs);
rpiv_status cmdpiv_add_meta(rpiv_meta *m, const rpiv_piv_params *p, const rpiv_pairs *pairs,
                            const rpiv_piv *pv);

#endif
