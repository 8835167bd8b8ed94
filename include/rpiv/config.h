/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/config.h - the experiment: every parameter of every module, read from an INI file
 * (rpiv's own reader over text_getline: no line-length limit) with strict keys, printed back as a
 * complete INI file.
 *
 * One table drives parsing, checking, --help and docs/config.md: each key has a section, a
 * name, a type, a unit, a range, a default (from the modules' *_default()) and a help line. */
#ifndef RPIV_CONFIG_H
#define RPIV_CONFIG_H

#include "rpiv/ccm.h"
#include "rpiv/error.h"
#include "rpiv/flow.h"
#include "rpiv/imaging.h"
#include "rpiv/optics.h"
#include "rpiv/piv.h"
#include "rpiv/sheet.h"
#include "rpiv/synth.h"

#include <stddef.h>
#include <stdio.h>

typedef struct rpiv_output_params {
    char dir[RPIV_PATH_MAX]; /* output folder ("rpiv-out")                 */
    int plots;               /* 1: write PNG plots (1)                     */
} rpiv_output_params;

typedef struct rpiv_experiment {
    rpiv_camera camera;
    rpiv_particles particles;
    rpiv_channel channel;
    rpiv_laser laser;
    rpiv_prism prism;
    rpiv_sheet_params sheet;
    rpiv_piv_params piv;
    rpiv_synth_params synth;
    rpiv_output_params output;
    rpiv_ccm_bias_params bias; /* [bias]: rpiv piv --sheet-bias */
} rpiv_experiment;

/* The embedded default: the paper's channel experiment (docs/config.md). */
rpiv_experiment rpiv_experiment_default(void);

/* Check every module's parameters (the message names section.key and the range). */
RPIV_NODISCARD rpiv_status rpiv_experiment_check(const rpiv_experiment *e);

/* Read an INI file over *e (keys not in the file keep their value). Unknown sections or keys,
 * unparsable or out-of-range values: RPIV_ECONFIG with "file:line: ..." naming the key and the
 * accepted range. Missing file: RPIV_EIO. */
RPIV_NODISCARD rpiv_status rpiv_config_load(const char *path, rpiv_experiment *e);

/* Set one key from a "section.key=value" or (section, key, value) string, as a command-line
 * override; `origin` names where it came from in messages (e.g. "--set"). */
RPIV_NODISCARD rpiv_status rpiv_config_set(rpiv_experiment *e, const char *section, const char *key,
                                           const char *value, const char *origin);

/* Write *e as a complete INI file, every key with its unit and help as a comment. */
RPIV_NODISCARD rpiv_status rpiv_config_write(const rpiv_experiment *e, FILE *fp);

/* Write the key reference as a Markdown table (docs/config.md). */
RPIV_NODISCARD rpiv_status rpiv_config_write_doc(FILE *fp);

/* ---- the experiment mapped onto the modules' parameters ---------------------------------- */

/* The synthetic-image generator's setup: the experiment's camera, particles, channel, sheet
 * and synth sections. */
rpiv_synth_setup rpiv_config_synth_setup(const rpiv_experiment *e);

/* rpiv_synth_new on rpiv_config_synth_setup(e). */
RPIV_NODISCARD rpiv_status rpiv_config_synth_new(const rpiv_experiment *e, const rpiv_flow *flow,
                                                 rpiv_synth **out);

/* Write the parameters of generator s, made from e: the complete experiment as INI (readable
 * with --config) and, as comments, the derived figures of rpiv_synth_info. Written
 * atomically. RPIV_EIO. */
RPIV_NODISCARD rpiv_status rpiv_config_save_synth(const rpiv_experiment *e, const rpiv_synth *s,
                                                  const char *path);

/* The CCM model of the experiment's camera, particles and channel (h, d_p, and scale_px, the
 * bulk displacement U_b dt M / pixel of dt_s); I0, U*, P stay the defaults. */
rpiv_ccm_model rpiv_config_ccm_model(const rpiv_experiment *e, double dt_s);

/* Measured R-PIV velocities for the inversion (rpiv ccm invert) from path: a vector file of
 * rpiv piv ("# rpiv vector field" first line), read along the row at y* = ystar with the image
 * placed as rpiv synth places it for experiment e, U* = px / scale_px; otherwise rows
 * "x* U* [sigma]" (rpiv_ccm_curve_load). The caller frees *out. Errors of the loaders. */
RPIV_NODISCARD rpiv_status rpiv_config_ccm_measurements(const rpiv_experiment *e, const char *path,
                                                        double scale_px, double ystar,
                                                        rpiv_ccm_curve **out);

/* The sheet's bias for every vector of f (rpiv_ccm_bias_field, docs/bias.md), with the
 * experiment's camera, particles, channel, [sheet] and [bias], f placed in the channel as
 * rpiv synth places its images, P(z*) from [synth] pz_profile, the displacement scale of
 * [piv] dt_s (unset: [synth] dt_s). f in image coordinates. npairs: the image pairs of f's
 * correlation planes (an ensemble's count; 1 for a single pair or a mean of instantaneous
 * fields), the noise of the modelled window's plane where [bias] window_pairs is 0. Errors:
 * those of the checks, the file readers and rpiv_ccm_bias_field. */
RPIV_NODISCARD rpiv_status rpiv_config_sheet_bias(const rpiv_experiment *e, rpiv_field *f,
                                                  size_t npairs, int threads,
                                                  const rpiv_progress *progress);

/* ---- flat entry points for bindings (the Python package, ctypes) --------------------------- */

/* The library's version, RPIV_VERSION_STRING of the build ("0.1.0"). */
const char *rpiv_version_string(void);

/* A default experiment (rpiv_experiment_default) on the heap, so that a binding need not know
 * its layout: set keys with rpiv_config_set, release with rpiv_experiment_free. RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status rpiv_experiment_new(rpiv_experiment **out);
void rpiv_experiment_free(rpiv_experiment *e); /* NULL is a no-op */
/* Its [piv] section, for rpiv_piv_new. */
rpiv_piv_params *rpiv_experiment_piv(rpiv_experiment *e);

/* The sheet of the experiment's [laser], [prism] and channel height traced at the stations
 * xstar[0..nx-1] (rpiv_optics_trace, as `rpiv raytrace` does). Errors: RPIV_EINVAL (a section
 * or o out of range, no station), those of rpiv_optics_trace. */
RPIV_NODISCARD rpiv_status rpiv_config_raytrace(const rpiv_experiment *e, const double *xstar,
                                                size_t nx, const rpiv_optics_opts *o,
                                                const rpiv_progress *progress,
                                                rpiv_optics_result **out);

/* The displacement Eq. "statform" predicts for one R-PIV window of the experiment (as `rpiv ccm
 * convergence` computes its integral value): the model of rpiv_config_ccm_model(e, dt_s;
 * dt_s <= 0: [synth] dt_s), lit by the [sheet] at section xstar, the duct's U*(z*) at y* =
 * ystar, the object plane zop_star (< 0: the camera's), P(z*) from [synth] pz_profile, the
 * peak fit of [piv] subpixel. *out is the peak in px; *scale_px (may be NULL) the px per unit
 * U*. Errors: those of the parameters' checks, the profile reader and rpiv_ccm_predict. */
RPIV_NODISCARD rpiv_status rpiv_config_ccm_predict(const rpiv_experiment *e, double dt_s,
                                                   double xstar, double ystar, double zop_star,
                                                   rpiv_ccm_peak *out, double *scale_px);

#endif /* RPIV_CONFIG_H */
