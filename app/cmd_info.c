/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv info - not implemented yet (placeholder until its issue lands). */
#include "cli.h"

rpiv_status cmd_info(int argc, char **argv);

rpiv_status cmd_info(int argc, char **argv)
{
    (void)argc;
    return rpiv_fail(RPIV_EINVAL, "%s: not implemented yet", argv[0]);
}
