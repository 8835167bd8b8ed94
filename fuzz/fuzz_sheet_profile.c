/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz the light-sheet profile reader: rpiv_sheet_new on a self-similar sheet whose shape
 * table is the input ("# rpiv-sheet 1" files, sheet.h).
 * Invariants: a sheet that loads evaluates to a finite I0 in [0, 1.0001] (the reader accepts
 * table values up to 1.0001) everywhere in the channel, for x* from 0 to 10; a failure
 * names the file. */
#include "fuzz.h"
#include "rpiv/sheet.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready;
    if (!ready) {
        rpiv_init();
        ready = 1;
    }
    const char *path = fuzz_file(data, size, ".sheet");
    if (!path)
        return 0;
    rpiv_sheet_params sp = rpiv_sheet_params_default();
    sp.kind = RPIV_SHEET_SELFSIM;
    snprintf(sp.profile, sizeof sp.profile, "%s", path);
    rpiv_sheet *s = (rpiv_sheet *)&s;
    rpiv_status st = rpiv_sheet_new(&sp, &s);
    if (st != RPIV_OK) {
        FUZZ_CHECK(s == NULL, "failure left a sheet");
        fuzz_check_failure(st, path);
        return 0;
    }
    static const double xs[] = {0, 0.3187, 1.73, 4.1, 6.5, 10};
    for (size_t i = 0; i < sizeof xs / sizeof *xs; i++)
        for (int k = 0; k <= 64; k++) {
            double z = k / 64.0, v = rpiv_sheet_eval(s, xs[i], z);
            FUZZ_CHECK(isfinite(v) && v >= 0 && v <= 1.0001, "I0(%g, %g) = %g", xs[i], z, v);
        }
    rpiv_sheet_free(s);
    return 0;
}
