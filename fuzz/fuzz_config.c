/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz the strict INI configuration reader. */
#include "fuzz.h"
#include "rpiv/config.h"

#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready;
    if (!ready) {
        rpiv_init();
        ready = 1;
    }
    const char *path = fuzz_file(data, size, ".ini");
    if (!path)
        return 0;
    rpiv_experiment e = rpiv_experiment_default();
    if (rpiv_config_load(path, &e) == RPIV_OK) {
        /* whatever loads must check clean and print */
        FILE *null = fopen("/dev/null", "w");
        if (rpiv_experiment_check(&e) != RPIV_OK || rpiv_config_write(&e, null) != RPIV_OK)
            __builtin_trap();
        fclose(null);
    } else if (strlen(rpiv_errmsg()) == 0) {
        __builtin_trap(); /* a failure must carry a message */
    }
    return 0;
}
