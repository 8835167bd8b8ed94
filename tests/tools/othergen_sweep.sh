#!/bin/bash
# SPDX-License-Identifier: GPL-3.0-or-later
# The 45 cases of docs/uncertainty.md, "Session 14": 5 flows x particle images of 1.5, 2.2, 3 px
# x noise 0, 3, 8 %, 3 pairs each of 384 x 384 px from tests/tools/othergen.py, run by
# `rpiv piv --uncertainty` with the defaults (or OPTIONS), one line of coverage per case.
# usage: tests/tools/othergen_sweep.sh RPIV_BINARY WORKDIR [rpiv piv OPTIONS...]
set -u
bin=$1 work=$2
shift 2
tool=$(dirname "$0")/othergen.py
mkdir -p "$work/img" "$work/out"
for fl in uniform rot tg oseen jet; do
    for d in 1.5 2.2 3.0; do
        for nz in 0 0.03 0.08; do
            files=""
            for s in 1 2 3; do
                p="$work/img/${fl}_${d}_${nz}_$s"
                [ -f "${p}_b.pgm" ] || /usr/bin/python3 "$tool" make "$fl" 384 "$d" "$nz" "$s" "$p"
                o="$work/out/${fl}_${d}_${nz}_$s.txt"
                "$bin" piv --uncertainty "$@" "${p}_a.pgm" "${p}_b.pgm" -o "$o" >/dev/null ||
                    exit 1
                files="$files $o"
            done
            # shellcheck disable=SC2086
            echo "$fl d=$d noise=$nz $(/usr/bin/python3 "$tool" cover "$fl" 384 $files)"
        done
    done
done
