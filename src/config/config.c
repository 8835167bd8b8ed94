/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The experiment's key table drives the INI reader, the writer and the key reference. */
#include "rpiv/config.h"

#include "base/text.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

typedef enum {
    KEY_INT,
    KEY_LONG,
    KEY_ULONG,
    KEY_DOUBLE,
    KEY_BOOL,
    KEY_STRING,
    KEY_ENUM,
    KEY_WINDOWS, /* piv windows: "64,32,32" or "64x48,32"; also sets npass */
    KEY_ROI      /* four integers x0,y0,x1,y1 */
} key_type;

typedef struct key_spec {
    const char *section, *key;
    key_type type;
    size_t off;
    double min, max;  /* in file units */
    double scale;     /* struct value = file value * scale (e.g. mm -> m: 1e-3) */
    const char *unit; /* unit in the file */
    const char *help;
    const char *const *names; /* KEY_ENUM: names in enum order, NULL-terminated */
} key_spec;

#define OFF(m) offsetof(rpiv_experiment, m)

static const key_spec keys[] = {
    /* [camera] */
    {"camera", "width_px", KEY_INT, OFF(camera.width_px), 8, 65536, 1, "px", "sensor width", 0},
    {"camera", "height_px", KEY_INT, OFF(camera.height_px), 8, 65536, 1, "px", "sensor height", 0},
    {"camera", "sensor_w_mm", KEY_DOUBLE, OFF(camera.sensor_w_m), 0.1, 1000, 1e-3, "mm",
     "sensor width (pixel pitch = sensor_w_mm / width_px)", 0},
    {"camera", "sensor_h_mm", KEY_DOUBLE, OFF(camera.sensor_h_m), 0.1, 1000, 1e-3, "mm",
     "sensor height", 0},
    {"camera", "focal_mm", KEY_DOUBLE, OFF(camera.focal_m), 1, 10000, 1e-3, "mm",
     "lens focal length f", 0},
    {"camera", "fnumber", KEY_DOUBLE, OFF(camera.fnumber), 0.5, 128, 1, "-", "aperture number f#",
     0},
    {"camera", "magnification", KEY_DOUBLE, OFF(camera.magnification), 0.001, 100, 1, "-",
     "magnification M", 0},
    {"camera", "working_distance_mm", KEY_DOUBLE, OFF(camera.s0_m), 1, 100000, 1e-3, "mm",
     "distance s0 from the camera to the object plane", 0},
    {"camera", "zop", KEY_DOUBLE, OFF(camera.zop_star), -10, 10, 1, "h",
     "object plane height z*_OP", 0},
    {"camera", "lambda_nm", KEY_DOUBLE, OFF(camera.lambda_p_m), 100, 2000, 1e-9, "nm",
     "wavelength of the light recorded (fluorescence)", 0},
    {"camera", "beta2", KEY_DOUBLE, OFF(camera.beta2), 0.1, 100, 1, "-",
     "beta^2 of the Gaussian approximation of the Airy disc (Olsen & Adrian)", 0},
    {"camera", "n_medium", KEY_DOUBLE, OFF(camera.n_medium), 1, 4, 1, "-",
     "index of the fluid seen through a flat wall: defocus at the apparent depth (1 = paper)", 0},
    /* [particles] */
    {"particles", "diameter_um", KEY_DOUBLE, OFF(particles.dp_m), 0.01, 10000, 1e-6, "um",
     "mean particle diameter d_p", 0},
    {"particles", "diameter_spread_um", KEY_DOUBLE, OFF(particles.dp_sigma_m), 0, 10000, 1e-6, "um",
     "half-range of the uniform diameter distribution (d_p +- spread)", 0},
    {"particles", "density_ppp", KEY_DOUBLE, OFF(particles.density_ppp), 0, 1, 1, "1/px",
     "particle images per pixel (all heights)", 0},
    /* [channel] */
    {"channel", "height_mm", KEY_DOUBLE, OFF(channel.h_m), 0.01, 10000, 1e-3, "mm",
     "side h of the square duct", 0},
    {"channel", "reynolds", KEY_DOUBLE, OFF(channel.reynolds), 0, 1e6, 1, "-",
     "Reynolds number on the bulk velocity and h", 0},
    {"channel", "nu_m2s", KEY_DOUBLE, OFF(channel.nu_m2s), 1e-9, 1, 1, "m^2/s",
     "kinematic viscosity", 0},
    {"channel", "x0", KEY_DOUBLE, OFF(channel.x0_star), 0, 1000, 1, "h",
     "distance from the sheet's emerging point (x* = 0) to the channel end", 0},
    {"channel", "fov_x0", KEY_DOUBLE, OFF(channel.fov_x0_star), -1000, 1000, 1, "h",
     "x* of the left image edge", 0},
    {"channel", "fov_y0", KEY_DOUBLE, OFF(channel.fov_y0_star), -1000, 1000, 1, "h",
     "y* of the top image edge", 0},
    /* [laser] */
    {"laser", "lambda_nm", KEY_DOUBLE, OFF(laser.lambda_m), 100, 2000, 1e-9, "nm",
     "laser wavelength", 0},
    {"laser", "beam_diameter_mm", KEY_DOUBLE, OFF(laser.beam_d_m), 0.01, 1000, 1e-3, "mm",
     "beam diameter at 1/e^2 at the laser output", 0},
    {"laser", "expander", KEY_DOUBLE, OFF(laser.expander), 0.01, 100, 1, "-",
     "beam expander factor", 0},
    {"laser", "divergence_mrad", KEY_DOUBLE, OFF(laser.divergence_rad), 0, 500, 1e-3, "mrad",
     "full divergence angle of the beam", 0},
    {"laser", "lens_focal_mm", KEY_DOUBLE, OFF(laser.lens_f_m), 1, 100000, 1e-3, "mm",
     "spherical converging lens focal length", 0},
    {"laser", "lens_distance_mm", KEY_DOUBLE, OFF(laser.lens_dist_m), 0, 100000, 1e-3, "mm",
     "lens to the prism's inclined face", 0},
    {"laser", "beta1_deg", KEY_DOUBLE, OFF(laser.beta1_deg), -45, 45, 1, "deg",
     "beam axis deviation from the inclined face's normal, towards the vertical", 0},
    {"laser", "beta1_side", KEY_ENUM, OFF(laser.beta1_side), 0, 0, 1, "-",
     "side of the face beta1 is measured on: air (incidence) or pmma (inside)",
     rpiv_beta1_side_names},
    {"laser", "bundle_mm", KEY_DOUBLE, OFF(laser.bundle_m), 0.01, 1000, 1e-3, "mm",
     "full width of the equally spaced ray bundle at the lens", 0},
    {"laser", "rays", KEY_LONG, OFF(laser.nrays), 1, 1e8, 1, "-", "number of rays traced", 0},
    {"laser", "polarisation", KEY_ENUM, OFF(laser.polar), 0, 0, 1, "-",
     "Fresnel transmission: p (paper), s or unpolarised", rpiv_polar_names},
    /* [prism] */
    {"prism", "inclination_deg", KEY_DOUBLE, OFF(prism.theta_p_deg), 1, 89, 1, "deg",
     "inclination theta_p of the inclined face", 0},
    {"prism", "thickness_mm", KEY_DOUBLE, OFF(prism.thickness_m), 0.1, 10000, 1e-3, "mm",
     "block thickness: beam entry point to floor along the face normal", 0},
    {"prism", "n_pmma", KEY_DOUBLE, OFF(prism.n_pmma), 1, 4, 1, "-", "refractive index of PMMA", 0},
    {"prism", "n_water", KEY_DOUBLE, OFF(prism.n_water), 1, 4, 1, "-",
     "refractive index of the fluid", 0},
    {"prism", "n_air", KEY_DOUBLE, OFF(prism.n_air), 1, 4, 1, "-", "refractive index of air", 0},
    /* [sheet] */
    {"sheet", "kind", KEY_ENUM, OFF(sheet.kind), 0, 0, 1, "-",
     "gauss (P-PIV), selfsim (R-PIV) or uniform (volume)", rpiv_sheet_kind_names},
    {"sheet", "zb", KEY_DOUBLE, OFF(sheet.zb_star), -10, 10, 1, "h", "gauss: centre z*_B", 0},
    {"sheet", "thickness", KEY_DOUBLE, OFF(sheet.e_star), 1e-4, 100, 1, "h",
     "gauss: thickness e* at a quarter of the maximum", 0},
    {"sheet", "e0", KEY_DOUBLE, OFF(sheet.e0), -100, 100, 1, "h", "selfsim: e*(x*) = e0 + e1 x*",
     0},
    {"sheet", "e1", KEY_DOUBLE, OFF(sheet.e1), -10, 10, 1, "-", "selfsim: thickness growth", 0},
    {"sheet", "zm0", KEY_DOUBLE, OFF(sheet.zm0), -10, 10, 1, "h",
     "selfsim: z*_max(x*) = zm0 + zm1 x*", 0},
    {"sheet", "zm1", KEY_DOUBLE, OFF(sheet.zm1), -10, 10, 1, "-",
     "selfsim: slope of the sheet's peak", 0},
    {"sheet", "skew", KEY_DOUBLE, OFF(sheet.skew), 0.05, 20, 1, "-",
     "selfsim default shape: lower/upper half-width ratio", 0},
    {"sheet", "profile", KEY_STRING, OFF(sheet.profile), 0, 0, 1, "path",
     "selfsim: shape table from rpiv raytrace or rpiv calib (empty = default shape)", 0},
    /* [piv] */
    {"piv", "windows", KEY_WINDOWS, OFF(piv), 0, 0, 1, "px",
     "window size per pass, e.g. 64,32,32 or 64x48,32", 0},
    {"piv", "overlap", KEY_DOUBLE, OFF(piv.overlap), 0, 0.95, 1, "-", "window overlap fraction", 0},
    {"piv", "step_px", KEY_INT, OFF(piv.step_px), 0, 1024, 1, "px", "grid step (0 = from overlap)",
     0},
    {"piv", "ensemble", KEY_BOOL, OFF(piv.ensemble), 0, 1, 1, "-",
     "sum of correlation over all pairs", 0},
    {"piv", "subpixel", KEY_ENUM, OFF(piv.subpixel), 0, 0, 1, "-",
     "peak fit: gauss, parabola, centroid, spline or auto (spline for ensembles, else gauss)",
     rpiv_subpixel_names},
    {"piv", "median_threshold", KEY_DOUBLE, OFF(piv.median_thr), 0, 100, 1, "-",
     "normalised median test threshold (0 = off)", 0},
    {"piv", "median_eps_px", KEY_DOUBLE, OFF(piv.median_eps), 0, 10, 1, "px",
     "normalised median test epsilon", 0},
    {"piv", "median_lines", KEY_BOOL, OFF(piv.median_lines), 0, 1, 1, "-",
     "keep a vector that fails the median test but agrees with a grid line (shear layers)", 0},
    {"piv", "search_radius_px", KEY_INT, OFF(piv.search_radius), -1, 2048, 1, "px",
     "passes with a predictor: peak searched within this radius of it (0 = whole plane, -1 = "
     "the previous pass's window / 8, at least 2)",
     0},
    {"piv", "cbc", KEY_INT, OFF(piv.cbc), 0, 2, 1, "-",
     "correlation-based correction: each window's peak chosen on its correlation combined with "
     "its 4 neighbours' (0 off, 1 product, 2 sum)",
     0},
    {"piv", "peak_ratio_min", KEY_DOUBLE, OFF(piv.peak_ratio_min), 0, 100, 1, "-",
     "reject vectors whose correlation peak ratio is below this (0 = off)", 0},
    {"piv", "u_min_px", KEY_DOUBLE, OFF(piv.u_min_px), -1e6, 1e6, 1, "px",
     "global limits: reject u < u_min_px (u off while u_min_px >= u_max_px)", 0},
    {"piv", "u_max_px", KEY_DOUBLE, OFF(piv.u_max_px), -1e6, 1e6, 1, "px",
     "global limits: reject u > u_max_px", 0},
    {"piv", "v_min_px", KEY_DOUBLE, OFF(piv.v_min_px), -1e6, 1e6, 1, "px",
     "global limits: reject v < v_min_px, image coordinates (v off while min >= max)", 0},
    {"piv", "v_max_px", KEY_DOUBLE, OFF(piv.v_max_px), -1e6, 1e6, 1, "px",
     "global limits: reject v > v_max_px", 0},
    {"piv", "std_k", KEY_DOUBLE, OFF(piv.std_k), 0, 100, 1, "-",
     "reject vectors farther than std_k standard deviations from the mean (0 = off)", 0},
    {"piv", "replace", KEY_ENUM, OFF(piv.replace), 0, 0, 1, "-",
     "replacement of rejected vectors: median (3x3) or inpaint (Laplace, fills large gaps)",
     rpiv_replace_names},
    {"piv", "smooth", KEY_DOUBLE, OFF(piv.smooth), 0, 1e6, 1, "-",
     "penalised least-squares smoothing of the final field (0 = off)", 0},
    {"piv", "refine_max", KEY_INT, OFF(piv.refine_max), 0, 20, 1, "-",
     "repeats of the last pass until the field converges", 0},
    {"piv", "ensemble_refine", KEY_INT, OFF(piv.ensemble_refine), 0, 20, 1, "-",
     "ensembles: repeats of the final pass while the field changes (0 = the listed passes)", 0},
    {"piv", "ensemble_refine_tol_px", KEY_DOUBLE, OFF(piv.ensemble_refine_tol_px), 0, 10, 1, "px",
     "ensembles: converged when the RMS change between two final passes is below this", 0},
    {"piv", "ensemble_denoise", KEY_BOOL, OFF(piv.ensemble_denoise), 0, 1, 1, "-",
     "ensembles: denoise the final size's predictor (0: notch it only)", 0},
    {"piv", "refine_tol_px", KEY_DOUBLE, OFF(piv.refine_tol_px), 0, 10, 1, "px",
     "refinement converged: RMS change between iterations below this", 0},
    {"piv", "refine_filter", KEY_DOUBLE, OFF(piv.refine_filter), 0, 0.5, 1, "-",
     "refinement: predictor low-pass weight a of [a/2, 1-a, a/2]", 0},
    {"piv", "refine_denoise", KEY_BOOL, OFF(piv.refine_denoise), 0, 1, 1, "-",
     "refinement: shrink the predictor's detail, threshold from its own noise level", 0},
    {"piv", "refine_denoise_order", KEY_INT, OFF(piv.refine_denoise_order), 2, 4, 1, "-",
     "refinement denoiser's finest detail: 4 fourth difference, 2 second (before session 13)", 0},
    {"piv", "refine_notch", KEY_INT, OFF(piv.refine_notch), 0, 8, 1, "-",
     "refinement: order of the denoised predictor's notch of its grid's Nyquist mode, 0 off "
     "(before session 14)",
     0},
    {"piv", "refine_stop", KEY_BOOL, OFF(piv.refine_stop), 0, 1, 1, "-",
     "refinement: stop when the change stops falling (keep the field of the smallest change)", 0},
    {"piv", "refine_defer", KEY_BOOL, OFF(piv.refine_defer), 0, 1, 1, "-",
     "refinement: median test on the converged field only, not between repeats", 0},
    {"piv", "edge_curvature", KEY_INT, OFF(piv.edge_curvature), -1, 1, 1, "-",
     "predictor beyond the grid's edge: 0 linear, 1 with its curvature, -1 ensembles only", 0},
    {"piv", "spline_check", KEY_BOOL, OFF(piv.spline_check), 0, 1, 1, "-",
     "ensembles: spline corrections unlike the neighbours' replaced by the Gaussian's + theirs", 0},
    {"piv", "uncertainty", KEY_BOOL, OFF(piv.uncertainty), 0, 1, 1, "-",
     "add sigma_u, sigma_v per vector (correlation statistics; docs/uncertainty.md)", 0},
    {"piv", "background", KEY_ENUM, OFF(piv.background), 0, 0, 1, "-",
     "subtract the series' min or mean image, or none", rpiv_background_names},
    {"piv", "roi", KEY_ROI, OFF(piv.roi), 0, 65536, 1, "px",
     "region of interest x0,y0,x1,y1 (0,0,0,0 = whole image)", 0},
    {"piv", "mask", KEY_STRING, OFF(piv.mask), 0, 0, 1, "path", "mask image, 0 = masked", 0},
    {"piv", "threads", KEY_INT, OFF(piv.threads), 0, 1024, 1, "-", "threads (0 = all cores)", 0},
    {"piv", "scale_mm_per_px", KEY_DOUBLE, OFF(piv.scale_mm_per_px), 0, 1e6, 1, "mm/px",
     "physical scale for mm and m/s columns (0 = unset)", 0},
    {"piv", "dt_s", KEY_DOUBLE, OFF(piv.dt_s), 0, 1e6, 1, "s",
     "pulse separation for m/s columns (0 = unset)", 0},
    {"piv", "deform", KEY_BOOL, OFF(piv.deform), 0, 1, 1, "-",
     "deform the images by the predictor between passes", 0},
    {"piv", "y_up", KEY_BOOL, OFF(piv.y_up), 0, 1, 1, "-",
     "output files with origin bottom-left, y and v up (0 = image coordinates)", 0},
    {"piv", "max_mem_mb", KEY_DOUBLE, OFF(piv.max_mem_mb), 1, 1e9, 1, "MB",
     "refuse runs that would need more memory", 0},
    /* [preprocess] */
    {"preprocess", "ops", KEY_STRING, OFF(piv.prep.ops), 0, RPIV_PREPROCESS_LIST_MAX, 1, "list",
     "image preprocessing of both frames, in order: clahe[:TILE], highpass[:SIZE], cap, "
     "normalize[:SIZE], invert (\"\" = none)",
     0},
    {"preprocess", "clahe_tile_px", KEY_INT, OFF(piv.prep.clahe_tile_px), 3, 1024, 1, "px",
     "CLAHE tile side", 0},
    {"preprocess", "clahe_clip", KEY_DOUBLE, OFF(piv.prep.clahe_clip), 0, 1, 1, "-",
     "CLAHE clip limit, 0 (uniform histogram) .. 1 (no limit)", 0},
    {"preprocess", "clahe_bins", KEY_INT, OFF(piv.prep.clahe_bins), 16, 65536, 1, "-",
     "CLAHE histogram bins", 0},
    {"preprocess", "clahe_low_pct", KEY_DOUBLE, OFF(piv.prep.clahe_low_pct), 0, 100, 1, "%",
     "CLAHE bins from this percentile of the frame (below: the first bin)", 0},
    {"preprocess", "clahe_high_pct", KEY_DOUBLE, OFF(piv.prep.clahe_high_pct), 0, 100, 1, "%",
     "CLAHE bins up to this percentile (above: the last bin); 0 and 100: min and max", 0},
    {"preprocess", "highpass_px", KEY_INT, OFF(piv.prep.highpass_px), 3, 1024, 1, "px",
     "high-pass background window", 0},
    {"preprocess", "highpass_method", KEY_ENUM, OFF(piv.prep.highpass_method), 0, 0, 1, "-",
     "background: min (sliding minimum, smoothed) or blur (Gaussian, sigma = size / 4)",
     rpiv_prep_background_names},
    {"preprocess", "cap_k", KEY_DOUBLE, OFF(piv.prep.cap_k), 0.1, 100, 1, "-",
     "intensity capping at mean + cap_k std", 0},
    {"preprocess", "normalize_px", KEY_INT, OFF(piv.prep.normalize_px), 3, 1024, 1, "px",
     "local min/max normalisation window", 0},
    /* [synth] */
    {"synth", "width_px", KEY_INT, OFF(synth.width_px), 0, 65536, 1, "px",
     "image width (0 = camera sensor)", 0},
    {"synth", "height_px", KEY_INT, OFF(synth.height_px), 0, 65536, 1, "px",
     "image height (0 = camera sensor)", 0},
    {"synth", "pairs", KEY_INT, OFF(synth.pairs), 1, 1e7, 1, "-", "number of image pairs", 0},
    {"synth", "seed", KEY_ULONG, OFF(synth.seed), 0, 4294967295.0, 1, "-", "random seed", 0},
    {"synth", "dt_s", KEY_DOUBLE, OFF(synth.dt_s), 1e-9, 100, 1, "s", "pulse separation", 0},
    {"synth", "bits", KEY_INT, OFF(synth.bits), 8, 16, 1, "bit", "bit depth: 8, 12 or 16", 0},
    {"synth", "peak_counts", KEY_DOUBLE, OFF(synth.peak_counts), 1e-6, 1e9, 1, "counts",
     "peak of the Gaussian image of an in-focus particle of mean d_p at I0 = 1", 0},
    {"synth", "background", KEY_DOUBLE, OFF(synth.background), 0, 1e9, 1, "counts",
     "constant background", 0},
    {"synth", "read_noise", KEY_DOUBLE, OFF(synth.read_noise), 0, 1e9, 1, "counts",
     "Gaussian read noise (sigma)", 0},
    {"synth", "shot_noise", KEY_BOOL, OFF(synth.shot_noise), 0, 1, 1, "-", "Poisson shot noise", 0},
    {"synth", "margin_px", KEY_DOUBLE, OFF(synth.margin_px), 0, 1024, 1, "px",
     "particles placed this far outside the image too", 0},
    {"synth", "w", KEY_DOUBLE, OFF(synth.w_star), -1, 1, 1, "h",
     "out-of-plane displacement between frames", 0},
    {"synth", "double_frame", KEY_BOOL, OFF(synth.double_frame), 0, 1, 1, "-",
     "write frame A above frame B in one file", 0},
    {"synth", "flow", KEY_STRING, OFF(synth.flow), 0, 0, 1, "spec",
     "flow in px: uniform:U,V; duct[:A]; poiseuille[:A]; poiseuille-y:A; oseen:A,RC[,CX,CY]; "
     "sine:A,L (rpiv synth --help)",
     0},
    {"synth", "truth_z", KEY_DOUBLE, OFF(synth.truth_z), -1, 1, 1, "h",
     "z* of the ground truth of z-dependent flows (< 0: the sheet's peak)", 0},
    {"synth", "pz_profile", KEY_STRING, OFF(synth.pz_profile), 0, 0, 1, "path",
     "particle density P(z*) table, rows 'z* P' (empty = uniform)", 0},
    {"synth", "radius_sigma", KEY_DOUBLE, OFF(synth.radius_sigma), 1, 20, 1, "sigma",
     "particle images drawn out to this many sigma", 0},
    {"synth", "cutoff_counts", KEY_DOUBLE, OFF(synth.cutoff_counts), 0, 1e9, 1, "counts",
     "particle images with a lower peak are not drawn", 0},
    {"synth", "rk_steps", KEY_INT, OFF(synth.rk_steps), 1, 1000, 1, "-",
     "RK4 steps over dt/2 for flows varying along the path", 0},
    /* [output] */
    /* [bias] (rpiv piv --sheet-bias, docs/bias.md) */
    {"bias", "depth", KEY_ENUM, OFF(bias.depth), 0, 0, 1, "-",
     "depth the bias is referred to: zmax (the sheet's peak) or zop (the object plane)",
     rpiv_ccm_depth_names},
    {"bias", "variation", KEY_ENUM, OFF(bias.vary), 0, 0, 1, "-",
     "velocity across the depth: duct, profile (file) or field (measured gradient)",
     rpiv_ccm_vary_names},
    {"bias", "profile", KEY_STRING, OFF(bias.profile), 0, 0, 1, "path",
     "variation = profile: U*(z*) as two columns", 0},
    {"bias", "rel_thickness", KEY_DOUBLE, OFF(bias.rel_thickness), 0, 0.9, 1, "-",
     "uncertainty: relative change of the sheet's thickness", 0},
    {"bias", "dz", KEY_DOUBLE, OFF(bias.dz), 0, 0.5, 1, "h", "uncertainty: shift of the sheet", 0},
    {"bias", "pixel_box", KEY_DOUBLE, OFF(bias.pixel_box), 0, 4, 1, "px",
     "the CCM's pixel integration: side of the square a pixel integrates over (0 = the "
     "paper's point-sampled images)",
     0},
    {"bias", "window_model", KEY_BOOL, OFF(bias.window_model), 0, 1, 1, "-",
     "the CCM's prediction of what the engine measures models the [piv] final window (pairs "
     "lost at its edges, the mean removal's baseline; 0 = an infinite window)",
     0},
    {"bias", "window_interp", KEY_BOOL, OFF(bias.window_interp), 0, 1, 0, "-",
     "with window_model and [piv] deform, the final window's plane through the deformation's "
     "cubic-spline interpolation kernel, the pairs lost per shift of the plane (docs/ccm.md, "
     "\"The planes' skew\"; off: per term, no interpolation)",
     0},
    {"bias", "window_pairs", KEY_DOUBLE, OFF(bias.window_pairs), 0, 1e9, 1, "-",
     "with window_interp, the ensemble's pairs whose noise the modelled plane carries (the "
     "estimator's 7 x 7 / 5 x 5 / 3-point paths weighted by their probability); 0 = the run's "
     "own (rpiv piv --sheet-bias, the demo), else the noise-free plane (docs/ccm.md)",
     0},
    {"bias", "window_area", KEY_INT, OFF(bias.window_area), 0, 64, 1, "-",
     "with window_model, rpiv_config_ccm_predict (python rpiv.ccm.predict) averages the "
     "model over N x N sub-positions of the final window (the flow across it, followed by the "
     "deformation); 0 or 1 = the window's centre (the same to 3e-5 px on the duct, 25-180 "
     "times cheaper; docs/ccm.md)",
     0},
    {"bias", "measured", KEY_BOOL, OFF(bias.measured), 0, 1, 1, "-",
     "the per-vector bias is that of what the engine measures (its sub-pixel estimator on the "
     "plane of its final window, as window_model sets it); 0 = the CCM's continuous peak",
     0},
    {"bias", "measured_step", KEY_INT, OFF(bias.measured_step), 1, 64, 1, "-",
     "with measured, the window's estimate is computed exactly every N-th vector of a row (and "
     "by bisection where the estimator's path changes), interpolated between; 1 = at every "
     "vector",
     0},
    {"output", "dir", KEY_STRING, OFF(output.dir), 0, 0, 1, "path", "output folder", 0},
    {"output", "plots", KEY_BOOL, OFF(output.plots), 0, 1, 1, "-", "write PNG plots", 0},
};
static const size_t nkeys = sizeof keys / sizeof keys[0];

rpiv_experiment rpiv_experiment_default(void)
{
    rpiv_experiment e;
    memset(&e, 0, sizeof e);
    e.camera = rpiv_camera_default();
    e.particles = rpiv_particles_default();
    e.channel = rpiv_channel_default();
    e.laser = rpiv_laser_default();
    e.prism = rpiv_prism_default();
    e.sheet = rpiv_sheet_params_default();
    e.piv = rpiv_piv_params_default();
    e.synth = rpiv_synth_params_default();
    e.bias = rpiv_ccm_bias_params_default();
    strcpy(e.output.dir, "rpiv-out");
    e.output.plots = 1;
    return e;
}

rpiv_status rpiv_experiment_check(const rpiv_experiment *e)
{
    rpiv_status st;
    if ((st = rpiv_camera_check(&e->camera)) || (st = rpiv_particles_check(&e->particles)) ||
        (st = rpiv_channel_check(&e->channel)) || (st = rpiv_laser_check(&e->laser)) ||
        (st = rpiv_prism_check(&e->prism)) || (st = rpiv_sheet_params_check(&e->sheet)) ||
        (st = rpiv_piv_params_check(&e->piv)) || (st = rpiv_synth_params_check(&e->synth)) ||
        (st = rpiv_ccm_bias_params_check(&e->bias)))
        return st;
    return RPIV_OK;
}

static const key_spec *find_key(const char *section, const char *key, int *section_known)
{
    *section_known = 0;
    for (size_t i = 0; i < nkeys; i++) {
        if (strcmp(keys[i].section, section))
            continue;
        *section_known = 1;
        if (!strcmp(keys[i].key, key))
            return &keys[i];
    }
    return NULL;
}

static int parse_num(const char *s, double *v)
{
    char *end;
    errno = 0;
    while (*s == ' ' || *s == '\t')
        s++;
    *v = strtod(s, &end);
    while (*end == ' ' || *end == '\t')
        end++;
    return end != s && !*end && !errno && isfinite(*v);
}

static void range_text(const key_spec *k, char *buf, size_t n)
{
    if (k->type == KEY_ENUM) {
        size_t used = 0;
        buf[0] = '\0';
        for (int i = 0; k->names[i]; i++)
            used += (size_t)snprintf(buf + used, used < n ? n - used : 0, "%s%s", i ? "|" : "",
                                     k->names[i]);
    } else if (k->type == KEY_BOOL) {
        snprintf(buf, n, "0|1|true|false|yes|no");
    } else if (k->type == KEY_STRING) {
        snprintf(buf, n, "text up to %d characters",
                 (k->max > 0 ? (int)k->max : RPIV_PATH_MAX) - 1);
    } else if (k->type == KEY_WINDOWS) {
        snprintf(buf, n, "1..%d sizes of 8..1024 px, W or WxH", RPIV_PIV_MAX_PASSES);
    } else {
        snprintf(buf, n, "%g..%g %s", k->min, k->max, k->unit);
    }
}

/* Parse windows "64,32,32" / "64x48,32" into piv params. */
static int parse_windows(const char *s, rpiv_piv_params *p)
{
    int n = 0;
    const char *c = s;
    while (*c) {
        char *end;
        while (*c == ' ')
            c++;
        long w = strtol(c, &end, 10), h = w;
        if (end == c)
            return 0;
        c = end;
        if (*c == 'x' || *c == 'X') {
            c++;
            h = strtol(c, &end, 10);
            if (end == c)
                return 0;
            c = end;
        }
        while (*c == ' ')
            c++;
        if (n >= RPIV_PIV_MAX_PASSES || w < 8 || h < 8 || w > 1024 || h > 1024)
            return 0;
        p->win_w[n] = (int)w;
        p->win_h[n] = (int)h;
        n++;
        if (*c == ',')
            c++;
        else if (*c)
            return 0;
    }
    if (n == 0)
        return 0;
    p->npass = n;
    return 1;
}

static rpiv_status set_value(rpiv_experiment *e, const key_spec *k, const char *value,
                             const char *where)
{
    char *base = (char *)e + k->off;
    char range[256];
    double v;
    range_text(k, range, sizeof range);
    switch (k->type) {
    case KEY_STRING: /* the capacity is the row's max, or RPIV_PATH_MAX */
        if (strlen(value) >= (k->max > 0 ? (size_t)k->max : RPIV_PATH_MAX))
            break;
        strcpy(base, value);
        return RPIV_OK;
    case KEY_ENUM:
        for (int i = 0; k->names[i]; i++)
            if (!strcasecmp(value, k->names[i])) {
                *(int *)base = i;
                return RPIV_OK;
            }
        break;
    case KEY_BOOL:
        if (!strcasecmp(value, "1") || !strcasecmp(value, "true") || !strcasecmp(value, "yes") ||
            !strcasecmp(value, "on")) {
            *(int *)base = 1;
            return RPIV_OK;
        }
        if (!strcasecmp(value, "0") || !strcasecmp(value, "false") || !strcasecmp(value, "no") ||
            !strcasecmp(value, "off")) {
            *(int *)base = 0;
            return RPIV_OK;
        }
        break;
    case KEY_WINDOWS:
        if (parse_windows(value, (rpiv_piv_params *)base))
            return RPIV_OK;
        break;
    case KEY_ROI: {
        int r[4];
        const char *c = value;
        int n = 0;
        for (; n < 4; n++) {
            char *end;
            errno = 0;
            long x = strtol(c, &end, 10);
            if (end == c || errno || x < 0 || x > (long)k->max)
                break;
            r[n] = (int)x;
            c = end + strspn(end, " \t");
            if (n < 3 && *c++ != ',')
                break;
        }
        if (n < 4 || *c || ((r[2] || r[3]) && (r[2] <= r[0] || r[3] <= r[1])))
            break;
        memcpy(base, r, sizeof r);
        return RPIV_OK;
    }
    case KEY_INT:
    case KEY_LONG:
    case KEY_ULONG:
    case KEY_DOUBLE:
        if (!parse_num(value, &v) || v < k->min || v > k->max)
            break;
        if (k->type != KEY_DOUBLE && v != floor(v))
            break;
        if (k->type == KEY_INT)
            *(int *)base = (int)v;
        else if (k->type == KEY_LONG)
            *(long *)base = (long)v;
        else if (k->type == KEY_ULONG)
            *(unsigned long *)base = (unsigned long)v;
        else
            *(double *)base = v * k->scale;
        return RPIV_OK;
    }
    /* a long value is cut in the message so that the accepted range stays visible */
    return rpiv_fail(RPIV_ECONFIG, "%s: bad value '%.*s%s' for %s.%s (accepted: %s)", where,
                     strlen(value) > 80 ? 72 : 80, value, strlen(value) > 80 ? "..." : "",
                     k->section, k->key, range);
}

rpiv_status rpiv_config_set(rpiv_experiment *e, const char *section, const char *key,
                            const char *value, const char *origin)
{
    int known;
    const key_spec *k = find_key(section, key, &known);
    if (!k) {
        if (!known)
            return rpiv_fail(RPIV_ECONFIG, "%s: unknown section [%s]", origin, section);
        return rpiv_fail(RPIV_ECONFIG, "%s: unknown key '%s' in [%s]", origin, key, section);
    }
    return set_value(e, k, value, origin);
}

/* The INI reader: our own, over text_getline, so that a line has no length limit (Debian's
 * libinih cut lines at 199 characters and read the rest as a new line). The syntax is the
 * subset libinih read: a UTF-8 BOM is skipped; blank lines and lines whose first non-blank
 * character is ';' or '#' are comments; "[section]"; "key = value" or "key : value", blanks
 * around both trimmed, and a ';' preceded by a blank starts a comment in the value. Anything
 * else is a syntax error naming file:line. */
static char *trim(char *s)
{
    s += strspn(s, " \t\r\n");
    size_t n = strlen(s);
    while (n > 0 && strchr(" \t\r\n", s[n - 1]))
        s[--n] = '\0';
    return s;
}

static rpiv_status parse_line(char *line, char *section, size_t section_size, rpiv_experiment *e,
                              const char *where)
{
    char *s = trim(line);
    if (*s == '\0' || *s == ';' || *s == '#')
        return RPIV_OK;
    if (*s == '[') {
        char *close = strchr(s, ']');
        char *rest = close ? trim(close + 1) : NULL;
        if (!close || (*rest && *rest != ';' && *rest != '#'))
            return rpiv_fail(RPIV_ECONFIG, "%s: syntax error: a section header is [name]", where);
        *close = '\0';
        char *name = trim(s + 1);
        int known = 0;
        (void)find_key(name, "", &known);
        if (!known)
            return rpiv_fail(RPIV_ECONFIG, "%s: unknown section [%.64s]", where, name);
        snprintf(section, section_size, "%s", name);
        return RPIV_OK;
    }
    size_t k = strcspn(s, "=:");
    if (s[k] == '\0' || k == 0)
        return rpiv_fail(RPIV_ECONFIG, "%s: syntax error (expected [section] or key = value)",
                         where);
    if (!*section)
        return rpiv_fail(RPIV_ECONFIG, "%s: key outside a section (a [section] line first)", where);
    s[k] = '\0';
    char *value = s + k + 1;
    for (char *c = value; *c; c++)
        if (*c == ';' && c > value && (c[-1] == ' ' || c[-1] == '\t')) {
            *c = '\0';
            break;
        }
    value = trim(value);
    if (strchr(value, '\r')) /* a lone CR inside a line: a line break to some editors */
        return rpiv_fail(RPIV_ECONFIG, "%s: a carriage return inside the value of '%.64s'", where,
                         trim(s));
    return rpiv_config_set(e, section, trim(s), value, where);
}

/* Open a regular file for reading without blocking on a FIFO or a device first. */
static FILE *open_regular(const char *path, rpiv_status *st)
{
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    struct stat sb;
    if (fd < 0) {
        *st = rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
        return NULL;
    }
    if (fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        close(fd);
        *st = rpiv_fail(RPIV_EIO, "%s: not a regular file (%s)", path,
                        S_ISDIR(sb.st_mode) ? "a directory" : "a FIFO, device or socket");
        return NULL;
    }
    FILE *fp = fdopen(fd, "r");
    if (!fp) {
        *st = rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
        close(fd);
    }
    return fp;
}

rpiv_status rpiv_config_load(const char *path, rpiv_experiment *e)
{
    rpiv_status st = RPIV_OK;
    FILE *fp = open_regular(path, &st);
    if (!fp)
        return st;
    char *line = NULL, section[64] = "", where[RPIV_PATH_MAX + 32];
    size_t cap = 0;
    long lineno = 0;
    ssize_t len;
    while (!st && (len = text_getline(fp, &line, &cap, path, &lineno, &st)) >= 0) {
        char *s = line;
        if (lineno == 1 && !strncmp(s, "\xef\xbb\xbf", 3))
            s += 3;
        snprintf(where, sizeof where, "%s:%ld", path, lineno);
        st = parse_line(s, section, sizeof section, e, where);
    }
    if (!st && ferror(fp))
        st = rpiv_fail(RPIV_EIO, "%s: cannot read: %s", path, strerror(errno));
    free(line);
    fclose(fp);
    if (st)
        return st;
    st = rpiv_experiment_check(e);
    if (st) { /* the message buffer is both source and destination: copy it first */
        char msg[768];
        snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
        return rpiv_fail(st, "%s: %s", path, msg);
    }
    return RPIV_OK;
}

/* 1 if the reader gives the string back as written: one line, no blanks at either end, no
 * ';' after a blank (an inline comment). */
static int reads_back(const char *v)
{
    if (strpbrk(v, "\r\n"))
        return 0;
    size_t n = strlen(v);
    if (n && (strchr(" \t", v[0]) || strchr(" \t", v[n - 1])))
        return 0;
    for (const char *c = v; (c = strchr(c, ';')); c++)
        if (c > v && (c[-1] == ' ' || c[-1] == '\t'))
            return 0;
    return 1;
}

static void write_value(const rpiv_experiment *e, const key_spec *k, FILE *fp)
{
    const char *base = (const char *)e + k->off;
    switch (k->type) {
    case KEY_STRING:
        fprintf(fp, "%s", base);
        break;
    case KEY_ENUM:
        fprintf(fp, "%s", k->names[*(const int *)base]);
        break;
    case KEY_BOOL:
    case KEY_INT:
        fprintf(fp, "%d", *(const int *)base);
        break;
    case KEY_LONG:
        fprintf(fp, "%ld", *(const long *)base);
        break;
    case KEY_ULONG:
        fprintf(fp, "%lu", *(const unsigned long *)base);
        break;
    case KEY_DOUBLE: {
        /* the shortest form that reads back to the same double */
        double v = *(const double *)base / k->scale;
        char buf[40];
        for (int prec = 6; prec <= 17; prec++) {
            snprintf(buf, sizeof buf, "%.*g", prec, v);
            if (strtod(buf, NULL) * k->scale == *(const double *)base)
                break;
        }
        fputs(buf, fp);
        break;
    }
    case KEY_WINDOWS: {
        const rpiv_piv_params *p = (const rpiv_piv_params *)base;
        for (int i = 0; i < p->npass; i++) {
            if (p->win_w[i] == p->win_h[i])
                fprintf(fp, "%s%d", i ? "," : "", p->win_w[i]);
            else
                fprintf(fp, "%s%dx%d", i ? "," : "", p->win_w[i], p->win_h[i]);
        }
        break;
    }
    case KEY_ROI: {
        const int *r = (const int *)base;
        fprintf(fp, "%d,%d,%d,%d", r[0], r[1], r[2], r[3]);
        break;
    }
    }
}

rpiv_status rpiv_config_write(const rpiv_experiment *e, FILE *fp)
{
    const char *sec = "";
    for (size_t i = 0; i < nkeys; i++)
        if (keys[i].type == KEY_STRING && !reads_back((const char *)e + keys[i].off))
            return rpiv_fail(RPIV_ECONFIG,
                             "%s.%s: a value with a line break, blanks at an end or ' ;' "
                             "cannot be written to an INI file and read back",
                             keys[i].section, keys[i].key);
    fprintf(fp, "# rpiv configuration (complete; feed back with --config)\n");
    for (size_t i = 0; i < nkeys; i++) {
        const key_spec *k = &keys[i];
        if (strcmp(sec, k->section)) {
            sec = k->section;
            fprintf(fp, "\n[%s]\n", sec);
        }
        fprintf(fp, "; %s [%s]\n%s = ", k->help, k->unit, k->key);
        write_value(e, k, fp);
        fputc('\n', fp);
    }
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "cannot write the configuration");
    return RPIV_OK;
}

rpiv_status rpiv_config_write_doc(FILE *fp)
{
    rpiv_experiment d = rpiv_experiment_default();
    const char *sec = "";
    char range[256];
    for (size_t i = 0; i < nkeys; i++) {
        const key_spec *k = &keys[i];
        if (strcmp(sec, k->section)) {
            sec = k->section;
            fprintf(fp,
                    "\n### [%s]\n\n| key | unit | default | accepted | meaning |\n"
                    "|---|---|---|---|---|\n",
                    sec);
        }
        range_text(k, range, sizeof range);
        fprintf(fp, "| `%s` | %s | `", k->key, k->unit);
        write_value(&d, k, fp);
        fprintf(fp, "` | %s | %s |\n", range, k->help);
    }
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "cannot write the key reference");
    return RPIV_OK;
}
