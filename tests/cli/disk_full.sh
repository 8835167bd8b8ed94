#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Issue #20 items 1 and 2: a figure (--plot) or a NetCDF file written to a full disk exits 1
# with one line naming the file and "No space left on device", no crash, and the old file
# left intact. Needs a small tmpfs (256 kB: room for the 1000 x 800 figure of rpiv plot):
# mounted when run as root, skipped (77) otherwise.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
data=${RPIV_TEST_DATA:?RPIV_TEST_DATA not set}
tmp=$(mktemp -d)
full="$tmp/full"
mkdir "$full"
if ! mount -t tmpfs -o size=256k tmpfs "$full" 2>/dev/null; then
    rm -rf "$tmp"
    echo "disk_full: skipped: cannot mount a tmpfs (needs root)"
    exit 77
fi
trap 'umount "$full"; rm -rf "$tmp"' EXIT
printf 'leak:libfontconfig.so\n' >"$tmp/lsan.supp"
export LSAN_OPTIONS="suppressions=$tmp/lsan.supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
a="$data/Oseen_center_01.tif"
b="$data/Oseen_center_02.tif"

# the disk filled to several levels: nothing left, a few kB left (a truncated write)
for kb in 254 244 232; do # 2, 12, 24 kB left
    rm -f "$full"/*
    echo old >"$full/p.png"
    echo old >"$full/o.nc"
    dd if=/dev/zero of="$full/fill" bs=1k count=$kb 2>/dev/null
    "$bin" piv --quiet "$a" "$b" -o "$tmp/one.txt" --plot "$full/p.png" 2>"$tmp/err"
    rc=$?
    [ "$rc" -eq 1 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] &&
        grep -q "$full/p.png: .*No space left on device" "$tmp/err" && ok ||
        ko "plot, ${kb} kB filled: rc=$rc $(cat "$tmp/err")"
    [ "$(cat "$full/p.png")" = old ] && ok || ko "plot, ${kb} kB filled: old file replaced"
    "$bin" piv --quiet "$a" "$b" -o "$full/o.nc" 2>"$tmp/err"
    rc=$?
    [ "$rc" -eq 1 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] &&
        grep -q "$full/o.nc: .*No space left on device" "$tmp/err" && ok ||
        ko "nc, ${kb} kB filled: rc=$rc $(cat "$tmp/err")"
    [ "$(cat "$full/o.nc")" = old ] && ok || ko "nc, ${kb} kB filled: old file replaced"
    [ "$(ls "$full" | wc -l)" -eq 3 ] && ok || ko "temporary files left: $(ls "$full")"
done
# with room, both are written
rm -f "$full"/*
"$bin" piv --quiet "$a" "$b" -o "$full/o.nc" && [ "$(head -c 4 "$full/o.nc" | od -An -c | tr -d ' ')" = '211HDF' ] && ok || ko "nc with room"
rm -f "$full"/*
"$bin" piv --quiet "$a" "$b" -o "$tmp/one.txt" --plot "$full/p.png" && [ -s "$full/p.png" ] && ok || ko "plot with room"

echo "disk_full: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
