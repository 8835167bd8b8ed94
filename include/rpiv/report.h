/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/report.h - the figures of the paper's models, written once for the rpiv commands and
 * the demo, and the small derived numbers they share.
 *
 * Each figure function composes one or more PNG files through plot.h from the result of a
 * model's library call (calib.h, ccm.h, optics.h, field.h, flow.h) and writes it into the
 * folder or path given; the file names are those the commands document (docs/rpiv.1). Like
 * plot.h, these functions are NOT thread-safe (PLplot is global state): one figure at a time
 * in a process. They return RPIV_OK, RPIV_ENOMEM, or the codes of rpiv_plot_lines /
 * rpiv_plot_map (RPIV_EINVAL, RPIV_EIO naming the file, RPIV_EFORMAT). Inputs are read during
 * the call only; nothing is printed. */
#ifndef RPIV_REPORT_H
#define RPIV_REPORT_H

#include "rpiv/calib.h"
#include "rpiv/ccm.h"
#include "rpiv/config.h"
#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/optics.h"
#include "rpiv/plot.h"

#include <stddef.h>
#include <stdio.h>

/* ---- files --------------------------------------------------------------------------------- */

/* A text file written by `write` (which prints obj onto fp and returns a status) under a
 * temporary name next to path, renamed over path when complete: a failure leaves the old
 * file intact. RPIV_EIO naming path, or write's status. */
typedef rpiv_status (*rpiv_report_writer)(const void *obj, FILE *fp);
RPIV_NODISCARD rpiv_status rpiv_report_write_file(const char *path, rpiv_report_writer write,
                                                  const void *obj);

/* ---- sheet profiles (calib, raytrace, demo) -------------------------------------------------- */

/* Profiles I0*(z*) the way the paper draws them: I0* across (x), z* up (y, 0..1), one line
 * per series (series[k].x = I0*, .y = z*). xmax > 0 fixes the I0* axis to 0..xmax (room on
 * the right for the legend); xmax <= 0 leaves it to the data. */
RPIV_NODISCARD rpiv_status rpiv_report_sheet_profiles(const char *path, const char *title,
                                                      const char *xlabel,
                                                      const rpiv_plot_series *series, size_t n,
                                                      double xmax);

/* Index of the s-th of ns items picked evenly from n (the first and the last included). */
size_t rpiv_report_pick(size_t s, size_t ns, size_t n);

/* ---- calib (calib.h) ------------------------------------------------------------------------ */

/* DIR/calib_sheet_profiles.png (at most 12 plates' I0*(z*)), DIR/calib_sheet_shape.png (the
 * plates in z+ and the mean shape), DIR/calib_sheet_edges.png (z*_inf, z*_max, z*_sup along
 * x* with the fitted lines). */
RPIV_NODISCARD rpiv_status rpiv_report_calib_sheet(const rpiv_calib_sheet_result *r,
                                                   const char *dir);
/* DIR/calib_dof.png: the measured focus curve, its local fit and (model not NULL) the
 * imaging model's curve shifted by shift in z*. */
RPIV_NODISCARD rpiv_status rpiv_report_calib_dof(const rpiv_calib_focus *c,
                                                 const rpiv_calib_focus *model, double shift,
                                                 const char *dir);
/* DIR/calib_sheet_plates.txt and DIR/calib_sheet_profiles.txt (rpiv_calib_sheet_write_*). */
RPIV_NODISCARD rpiv_status rpiv_report_calib_sheet_tables(const rpiv_calib_sheet_result *r,
                                                          const char *dir);
/* DIR/calib_dof_curve.txt, DIR/calib_dof_dots.txt and (model not NULL)
 * DIR/calib_dof_model.txt. */
RPIV_NODISCARD rpiv_status rpiv_report_calib_dof_tables(const rpiv_calib_dof_result *r,
                                                        const rpiv_calib_focus *model,
                                                        const char *dir);

/* ---- ccm (ccm.h) ---------------------------------------------------------------------------- */

/* The paper's figures 19-22 for the scenario `name`: DIR/ccm_<name>_profile.png (the reference
 * and each table's model profile) and DIR/ccm_<name>_error.png (the pointwise relative error).
 * e_star[k] labels table k (P-PIV thicknesses); NULL: one R-PIV table. */
RPIV_NODISCARD rpiv_status rpiv_report_ccm_tables(const char *dir, const char *name,
                                                  rpiv_ccm_table *const *t, const double *e_star,
                                                  size_t nt);
/* DIR/ccm_convergence.png: the Monte-Carlo mean +- std against log10 N_im, and the integral
 * prediction dx_integral (px); U* = px / scale_px. */
RPIV_NODISCARD rpiv_status rpiv_report_ccm_convergence(const char *dir,
                                                       const rpiv_ccm_mc_result *res,
                                                       double scale_px, double dx_integral);
/* DIR/ccm_invert.png: the measurements at z*_max, the corrected profile +- 2 sigma and
 * (ref not NULL) the reference profile. */
RPIV_NODISCARD rpiv_status rpiv_report_ccm_invert(const char *dir,
                                                  const rpiv_ccm_invert_result *res,
                                                  const rpiv_ccm_func *ref);

/* ---- optics (optics.h) ---------------------------------------------------------------------- */

/* DIR/raytrace_profile.png: station 0 of r as I0*(z*). */
RPIV_NODISCARD rpiv_status rpiv_report_optics_profile(const rpiv_optics_result *r, const char *dir);
/* DIR/raytrace_metrics.png: z*_inf, z*_max, z*_sup and e* along x* (paper fig 8) and, fit not
 * NULL, the fitted z*_max line. */
RPIV_NODISCARD rpiv_status rpiv_report_optics_metrics_plot(const rpiv_optics_result *r,
                                                           const rpiv_optics_selfsim *fit,
                                                           const char *dir);
/* DIR/raytrace_map.png: the sheet's fluence rate normalised at each x* over (x*, z*), traced
 * again at 200 stations from x* = -0.5 to x_last (9 if x_last <= 1). */
RPIV_NODISCARD rpiv_status rpiv_report_optics_map(const rpiv_laser *laser, const rpiv_prism *prism,
                                                  double h_m, double x_last,
                                                  const rpiv_optics_opts *o, const char *dir);
/* DIR/raytrace_sweep_profiles.png (at most 12 of the n profiles prof[i * nz + q], bins of
 * 1/nz in z*) and DIR/raytrace_sweep.png (It/Ig, I*_peak and e* against beta1) at x* = x. */
RPIV_NODISCARD rpiv_status rpiv_report_optics_sweep(const rpiv_optics_sweep_row *rows, size_t n,
                                                    const double *prof, size_t nz, double x,
                                                    const char *dir);
/* DIR/raytrace_sensitivity.png: the one-ray sensitivity at beta1 (paper fig 10). */
RPIV_NODISCARD rpiv_status rpiv_report_optics_sensitivity(const rpiv_optics_sens_row *rows,
                                                          size_t n, double beta1, const char *dir);

/* ---- flow and comparisons (flow.h, field.h) -------------------------------------------------- */

/* The square-duct profile U*(y*, z*) at the n abscissae al (along y* at z* = fixed when
 * along_y, else along z* at y* = fixed) printed onto fp as the two-column profile file of
 * `rpiv duct`, and plotted into png unless NULL. RPIV_EIO if fp cannot be written. */
RPIV_NODISCARD rpiv_status rpiv_report_duct(FILE *fp, const double *al, size_t n, int along_y,
                                            double fixed, const char *png);
/* Both profiles of a comparison r (labels: their file names) into png. */
RPIV_NODISCARD rpiv_status rpiv_report_compare_profiles(const char *png, const rpiv_profile *ref,
                                                        const rpiv_profile *cmp,
                                                        const char *ref_name, const char *cmp_name,
                                                        const rpiv_compare *r);
/* The map of REF - CMP (component c, named cname) of two fields on one grid into png; points
 * masked in either field are blank. */
RPIV_NODISCARD rpiv_status rpiv_report_compare_fields(const char *png, const rpiv_field *ref,
                                                      const rpiv_field *cmp, rpiv_component c,
                                                      const char *cname, const rpiv_compare *r);

#endif /* RPIV_REPORT_H */
