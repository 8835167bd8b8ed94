/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Step 6 of the demo: the PNG plots (demo_plots.c) and the report, written twice from the
 * same calls: DIR/report.md and DIR/report.html (plots inline). Every number in the report
 * comes from the run; the paper's statements stand next to them for comparison. */
#include "demo_impl.h"

#include "rpiv/version.h"

#include "base/atomic.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- the report, in Markdown and HTML ------------------------------------------------------- */

typedef struct rep {
    FILE *md, *html;
    rpiv_status st; /* the first failure (a plot that cannot be read back) */
} rep;

/* Text with `code` spans: as is in Markdown, escaped with <code> in HTML. */
static void html_text(FILE *f, const char *s)
{
    int code = 0;
    for (; *s; s++) {
        switch (*s) {
        case '`':
            fputs(code ? "</code>" : "<code>", f);
            code = !code;
            break;
        case '<':
            fputs("&lt;", f);
            break;
        case '>':
            fputs("&gt;", f);
            break;
        case '&':
            fputs("&amp;", f);
            break;
        default:
            fputc(*s, f);
        }
    }
    if (code)
        fputs("</code>", f);
}

/* fmt is the printf format its callers (r_h, r_p) were given: checked there. */
static void r_vfmt(char *buf, size_t size, const char *fmt, va_list ap) RPIV_PRINTF(3, 0);
static void r_vfmt(char *buf, size_t size, const char *fmt, va_list ap)
{
    vsnprintf(buf, size, fmt, ap);
}

static void r_h(rep *r, int level, const char *fmt, ...) RPIV_PRINTF(3, 4);
static void r_h(rep *r, int level, const char *fmt, ...)
{
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    r_vfmt(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fprintf(r->md, "\n%.*s %s\n\n", level, "######", buf);
    fprintf(r->html, "<h%d>", level);
    html_text(r->html, buf);
    fprintf(r->html, "</h%d>\n", level);
}

static void r_p(rep *r, const char *fmt, ...) RPIV_PRINTF(2, 3);
static void r_p(rep *r, const char *fmt, ...)
{
    char buf[2048];
    va_list ap;
    va_start(ap, fmt);
    r_vfmt(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fprintf(r->md, "%s\n\n", buf);
    fputs("<p>", r->html);
    html_text(r->html, buf);
    fputs("</p>\n", r->html);
}

static int has_plot(const demo_ctx *c, const char *name)
{
    for (size_t k = 0; k < c->res->nplots; k++)
        if (!strcmp(c->res->plots[k], name))
            return 1;
    return 0;
}

/* The bytes of DIR/name as base64 (RFC 4648, with padding, one line) into f. */
static rpiv_status base64_file(FILE *f, const char *path)
{
    static const char abc[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    FILE *in = fopen(path, "rb");
    if (!in)
        return rpiv_fail(RPIV_EIO, "%s: cannot open to embed it in report.html", path);
    unsigned char b[3 * 1024];
    size_t n;
    while ((n = fread(b, 1, sizeof b, in)) > 0) {
        for (size_t k = 0; k < n; k += 3) {
            size_t m = n - k < 3 ? n - k : 3;
            unsigned long v = (unsigned long)b[k] << 16;
            if (m > 1)
                v |= (unsigned long)b[k + 1] << 8;
            if (m > 2)
                v |= b[k + 2];
            char q[4] = {abc[(v >> 18) & 63], abc[(v >> 12) & 63], m > 1 ? abc[(v >> 6) & 63] : '=',
                         m > 2 ? abc[v & 63] : '='};
            fwrite(q, 1, 4, f);
        }
        if (n < sizeof b) /* a short read ends the file (or is an error): stop either way */
            break;
    }
    int bad = ferror(in);
    fclose(in);
    if (bad)
        return rpiv_fail(RPIV_EIO, "%s: read error while embedding it in report.html", path);
    return RPIV_OK;
}

/* A plot: a link in report.md (the PNG beside it), embedded as a data URI in report.html so
 * that the HTML stands alone when copied; data-file names the PNG it holds. */
static void r_img(rep *r, const demo_ctx *c, const char *name, const char *caption)
{
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    if (!has_plot(c, name) || r->st)
        return;
    if ((st = demo_path(c, name, path, sizeof path))) {
        r->st = st;
        return;
    }
    fprintf(r->md, "![%s](%s)\n\n%s\n\n", caption, name, caption);
    fprintf(r->html, "<figure><img data-file=\"%s\" src=\"data:image/png;base64,", name);
    if ((st = base64_file(r->html, path))) {
        r->st = st;
        return;
    }
    fputs("\" alt=\"", r->html);
    html_text(r->html, caption);
    fputs("\"><figcaption>", r->html);
    html_text(r->html, caption);
    fputs("</figcaption></figure>\n", r->html);
}

static void r_row(rep *r, int head, const char *a, const char *b, const char *cc)
{
    const char *cell[3] = {a, b, cc};
    fputs("|", r->md);
    fputs("<tr>", r->html);
    for (int k = 0; k < 3; k++) {
        fprintf(r->md, " %s |", cell[k]);
        fputs(head ? "<th>" : "<td>", r->html);
        html_text(r->html, cell[k]);
        fputs(head ? "</th>" : "</td>", r->html);
    }
    fputs("\n", r->md);
    fputs("</tr>\n", r->html);
    if (head)
        fputs("|---|---|---|\n", r->md);
}

static void r_list(rep *r, const char *const *items, size_t n)
{
    fputs("<ul>\n", r->html);
    for (size_t k = 0; k < n; k++) {
        fprintf(r->md, "- %s\n", items[k]);
        fputs("<li>", r->html);
        html_text(r->html, items[k]);
        fputs("</li>\n", r->html);
    }
    fputs("\n", r->md);
    fputs("</ul>\n", r->html);
}

/* A percentage or "n/a". */
static const char *pct(char *buf, size_t n, double v)
{
    if (isfinite(v))
        snprintf(buf, n, "%.2f %%", 100 * v);
    else
        snprintf(buf, n, "n/a");
    return buf;
}

/* The per-vector sheet bias (rpiv_ccm_bias_field) and the corrected field against the
 * analytic duct, the whole field and by bands of x*. */
static void sheet_bias_section(rep *r, const demo_ctx *c)
{
    const rpiv_demo_result *s = c->res;
    if (!s->nbias_bands)
        return;
    char a[32], b[32], v1[128], v2[128], v3[128];
    r_h(r, 3, "Sheet bias per vector; the corrected field against the analytic duct");
    r_p(r,
        "For every vector of the R-PIV field, `rpiv_ccm_bias_field` (what `rpiv piv "
        "--sheet-bias` computes) predicts by the CCM the bias of the measured displacement "
        "against the velocity at `z*_max(x*)`: the synthesised sheet at the vector's `x*`, the "
        "object plane, the duct's `U*(y*, z*)` at the vector's `y*`, pixel-integrated particle "
        "images (`[bias] pixel_box` = %g), %s. `u_corrected = u - bias_u`. E1 against the "
        "analytic `U` at `z*_max(x*)` over the compared vectors: raw %s, corrected %s.",
        c->e.bias.pixel_box,
        c->e.bias.measured ? "the displacement the engine measures (`[bias] measured` = 1: its "
                             "estimator on its final window's plane, with the ensemble's noise)"
                           : "the correlation's continuous peak (`[bias] measured` = 0)",
        pct(a, 32, s->bias_e1_raw), pct(b, 32, s->bias_e1_corr));
    r_img(r, c, "bias_map.png", "The predicted sheet bias per vector, U*");
    fputs("<table>\n", r->html);
    r_row(r, 1, "band of `x*` (sheet width `z*_sup - z*_inf`)",
          "mean `U*` error, measured / predicted bias", "E1 raw -> corrected");
    for (int k = 0; k < s->nbias_bands; k++) {
        snprintf(v1, sizeof v1, "%.2f - %.2f (%.3f)", s->bias_x0[k], s->bias_x1[k], s->bias_e[k]);
        snprintf(v2, sizeof v2, "%+.4f / %+.4f", s->bias_err[k], s->bias_mean[k]);
        snprintf(v3, sizeof v3, "%s -> %s (%s)", pct(a, 32, s->bias_raw[k]),
                 pct(b, 32, s->bias_corr[k]),
                 s->bias_corr[k] < s->bias_raw[k] ? "pays" : "does not pay");
        r_row(r, 0, v1, v2, v3);
    }
    fputs("</table>\n\n", r->html);
    fputs("\n", r->md);
    r_p(r, "The correction pays where the predicted bias is large against what the model "
           "leaves out: with particle images of d_e = 1.8 px in focus the measured error carries "
           "an offset of about -0.04 px the model does not hold (the triangle of the pixel "
           "integration, the window deformation's interpolation, docs/bias.md \"On images\"); "
           "it cannot remove the noise of the near-floor columns, where few particles are lit.");
}

/* The R-PIV ensemble's random uncertainty and its coverage against the synthetic truth. */
static void uncertainty_section(rep *r, const demo_ctx *c)
{
    const rpiv_demo_result *s = c->res;
    if (!s->unc_n)
        return;
    char a[32], b[32];
    r_h(r, 3, "Random uncertainty per vector and its coverage");
    r_p(r,
        "The R-PIV ensemble runs with `--uncertainty` (docs/uncertainty.md: correlation "
        "statistics summed over the pairs, the predictor's noise carried through the passes). "
        "Over the %zu valid compared vectors the median `sigma_u` is %.4f U*. A standard "
        "uncertainty covers about 68 %% of the errors when the error is random. Here %s of the "
        "vectors have |U*_measured - U*(z*_max)| <= sigma_u (RMS error %.4f U*), and %s once the "
        "predicted sheet bias is removed (RMS %.4f U*): most of the error of this ensemble is "
        "not random. The columns at small `x*`, where the sheet's lit part is thin and few "
        "particles are lit (large sigma on the map), and the model's residual offset (section "
        "above) dominate it; a random uncertainty does not hold systematic errors by design. "
        "sigma_u is the part that more pairs would remove, not the total error.",
        s->unc_n, s->unc_med_sigma, pct(a, 32, s->unc_cov_raw), s->unc_rms_raw,
        pct(b, 32, s->unc_cov_corr), s->unc_rms_corr);
    r_img(r, c, "uncertainty_map.png", "The random uncertainty sigma_u per vector, U*");
}

static void key_figures(rep *r, const demo_ctx *c)
{
    const rpiv_demo_result *s = c->res;
    char v[256], a[32], b[32], d[32];
    fputs("<table>\n", r->html);
    r_row(r, 1, "figure", "this run", "the paper");
    snprintf(v, sizeof v, "%.2f deg (de*/dx* = %.4f)", s->sheet_incl_deg, s->sheet_de_dx);
    r_row(r, 0, "inclination of the sheet used, `atan(dz*_max/dx*)`", v,
          "about 5 deg, thickness growing along x*");
    snprintf(v, sizeof v, "%.2f deg", s->trace_elev_deg);
    r_row(r, 0, "elevation of the traced beam axis in the water", v, "-");
    snprintf(v, sizeof v, "%.3f", s->trace_e_65);
    r_row(r, 0, "traced thickness `e*` at `x* = 6.5`", v, "0.42 (measured, fig 7b)");
    if (isfinite(s->sheet_x_zop))
        snprintf(v, sizeof v, "%.2f", s->sheet_x_zop);
    else
        snprintf(v, sizeof v, "n/a");
    r_row(r, 0, "`x*` where `z*_max = z*_OP`", v, "6.3");
    snprintf(v, sizeof v, "%.1f %%", 100 * s->trace_it_ig);
    r_row(r, 0, "power transmitted into the water `It/Ig`", v, "fig 12b (grows with beta1)");
    snprintf(v, sizeof v, "mean %s, max %s, at z* = 0.5: %s", pct(a, 32, s->ppiv_e1_mean),
             pct(b, 32, s->ppiv_e1_max), pct(d, 32, s->ppiv_e1_mid));
    r_row(r, 0,
          "P-PIV planes (`e* = 0.05`, `z*_OP = z*_B`) vs the analytic duct, E1 over each "
          "plane",
          v, "a reference measurement (section 'Flow structure using P-PIV')");
    snprintf(v, sizeof v, "%s", pct(a, 32, s->ppiv_e1_z));
    r_row(r, 0, "P-PIV `U*(z*)` at `y* = 0.5` vs the analytic duct, E1 along `z*`", v,
          "sheet-thickness bias about 0.1 % (CCM, fig 19); measurement noise comes on top");
    snprintf(v, sizeof v, "%s", pct(a, 32, s->e1_zmax));
    r_row(r, 0, "R-PIV vs P-PIV at `z*_max`, E1 along `y*`, mean over `x*`", v,
          "R-PIV agrees with P-PIV at `z*_max` (fig 25, green)");
    snprintf(v, sizeof v, "%s; %s", pct(a, 32, s->e1_zinf), pct(b, 32, s->e1_zsup));
    r_row(r, 0, "R-PIV vs P-PIV at `z*_inf`; at `z*_sup`", v,
          "larger than at `z*_max` (fig 25, red and blue)");
    snprintf(v, sizeof v, "core %s (%d columns); near the floor %s (%d columns)",
             pct(a, 32, s->e1_zmax_core), s->ncols_core, pct(b, 32, s->e1_zmax_wall),
             s->ncols_wall);
    r_row(r, 0, "R-PIV vs P-PIV at `z*_max`: core vs near the wall", v,
          "bias below 1 % in the core, about 9 % at `z* = 0.0625` (CCM, fig 22): grows near "
          "the walls");
    snprintf(v, sizeof v, "%s (%d columns)", pct(a, 32, s->e1_zmax_above), s->ncols_above);
    r_row(r, 0, "R-PIV vs P-PIV at `z*_max` where `z*_max > z*_OP`", v,
          "the error grows for `x* >= 6` (fig 25)");
    snprintf(v, sizeof v, "%s", pct(a, 32, s->e1_model));
    r_row(r, 0, "R-PIV vs the CCM integral prediction at `y* = 0.5`, E1 along `x*`", v,
          "good agreement (fig 26)");
    if (s->nconv)
        snprintf(v, sizeof v, "%s after %d pair%s, %s after %d", pct(a, 32, s->conv_e1[0]),
                 s->conv_n[0], s->conv_n[0] > 1 ? "s" : "", pct(b, 32, s->conv_e1[s->nconv - 1]),
                 s->conv_n[s->nconv - 1]);
    r_row(r, 0, "the same E1 as pairs are added", v,
          "converges as `N_im` grows; over 200 pairs needed (fig 27)");
    snprintf(v, sizeof v, "%s", pct(a, 32, s->e1_model_ppiv));
    r_row(r, 0, "R-PIV vs P-PIV at `z*_max`, `y* = 0.5`, E1 along `x*`", v, "(fig 26)");
    snprintf(v, sizeof v, "corrected %s; association %s", pct(a, 32, s->e1_corr),
             pct(b, 32, s->e1_assoc));
    r_row(r, 0, "bias-corrected `U*(z*)` (CCM inversion) vs the truth, E1", v,
          "beyond the paper: the model undoes the bias");
    snprintf(v, sizeof v, "%s", pct(a, 32, s->rpiv_e1_truth));
    r_row(r, 0, "R-PIV field vs the analytic `U` at `z*_max(x*)`, E1", v, "-");
    double t5 = 0;
    for (int k = 0; k < 5; k++)
        t5 += s->step_seconds[k];
    snprintf(v, sizeof v, "%.1f s on %d thread%s (steps 1-5)", t5, s->threads,
             s->threads > 1 ? "s" : "");
    r_row(r, 0, "run time", v, "-");
    fputs("</table>\n", r->html);
    fputs("\n", r->md);
}

/* The notation and the paper's equations, for a reader without the paper. */
static void notation(rep *r, const demo_ctx *c)
{
    char hline[192];
    snprintf(hline, sizeof hline,
             "`h`: the channel height (here %.3g mm), the unit of length; `U_b`: the bulk "
             "velocity (flow rate / section, from `Re = U_b h / nu`), the unit of velocity",
             1e3 * c->e.channel.h_m);
    const char *const q[] = {
        hline,
        ("`x*`, `y*`, `z*` = x/h, y/h, z/h: streamwise, across the channel (side walls at 0 and "
         "1), and height above the floor through which the sheet enters (floor 0, top wall 1); "
         "`x* = 0` where the beam's axis enters the water"),
        ("`U*` = U / U_b: the streamwise velocity (V = W = 0 in this flow); `U*max` its value "
         "on the channel's axis; `U*_ref`, `U*_comp`: the two profiles an E1 compares; "
         "`U*_model`: the CCM's prediction"),
        ("`I0*(z*)`: the laser sheet's intensity across the height at one `x*`, divided by its "
         "maximum there"),
        ("`z*_max`: the height of the sheet's peak (`I0* = 1`); `z*_inf`, `z*_sup`: the heights "
         "below and above it where `I0* = 0.25` (the sheet's lower and upper edges)"),
        ("`e*` = `z*_sup - z*_inf`: the sheet's thickness at a quarter of its maximum; "
         "`de*/dx*`: its growth along `x*`"),
        ("`z+` = (`z* - z*_max`) / `e*`: the coordinate in which the traced profiles collapse "
         "onto one self-similar shape"),
        ("`z*_OP`: the height of the camera's object (in-focus) plane; `z*_B`: the height of a "
         "horizontal P-PIV sheet (the scan puts `z*_OP = z*_B`)"),
        ("`DOF*`: the depth of focus / h (the full width at half maximum of a dot's grey level "
         "as it leaves focus; the paper measures 0.43, `rpiv calib dof` measures it on images); "
         "the demo models the focus with Eq. diam instead"),
        ("`beta1`: the angle (deg) between the laser's axis and the normal of the prism's "
         "inclined face; it sets the sheet's angle in the water (fig 11)"),
        "`It/Ig`: the laser power transmitted into the water / the power incident on the prism",
        ("`E1`: the relative RMS difference of two profiles (Eq. E1); `E1` along `y*` at each "
         "`x*` (figs 24-25), along `x*` at `y* = 0.5` (figs 26-27), along `z*` (P-PIV)"),
        ("`N_im`: the number of image pairs summed; sum of correlation: the pairs' correlation "
         "maps are added before the peak is found (ensemble PIV)"),
        ("P-PIV: planar PIV, horizontal thin sheets scanned in height (the reference); R-PIV: "
         "the sheet refracted through the floor, inclined by a few degrees and thick; CCM: the "
         "cross-correlation model of R-PIV")};
    const char *const eq[] = {
        ("Eq. White: the laminar, fully developed velocity in a square duct (White 2006): "
         "`U*(y*, z*)` = a series over odd i of `cos(i pi (y* - 0.5)) [1 - cosh(i pi (z* - "
         "0.5)) / cosh(i pi / 2)] / i^3`, scaled so that its mean over the section is 1"),
        ("Eq. Desc: each ray's refraction (Snell-Descartes, `theta_t = asin(eta sin theta_i)`, "
         "`eta` the ratio of refractive indices) and transmitted fraction (Fresnel, `T = 1 - R`) "
         "at the air/PMMA and PMMA/water interfaces"),
        ("Eq. int: a particle's image is a Gaussian spot of energy `I0(z*) d_p^2` (fluorescence) "
         "divided by `d_e^2 (s_0 + z')^2`, `z' = |z* - z*_OP|` its distance from the object "
         "plane, `s_0` the working distance"),
        ("Eq. diam: the particle image diameter `d_e = sqrt(M^2 d_p^2 + 5.95 (M + 1)^2 "
         "lambda^2 f#^2 + M^2 z'^2 D_a^2 / (s_0 + z')^2)`: geometric image, diffraction, "
         "defocus"),
        ("Eq. CCM_gen, CCM_simp: the correlation of a window is a sum over its particles of "
         "Gaussians centred on their displacements, weighted by `I0^2 / d_e^2`; CCM_simp assumes "
         "the sheet uniform across a window, equal pulses and W = 0 (hypotheses 1-3)"),
        ("Eq. statform: the sum of correlation over `N_im` pairs tends, as `N_im` grows, to the "
         "integral over z of `P(z) R_Dz(z)` (`P` the probability of a particle at height z, "
         "uniform here); the displacement of its peak is the model's velocity `U*_model`"),
        ("Eq. E1: `E1 = sqrt(integral_0^1 (U*_ref - U*_comp)^2 d alpha) / integral_0^1 U*_ref "
         "d alpha`, `alpha` = `x*`, `y*` or `z*` rescaled to [0, 1]")};
    r_h(r, 2, "Notation and equations");
    r_p(r, "Starred quantities are made dimensionless with the channel height and the bulk "
           "velocity, as in the paper:");
    r_list(r, q, sizeof q / sizeof q[0]);
    r_p(r, "The equations, named as in the paper (Cabut et al.):");
    r_list(r, eq, sizeof eq / sizeof eq[0]);
}

/* The column of largest E1 at z*_max (fig 25's spike in a default run, at the band's first
 * column): what the sheet and the R-PIV vectors are there, so that the reader can judge it. */
static void worst_column(rep *r, const demo_ctx *c)
{
    int iw = -1, ncmp = 0;
    double sum = 0;
    for (int i = 0; i < c->nx; i++)
        if (c->col_ok[i] && isfinite(c->e1max[i])) {
            ncmp++;
            sum += c->e1max[i];
            if (iw < 0 || c->e1max[i] > c->e1max[iw])
                iw = i;
        }
    if (iw < 0 || ncmp < 2)
        return;
    const rpiv_field *f = c->rfield;
    /* its fluid vectors: replaced ones, mean peak ratio; and the band's median column's */
    int nfl = 0, nrep = 0;
    double pr = 0, dmax = 0, prall = 0;
    int nall = 0;
    for (int j = 0; j < c->ny; j++)
        for (int i = 0; i < c->nx; i++) {
            size_t k = (size_t)j * (size_t)c->nx + (size_t)i;
            if (!c->fluid[k] || f->flag[k] == RPIV_FLAG_MASKED)
                continue;
            prall += (double)f->peak_ratio[k];
            nall++;
            if (i != iw)
                continue;
            nfl++;
            nrep += f->flag[k] == RPIV_FLAG_REPLACED;
            pr += (double)f->peak_ratio[k];
            double ur = (double)f->u[k] / c->bulk_px;
            double up = demo_vol_eval(c, i, j, c->czmax[i]);
            if (isfinite(up) && fabs(ur - up) > dmax)
                dmax = fabs(ur - up);
        }
    if (!nfl || !nall)
        return;
    const char *where = iw == 0           ? "the band's first column (the image's left edge)"
                        : iw == c->nx - 1 ? "the band's last column (the image's right edge)"
                                          : "a column inside the band";
    char a[32], b[32], d[32], m[32], t[32];
    r_p(r,
        "The largest E1 at `z*_max` is %s at `x* = %.3f`, %s; there E1 is %s at `z*_inf` and "
        "%s at `z*_sup`, about the same at the three heights: the error is the R-PIV "
        "column's own, not the reference's. The sheet there is `e* = %.4f` thick (`z*_max = "
        "%.4f`), so few particles are lit: the mean peak ratio of its %d fluid vectors is %.2f "
        "(%.1f over the band), %d of them were replaced by the validation, and the largest "
        "departure from P-PIV at `z*_max` is %.2f in `U*`. The column is kept in every mean "
        "(without it the mean E1 at `z*_max` would be %s instead of %s): it is the measurement "
        "where the sheet is thinnest, not an artefact of the comparison.",
        pct(a, 32, c->e1max[iw]), c->xs[iw], where, pct(b, 32, c->e1inf[iw]),
        pct(d, 32, c->e1sup[iw]), c->czsup[iw] - c->czinf[iw], c->czmax[iw], nfl, pr / nfl,
        prall / nall, nrep, dmax, pct(m, 32, (sum - c->e1max[iw]) / (ncmp - 1)),
        pct(t, 32, sum / ncmp));
}

static void write_body(rep *r, const demo_ctx *c)
{
    const rpiv_demo_result *s = c->res;
    const rpiv_experiment *e = &c->e;
    char a[32], b[32];
    r_h(r, 1, "rpiv demo: the R-PIV study of Cabut et al. on synthetic images");
    r_p(r,
        "rpiv %s made every image of this study from the experiment's parameters, processed "
        "them as it would process camera images, and judged the result against the analytic "
        "duct flow and the cross-correlation model (CCM). Every number below was computed in "
        "this run. `docs/demo.md` explains each step and gives the `rpiv` commands that run "
        "the same study on your own images and calibration files.",
        RPIV_VERSION_STRING);
    r_p(r,
        "Experiment: square duct h = %.3g mm, Re = %g (U_b = %.4g m/s), camera %d x %d px, "
        "M = %g, f# = %g, object plane `z*_OP = %g`; pulse separation %g ms, so U* = 1 is "
        "%.3f px. Images: a band of %d x %d px centred on the field of view (`x*` %.3f ... "
        "%.3f, `y*` %.3f ... %.3f) holding the channel and %d px margins, the rows outside the "
        "fluid masked; PIV %d passes (%d to %d px windows, overlap %g), sum of correlation; "
        "grid %d x %d.",
        1e3 * e->channel.h_m, e->channel.reynolds, rpiv_channel_bulk_ms(&e->channel),
        e->camera.width_px, e->camera.height_px, e->camera.magnification, e->camera.fnumber,
        e->camera.zop_star, 1e3 * e->synth.dt_s, s->bulk_px, s->width_px, s->height_px, s->x0_star,
        s->x1_star, s->y0_star, s->y1_star, c->p.margin_px, e->piv.npass, e->piv.win_w[0],
        e->piv.win_w[e->piv.npass - 1], e->piv.overlap, s->grid_nx, s->grid_ny);

    notation(r, c);

    r_h(r, 2, "Key figures");
    key_figures(r, c);

    r_h(r, 2, "1. Optics: the refracted sheet");
    r_p(r,
        "%ld rays of the Gaussian beam are traced through the lens, the prism's inclined face "
        "(air/PMMA) and the channel floor (PMMA/water) with Snell-Descartes and Fresnel "
        "(Eq. Desc), and binned into profiles `I0*(z*)` at stations along `x*`. It/Ig = %.1f %%: "
        "the rest is reflected or totally reflected at the floor, near the critical angle.",
        e->laser.nrays, 100 * s->trace_it_ig);
    r_p(r, "The R-PIV synthesis uses %s.", s->sheet_note);
    r_img(r, c, "sheet_profiles.png", "Traced profiles: thick and asymmetric (paper fig 7b)");
    r_img(r, c, "sheet_metrics.png",
          "z*_inf, z*_max, z*_sup along x*, traced (points) and as synthesised (lines), and "
          "the object plane (paper figs 8, 21)");
    r_img(r, c, "sheet_beta1.png", "Profiles at x* = 4.455 for several beta1 (paper fig 11)");
    r_img(r, c, "sheet_selfsim.png", "Self-similarity of the traced profiles and the fit");

    r_h(r, 2, "2. Reference flow: the square duct");
    r_p(r,
        "Fully developed laminar flow (Eq. White), normalised by the bulk velocity: U*max = "
        "%.4f at the centre. The synthetic particles move with it (V = W = 0).",
        s->umax_star);
    r_img(r, c, "duct_profiles.png", "Analytic U* across the duct");

    r_h(r, 2, "3. P-PIV reference: z-scan of thin sheets");
    r_p(r,
        "%d horizontal Gaussian sheets (`e* = %g`) at `z*_B = z*_OP` = %g ... %g, %d pairs "
        "each, processed by sum of correlation; the volume `U*(x*, y*, z*)` is rebuilt by "
        "natural cubic splines across z through the planes and the no-slip walls (paper fig "
        "23). The particles of a plane are seeded within `z*_B +- %g e*` (outside, I0 < 1e-6): "
        "the images are those of a %.1f times denser seeding. E1 against the analytic duct: "
        "mean over the planes %s.",
        s->ppiv_planes, c->p.ppiv_e_star, c->zk[1], c->zk[c->nz], s->ppiv_pairs, c->p.ppiv_slab,
        1 / (2 * c->p.ppiv_slab * c->p.ppiv_e_star), pct(a, 32, s->ppiv_e1_mean));
    r_img(r, c, "ppiv_plane.png", "P-PIV ensemble field of the plane nearest z* = 0.5");
    r_img(r, c, "ppiv_section.png",
          "P-PIV volume: cross-section U*(y*, z*) at the centre of the band (paper fig 23)");
    r_img(r, c, "duct_section.png", "The analytic cross-section, for comparison");
    r_img(r, c, "ppiv_e1.png", "E1 of each P-PIV plane against the analytic duct");

    r_h(r, 2, "4. R-PIV: the refracted sheet");
    r_p(r,
        "%d pairs through the refracted sheet, object plane `z*_OP = %g`, defocus and "
        "intensity of each particle from Eq. diam and Eq. int, processed by sum of "
        "correlation; the ensemble of the last pass is also read after %d, ... pairs for the "
        "convergence. %s of the fluid vectors were replaced by the validation.",
        s->rpiv_pairs, e->camera.zop_star, c->snap[0], pct(a, 32, s->rpiv_replaced));
    r_img(r, c, "rpiv_image.png", "A synthetic R-PIV frame");
    r_img(r, c, "rpiv_field.png", "The R-PIV ensemble field (every few vectors)");
    r_img(r, c, "rpiv_map.png",
          "U* of the R-PIV field: it grows along x* as the sheet rises from the floor");

    r_h(r, 2, "5. Comparisons");
    r_p(r,
        "At every column `x*` where the sheet is lit across the window (%d of %d), the R-PIV "
        "profile along `y*` is compared with the P-PIV volume at the heights `z*_inf`, "
        "`z*_max`, `z*_sup` of the synthesised sheet there (E1 of Eq. E1 with alpha = y*). "
        "The CCM predicts the R-PIV velocity at `y* = 0.5` from the sheet, the object plane "
        "and the P-PIV profile `U*(z*)` at that column (Eq. statform, the continuous peak).",
        s->ncols, s->grid_nx);
    r_img(r, c, "fig24_profiles.png", "R-PIV and P-PIV profiles at one x* (paper fig 24)");
    r_img(r, c, "fig25_e1.png", "E1 along y* at every x* (paper fig 25)");
    worst_column(r, c);
    r_img(r, c, "fig26_model.png", "R-PIV and the CCM prediction at y* = 0.5 (paper fig 26)");
    r_img(r, c, "fig27_convergence.png",
          "Convergence of the sum of correlation towards the model (paper fig 27)");
    r_p(r,
        "Bias correction (beyond the paper): the R-PIV row at `y* = 0.5` seen through the "
        "sheet at each `x*` is inverted with the CCM into `U*(z*)` (regularised least squares, "
        "symmetric about z* = 0.5; the model predicts what the engine measures: its sub-pixel "
        "estimator on the plane of its final window). E1 against the analytic duct: corrected %s, "
        "the paper's "
        "association of each measurement with `z*_max` %s.",
        pct(a, 32, s->e1_corr), pct(b, 32, s->e1_assoc));
    r_img(r, c, "ccm_invert.png", "Bias-corrected profile against the truth");
    sheet_bias_section(r, c);
    uncertainty_section(r, c);

    r_h(r, 2, "Files");
    const char *files[] = {
        "`data/raytrace_metrics.txt`, `data/raytrace_profile_x4.455.txt`, "
        "`data/raytrace_sweep*.txt`: the ray tracing",
        "`data/sheet_fit.txt`: the self-similar sheet (a sheet profile file: `sheet.kind = "
        "selfsim`, `sheet.profile = ...`)",
        "`data/ppiv_z*.txt`: the P-PIV planes (vector files), `data/ppiv_pz_*.txt` their P(z*)",
        "`data/rpiv.txt`, `data/rpiv_truth.txt`: the R-PIV field and the analytic one",
        "`data/compare_x.txt`, `data/convergence.txt`, `data/ccm_invert.txt`: the comparisons",
        "`images/*.tif`: the first R-PIV pair and the first pair of the P-PIV plane nearest "
        "z* = 0.5 (16-bit TIFF)"};
    r_list(r, files, sizeof files / sizeof files[0]);
}

/* Both files through base's atomic writer: a failure leaves an older report intact. */
static rpiv_status write_report(demo_ctx *c)
{
    char pmd[RPIV_PATH_MAX], phtml[RPIV_PATH_MAX];
    atomic_file md, html;
    rpiv_status st;
    if ((st = demo_path(c, "report.md", pmd, sizeof pmd)) ||
        (st = demo_path(c, "report.html", phtml, sizeof phtml)) || (st = atomic_begin(&md, pmd, 1)))
        return st;
    if ((st = atomic_begin(&html, phtml, 1))) {
        atomic_abort(&md);
        return st;
    }
    rep r = {md.fp, html.fp, RPIV_OK};
    fputs("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
          "<title>rpiv demo report</title>\n<style>\n"
          "body{font-family:sans-serif;max-width:60em;margin:auto;padding:1em;line-height:1.4}\n"
          "table{border-collapse:collapse}td,th{border:1px solid #999;padding:.3em .6em;"
          "vertical-align:top}\nimg{max-width:100%}figure{margin:1em 0}"
          "figcaption{font-style:italic}\n</style></head><body>\n",
          r.html);
    write_body(&r, c);
    fputs("</body></html>\n", r.html);
    if (r.st) {
        atomic_abort(&md);
        atomic_abort(&html);
        return r.st;
    }
    if ((st = atomic_commit(&md))) {
        atomic_abort(&html);
        return st;
    }
    return atomic_commit(&html);
}

rpiv_status demo_report(demo_ctx *c)
{
    rpiv_status st;
    demo_note(c, "step 6/6: plots and report");
    if ((st = demo_plots(c)))
        return st;
    return write_report(c);
}
