/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/report/fig_impl.h - what the figure files of the report module share (fig_*.c, demo*.c). */
#ifndef RPIV_SRC_FIG_IMPL_H
#define RPIV_SRC_FIG_IMPL_H

#include "rpiv/plot.h"

#include <stddef.h>

/* dir/name into buf of RPIV_PATH_MAX bytes; RPIV_EINVAL if too long. */
RPIV_NODISCARD rpiv_status fig_path(char *buf, const char *dir, const char *name);

/* Keep, in order at the front of s, the series that have a point with finite x and y (a line
 * plot refuses the others); returns how many. */
size_t fig_keep_finite(rpiv_plot_series *s, size_t n);

#endif /* RPIV_SRC_FIG_IMPL_H */
