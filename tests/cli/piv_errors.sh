#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv piv, bad input: mismatched pair sizes, a window larger than the image or the ROI, an
# unknown option, bad option values, a missing file -> non-zero exit and exactly one stderr
# line that names the fault.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
data=${RPIV_TEST_DATA:?RPIV_TEST_DATA not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
a="$data/Oseen_center_01.tif"   # 400 x 300
b="$data/Oseen_center_02.tif"
small="$data/exp1_001_a_crop64x48.bmp"

check() { # expected-exit expected-substring args...
    local want=$1 word=$2 rc
    shift 2
    "$bin" piv --quiet "$@" >"$tmp/out" 2>"$tmp/err"
    rc=$?
    if [ "$rc" -ne "$want" ]; then
        echo "FAIL: rpiv piv $*: exit $rc, expected $want: $(cat "$tmp/err")" >&2; fail=$((fail + 1)); return
    fi
    if [ "$(wc -l <"$tmp/err")" -ne 1 ]; then
        echo "FAIL: rpiv piv $*: stderr is not one line:" >&2; cat "$tmp/err" >&2; fail=$((fail + 1)); return
    fi
    if ! grep -q -- "$word" "$tmp/err"; then
        echo "FAIL: rpiv piv $*: message lacks '$word': $(cat "$tmp/err")" >&2; fail=$((fail + 1)); return
    fi
    pass=$((pass + 1))
}

# frames of different sizes: both files named
check 1 "exp1_001_a_crop64x48.bmp" "$a" "$small" -o "$tmp/x.txt"
check 1 "Oseen_center_01.tif" "$a" "$small" -o "$tmp/x.txt"
# a window larger than the image, or than the ROI: usage errors (exit 2)
check 2 "larger than the image" "$a" "$b" --window 512 -o "$tmp/x.txt"
check 2 "larger than the image" "$a" "$b" --window 64x320,32 -o "$tmp/x.txt"
check 2 "larger than the ROI" "$a" "$b" --roi 10,10,50,290 -o "$tmp/x.txt"
check 2 "piv.roi" "$a" "$b" --roi 10,10,500,290 -o "$tmp/x.txt"
# issue 20 item 7: integers past 2^32 wrapped into range (used as 0,0,400,200)
check 2 "piv.roi" "$a" "$b" --roi 0,0,4294967696,4294967496 -o "$tmp/x.txt"
check 2 "checkpoint-every" "$a" "$b" --ensemble --checkpoint "$tmp/c" --checkpoint-every -1 -o "$tmp/x.txt"
check 2 "checkpoint-every" "$a" "$b" --ensemble --checkpoint "$tmp/c" --checkpoint-every 18446744073709551617 -o "$tmp/x.txt"
# issue 20 item 8: a FIFO given as an image hung in open()
mkfifo "$tmp/fifo.tif"
timeout 10 "$bin" piv --quiet "$tmp/fifo.tif" "$b" -o "$tmp/x.txt" >/dev/null 2>"$tmp/err"
rc=$?
if [ "$rc" -eq 1 ] && grep -q "not a regular file" "$tmp/err"; then pass=$((pass + 1))
else echo "FAIL: piv on a FIFO: exit $rc: $(cat "$tmp/err")" >&2; fail=$((fail + 1)); fi
# unknown option, bad values
check 2 "unknown option '--bogus'" "$a" "$b" --bogus -o "$tmp/x.txt"
check 2 "overlap" "$a" "$b" --overlap 0.99 -o "$tmp/x.txt"
check 2 "window" "$a" "$b" --window 64,abc -o "$tmp/x.txt"
check 2 "subpixel" "$a" "$b" --subpixel bicubic -o "$tmp/x.txt"
check 2 "validate" "$a" "$b" --validate mean:3 -o "$tmp/x.txt"
check 2 "background" "$a" "$b" --background max -o "$tmp/x.txt"
check 2 "pairing" "$a" "$b" --pairing random -o "$tmp/x.txt"
check 2 "extension" "$a" "$b" -o "$tmp/x.csv"
check 2 "no output" "$a" "$b"
check 2 "no image pairs" -o "$tmp/x.txt"
check 2 "mean-rms" "$a" "$b" --ensemble --mean-rms -o "$tmp/x.txt"
# missing files: the pair file, the mask
check 1 "nosuch.tif" "$a" "$tmp/nosuch.tif" -o "$tmp/x.txt"
check 1 "nomask.png" "$a" "$b" --mask "$tmp/nomask.png" -o "$tmp/x.txt"
# a mask of another size
check 2 "mask" "$a" "$b" --mask "$small" -o "$tmp/x.txt"
# an unwritable output
check 1 "$tmp/nodir/x.txt" "$a" "$b" --window 64 -o "$tmp/nodir/x.txt"
[ -e "$tmp/x.txt" ] && { echo "FAIL: an output was written by a failing run" >&2; fail=$((fail + 1)); }
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
