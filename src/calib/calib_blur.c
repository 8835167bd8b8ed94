/* SPDX-License-Identifier: GPL-3.0-or-later */
/* How the camera sees a target (calib_impl.h): the object-space scale, the blur of Eq. "diam"
 * without its geometric term, and that blur integrated over pixels for a bar, an ellipse (a dot)
 * and a lattice of dots. Used by the depth-of-focus model and the rendered targets. */
#include "calib_impl.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_integration.h>

#include <math.h>
#include <stdlib.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ---- optics helpers ------------------------------------------------------------------------ */

double calib_scale(double scale_px_m, const rpiv_camera *cam)
{
    return scale_px_m > 0 ? scale_px_m : cam->magnification / rpiv_camera_pixel_m(cam);
}

double calib_blur_px(const rpiv_camera *cam, double h_m, double scale, double zstar)
{
    double zdef = rpiv_imaging_defocus_m(cam, h_m, zstar);
    double sig_sensor = rpiv_imaging_sigma_m(cam, rpiv_imaging_de_m(cam, 0, zdef));
    /* sensor metres -> image pixels: the sensor pixel is M / scale */
    return sig_sensor * scale / cam->magnification;
}

/* Upper tail Q(x) = 1 - Phi(x), accurate for large x. */
static double upper(double x)
{
    return 0.5 * erfc(x / M_SQRT2);
}

double calib_boxg(double u, double s)
{
    double a = (u - 0.5) / s, b = (u + 0.5) / s;
    /* Phi(b) - Phi(a) written with the tail that does not cancel */
    if (a > 0)
        return upper(a) - upper(b);
    return upper(-b) - upper(-a);
}

/* F(x) = integral of Phi from -inf to x = x Phi(x) + phi(x); F(x) = x + F(-x). */
static double phi_int(double x)
{
    double ax = -fabs(x);
    double f = ax * upper(-ax) + exp(-0.5 * ax * ax) / sqrt(2 * M_PI);
    return x > 0 ? x + f : f;
}

double calib_boxg_bar(double u, double w, double s)
{
    if (!(w > 0))
        return 0;
    double a = (u + w + 0.5) / s, b = (u - w + 0.5) / s, c = (u + w - 0.5) / s,
           d = (u - w - 0.5) / s;
    double v = s * (phi_int(a) - phi_int(b) - phi_int(c) + phi_int(d));
    return v > 0 ? v : 0;
}

rpiv_status calib_gl_init(calib_gl *gl)
{
    gsl_integration_glfixed_table *t = gsl_integration_glfixed_table_alloc(CALIB_GL_BASE);
    if (!t)
        return rpiv_fail(RPIV_ENOMEM, "calib: out of memory (quadrature table)");
    for (size_t i = 0; i < CALIB_GL_BASE; i++)
        gsl_integration_glfixed_point(-1, 1, i, &gl->x[i], &gl->w[i], t);
    gsl_integration_glfixed_table_free(t);
    return RPIV_OK;
}

/* Nodes in theta for an ellipse of row semi-axis ay blurred by s: the pixel-row term varies
 * over about s / ay in theta, so the panels are made that narrow (within limits). */
static int gl_nodes(const calib_gl *gl, double ay, double s, double *theta, double *weight)
{
    double want = ceil(ay / (2 * fmax(s, 1e-3)));
    int np = want < 4 ? 4 : want > CALIB_GL_PANELS ? CALIB_GL_PANELS : (int)want;
    double hw = M_PI / (2 * np); /* panel half-width */
    int n = 0;
    for (int p = 0; p < np; p++) {
        double c = -M_PI / 2 + (2 * p + 1) * hw;
        for (int k = 0; k < CALIB_GL_BASE; k++, n++) {
            theta[n] = c + hw * gl->x[k];
            weight[n] = hw * gl->w[k];
        }
    }
    return n;
}

/* The ellipse is integrated row by row: qy = ay sin(theta), so the half-width of the row is
 * ax cos(theta) and dqy = ay cos(theta) dtheta; the integrand is smooth in theta. */
void calib_ellipse_add(const calib_gl *gl, double cx, double cy, double ax, double ay, double s,
                       int x0, int y0, int nx, int ny, double scale, double *out, double *work)
{
    double theta[CALIB_GL_MAX], weight[CALIB_GL_MAX];
    int K = gl_nodes(gl, ay, s, theta, weight);
    double *col = work, *row = work + (size_t)nx * K;
    for (int i = 0; i < nx; i++)
        for (int k = 0; k < K; k++) {
            double c = cos(theta[k]);
            col[(size_t)i * K + k] = weight[k] * ay * c * calib_boxg_bar(x0 + i - cx, ax * c, s);
        }
    for (int j = 0; j < ny; j++)
        for (int k = 0; k < K; k++)
            row[(size_t)j * K + k] = calib_boxg(y0 + j - cy - ay * sin(theta[k]), s);
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double v = 0;
            const double *r = row + (size_t)j * K, *c = col + (size_t)i * K;
            for (int k = 0; k < K; k++)
                v += r[k] * c[k];
            out[(size_t)j * nx + i] += scale * v;
        }
}

double calib_ellipse_at(const calib_gl *gl, double cx, double cy, double ax, double ay, double s,
                        double px, double py)
{
    double theta[CALIB_GL_MAX], weight[CALIB_GL_MAX], v = 0;
    int K = gl_nodes(gl, ay, s, theta, weight);
    for (int k = 0; k < K; k++) {
        double c = cos(theta[k]);
        v += weight[k] * ay * c * calib_boxg(py - cy - ay * sin(theta[k]), s) *
             calib_boxg_bar(px - cx, ax * c, s);
    }
    return v;
}

double calib_lattice_pixel(const calib_gl *gl, double ax, double ay, double ppx, double ppy,
                           double s, const double *node, const double *wt, int n)
{
    /* For one ellipse row (node theta), the row term depends only on the lattice row j and the
     * column term only on the lattice column i, so the lattice sum and the phase average
     * factor into two 1-D sums per node. */
    double theta[CALIB_GL_MAX], weight[CALIB_GL_MAX], v = 0;
    int K = gl_nodes(gl, ay, s, theta, weight);
    int kx = (int)ceil((ax + 6 * s + 2) / ppx), ky = (int)ceil((ay + 6 * s + 2) / ppy);
    for (int k = 0; k < K; k++) {
        double c = cos(theta[k]), sy = ay * sin(theta[k]), wx = ax * c, ry = 0, rx = 0;
        for (int b = 0; b < n; b++)
            for (int j = -ky; j <= ky; j++)
                ry += wt[b] * calib_boxg(node[b] - j * ppy - sy, s);
        for (int a = 0; a < n; a++)
            for (int i = -kx; i <= kx; i++)
                rx += wt[a] * calib_boxg_bar(node[a] - i * ppx, wx, s);
        v += weight[k] * ay * c * ry * rx;
    }
    return v;
}
