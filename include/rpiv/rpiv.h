/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/rpiv.h - umbrella header: the whole public API of librpiv. */
#ifndef RPIV_RPIV_H
#define RPIV_RPIV_H

#include "rpiv/config.h"
#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/flow.h"
#include "rpiv/image.h"
#include "rpiv/imaging.h"
#include "rpiv/optics.h"
#include "rpiv/piv.h"
#include "rpiv/plot.h"
#include "rpiv/progress.h"
#include "rpiv/sheet.h"
#include "rpiv/synth.h"
#include "rpiv/version.h"

#endif /* RPIV_RPIV_H */
