/* SPDX-License-Identifier: GPL-3.0-or-later */
/* A program outside the tree that uses the installed library: the duct centre velocity. */
#include <rpiv/rpiv.h>

#include <math.h>
#include <stdio.h>

int main(void)
{
    rpiv_init();
    double u = rpiv_duct_u(0.5, 0.5);
    printf("rpiv %s: U*(0.5, 0.5) = %.4f\n", RPIV_VERSION_STRING, u);
    return fabs(u - 2.096) < 0.001 ? 0 : 1;
}
