/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "rpiv/sheet.h"

#include <string.h>
#include <unistd.h>

static void gauss_sheet_has_quarter_height_at_half_thickness(void)
{
    rpiv_sheet_params p = rpiv_sheet_params_default();
    p.kind = RPIV_SHEET_GAUSS;
    p.zb_star = 0.3187;
    p.e_star = 0.19;
    rpiv_sheet *s;
    CHECK_OK(rpiv_sheet_new(&p, &s));
    CHECK_NEAR(rpiv_sheet_eval(s, 2.0, 0.3187), 1.0, 1e-15);
    CHECK_NEAR(rpiv_sheet_eval(s, 2.0, 0.3187 + 0.095), 0.25, 1e-12);
    CHECK_NEAR(rpiv_sheet_eval(s, 5.0, 0.3187 - 0.095), 0.25, 1e-12);
    CHECK(rpiv_sheet_eval(s, 5.0, -0.01) == 0 && rpiv_sheet_eval(s, 5.0, 1.01) == 0);
    rpiv_sheet_free(s);
}

static void selfsim_default_shape_has_its_thickness_and_peak(void)
{
    rpiv_sheet_params p = rpiv_sheet_params_default();
    rpiv_sheet *s;
    CHECK_OK(rpiv_sheet_new(&p, &s));
    for (double x = 2.0; x <= 6.0; x += 1.3187) {
        double z[2001], in[2001];
        for (int i = 0; i <= 2000; i++) {
            z[i] = i / 2000.0;
            in[i] = rpiv_sheet_eval(s, x, z[i]);
        }
        rpiv_sheet_metrics m;
        CHECK_OK(rpiv_sheet_metrics_of(z, in, 2001, &m));
        double e = p.e0 + p.e1 * x, zm = p.zm0 + p.zm1 * x;
        CHECK_NEAR(m.zmax, zm, 1e-3);
        CHECK_NEAR(m.e, e, 1e-3);
        /* asymmetric: the lower half-width is skew times the upper one */
        CHECK_NEAR((zm - m.zinf) / (m.zsup - zm), p.skew, 0.02);
    }
    rpiv_sheet_free(s);
}

static void profile_file_round_trips(void)
{
    char path[] = "/tmp/rpiv-sheet-XXXXXX";
    int fd = mkstemp(path);
    close(fd);
    double zp[5] = {-0.8, -0.3, 0.0, 0.2, 0.6}, in[5] = {0.0, 0.5, 1.0, 0.25, 0.0};
    CHECK_OK(rpiv_sheet_save_profile(path, 0.01, 0.06, 0.02, 0.08, zp, in, 5));
    rpiv_sheet_params p = rpiv_sheet_params_default();
    strcpy(p.profile, path);
    rpiv_sheet *s;
    CHECK_OK(rpiv_sheet_new(&p, &s));
    /* at x* = 4: e* = 0.25, z*_max = 0.34; z+ = 0.1 -> halfway between 1.0 and 0.25 */
    CHECK_NEAR(rpiv_sheet_eval(s, 4.0, 0.34), 1.0, 1e-12);
    CHECK_NEAR(rpiv_sheet_eval(s, 4.0, 0.34 + 0.1 * 0.25), 0.625, 1e-12);
    CHECK_NEAR(rpiv_sheet_eval(s, 4.0, 0.34 + 0.7 * 0.25), 0.0, 0);
    rpiv_sheet_free(s);
    remove(path);
}

static void bad_profile_files_are_refused(void)
{
    const char *cases[] = {
        "0 1\n1 0.5\n2 0\n", "# rpiv-sheet 1\n0 1\n1 0.5\n", "# rpiv-sheet 1\n0 1\n1 0.5\n0.5 0\n",
        "# rpiv-sheet 1\n0 1\nx y\n2 0\n", "# rpiv-sheet 1\n0 1\n1 1.5\n2 0\n",
        /* trailing junk, a third column, a number after a long run of blanks, a NUL */
        "# rpiv-sheet 1\n0 1\n1 0.5 cm\n2 0\n", "# rpiv-sheet 1\n0 1\n1 0.5 0.25\n2 0\n",
        "# rpiv-sheet 1\n0 1\n1 0.5"
        "                                                                  "
        "                                                                  "
        "                                                                  "
        "                                                                  "
        "                                                                  "
        "                                                                  "
        "                                                                  "
        "                                                                  "
        "  1\n2 0\n",
        "# rpiv-sheet 1\n0 1\n1 0.5\0 7\n2 0\n"};
    /* the last case holds a NUL: its length is that of the literal */
    const size_t nul_len = sizeof "# rpiv-sheet 1\n0 1\n1 0.5\0 7\n2 0\n" - 1;
    const size_t ncases = sizeof cases / sizeof cases[0];
    for (size_t i = 0; i < ncases; i++) {
        char path[] = "/tmp/rpiv-sheet-XXXXXX";
        int fd = mkstemp(path);
        size_t len = i + 1 == ncases ? nul_len : strlen(cases[i]);
        CHECK(write(fd, cases[i], len) == (ssize_t)len);
        close(fd);
        rpiv_sheet_params p = rpiv_sheet_params_default();
        strcpy(p.profile, path);
        rpiv_sheet *s = NULL;
        CHECK_FAILS(rpiv_sheet_new(&p, &s), RPIV_EFORMAT);
        CHECK(s == NULL);
        CHECK(strstr(rpiv_errmsg(), path) != NULL);
        remove(path);
    }
    rpiv_sheet_params p = rpiv_sheet_params_default();
    strcpy(p.profile, "/nonexistent/profile.txt");
    rpiv_sheet *s = NULL;
    CHECK_FAILS(rpiv_sheet_new(&p, &s), RPIV_EIO);
}

static void metrics_fail_when_the_profile_is_cut(void)
{
    double z[5] = {0, 0.25, 0.5, 0.75, 1}, in[5] = {1, 0.8, 0.5, 0.3, 0.1};
    rpiv_sheet_metrics m;
    CHECK_FAILS(rpiv_sheet_metrics_of(z, in, 5, &m), RPIV_ENUMERIC);
}

int main(void)
{
    rpiv_init();
    RUN_TEST(gauss_sheet_has_quarter_height_at_half_thickness);
    RUN_TEST(selfsim_default_shape_has_its_thickness_and_peak);
    RUN_TEST(profile_file_round_trips);
    RUN_TEST(bad_profile_files_are_refused);
    RUN_TEST(metrics_fail_when_the_profile_is_cut);
    return check_summary();
}
