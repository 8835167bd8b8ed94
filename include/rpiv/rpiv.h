/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/rpiv.h - umbrella header: the whole public API of librpiv. */
#ifndef RPIV_RPIV_H
#define RPIV_RPIV_H

#include "rpiv/batch.h"
#include "rpiv/calib.h"
#include "rpiv/ccm.h"
#include "rpiv/config.h"
#include "rpiv/deform.h"
#include "rpiv/demo.h"
#include "rpiv/ensemble.h"
#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/flow.h"
#include "rpiv/image.h"
#include "rpiv/imaging.h"
#include "rpiv/mpi.h"
#include "rpiv/optics.h"
#include "rpiv/peak.h"
#include "rpiv/piv.h"
#include "rpiv/plot.h"
#include "rpiv/progress.h"
#include "rpiv/sheet.h"
#include "rpiv/synth.h"
#include "rpiv/validate.h"
#include "rpiv/version.h"
#include "rpiv/xcorr.h"

#endif /* RPIV_RPIV_H */
