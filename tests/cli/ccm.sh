#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv ccm: every scenario runs and writes its table with the figures of docs/ccm.md; the
# inversion of the model's own R-PIV prediction recovers the duct; bad input gives one stderr
# line, exit 2 for usage and 1 for files.
set -u
bin=${RPIV_BIN:?}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }

# value of "max |err| = X %" for a summary line matching $2 in file $1
maxerr() { grep "$2" "$1" | sed -n 's/.*max |err| = \([0-9.]*\) %.*/\1/p' | head -1; }
# is $1 within [$2, $3]?
within() { awk -v x="$1" -v a="$2" -v b="$3" 'BEGIN { exit !(x != "" && x >= a && x <= b) }'; }

np="--set output.plots=0"
# the paper's figures: its model of continuous (point-sampled) particle images
paper="--set bias.pixel_box=0"
"$bin" ccm ppiv-scan -q -o "$tmp" $np $paper >"$tmp/scan.out" && ok || ko "ppiv-scan"
[ -s "$tmp/ccm_ppiv-scan_e0.05.txt" ] && [ -s "$tmp/ccm_ppiv-scan_e0.19.txt" ] && ok || ko "ppiv-scan tables"
within "$(maxerr "$tmp/scan.out" 'e\*=0.05')" 0.02 0.1 && ok || ko "ppiv-scan e*=0.05: $(cat "$tmp/scan.out")"
within "$(maxerr "$tmp/scan.out" 'e\*=0.19')" 3 8 && ok || ko "ppiv-scan e*=0.19"
[ "$(grep -vc '^#' "$tmp/ccm_ppiv-scan_e0.05.txt")" -eq 15 ] && ok || ko "15 positions"
grep -q '^# rpiv-ccm 1$' "$tmp/ccm_ppiv-scan_e0.05.txt" && ok || ko "table magic"

"$bin" ccm ppiv-fixed -q -o "$tmp" --thickness 0.19 $np $paper >"$tmp/fixed.out" && ok || ko "ppiv-fixed"
within "$(maxerr "$tmp/fixed.out" 'e\*=0.19')" 18 23 && ok || ko "ppiv-fixed e*=0.19: $(cat "$tmp/fixed.out")"

"$bin" ccm rpiv -q -o "$tmp" $paper >"$tmp/rpiv.out" && ok || ko "rpiv"
for f in ccm_rpiv_profile.png ccm_rpiv_error.png; do
    [ "$(head -c 4 "$tmp/$f" | od -An -c | tr -d ' ')" = '211PNG' ] && ok || ko "$f is not a PNG"
done
within "$(maxerr "$tmp/rpiv.out" rpiv)" 7 9 && ok || ko "rpiv: $(cat "$tmp/rpiv.out")"
[ "$(grep -vc '^#' "$tmp/ccm_rpiv.txt")" -eq 31 ] && ok || ko "rpiv rows (16 + 15 mirrored)"

"$bin" ccm convergence -q -o "$tmp" --repeats 4 --nim 1,10,50 $np >"$tmp/conv.out" && ok || ko "convergence"
[ "$(grep -vc '^#' "$tmp/ccm_convergence.txt")" -eq 3 ] && ok || ko "convergence rows"
# same seed, other thread count: identical file
"$bin" ccm convergence -q -o "$tmp/t1" -j 1 --repeats 4 --nim 1,10,50 $np >/dev/null && \
    cmp -s "$tmp/ccm_convergence.txt" "$tmp/t1/ccm_convergence.txt" && ok || ko "convergence depends on threads"

# invert the model's own prediction (object plane 0.5 as in the rpiv scenario; the same model)
awk '!/^#/ && $8 == 0 { print $1, $4 }' "$tmp/ccm_rpiv.txt" >"$tmp/meas.txt"
"$bin" ccm invert -q -o "$tmp" --input "$tmp/meas.txt" --zop 0.5 --symmetric --compare $np $paper >"$tmp/inv.out" && ok || ko "invert"
e1c=$(sed -n 's/.*corrected \([0-9.]*\) %.*/\1/p' "$tmp/inv.out")
e1a=$(sed -n 's/.*association (U at z\*_max) \([0-9.]*\) %.*/\1/p' "$tmp/inv.out")
# (2.14 % with the geometric defocus of the paper, 1.96 % with the apparent depth, n_medium 1.33)
within "$e1a" 1.8 2.3 && ok || ko "association E1 '$e1a'"
within "$e1c" 0 0.1 && ok || ko "corrected E1 '$e1c': $(cat "$tmp/inv.out")"
[ "$(grep -vc '^#' "$tmp/ccm_invert.txt")" -eq 129 ] && ok || ko "invert rows"

# a vector file of rpiv piv as input: the row at y* = 0.5 of a full-sensor field, placed as
# rpiv synth places it (x* = 1 + (x + 0.5) pixel / (M h)); u = 1.5 U_b in px
awk 'BEGIN { print "# rpiv vector field 1"; s = 3.495903614
    for (y = 1040; y <= 1104; y += 32) for (x = 16; x < 2560; x += 32)
        printf "%d %d %.6f 0 0 5 0.8\n", x, y, 1.5 * s }' >"$tmp/field.txt"
"$bin" ccm invert -q -o "$tmp/f" --input "$tmp/field.txt" --symmetric $np >/dev/null && ok || ko "invert from a vector file"
first=$(grep '^#m' "$tmp/f/ccm_invert.txt" | head -1)
x1=$(echo "$first" | awk '{print $2}'); u1=$(echo "$first" | awk '{print $4}')
within "$x1" 1.0342 1.0344 && within "$u1" 1.49999 1.50001 && ok || ko "vector file mapping: $first"
[ "$(grep -c '^#m' "$tmp/f/ccm_invert.txt")" -eq 80 ] && ok || ko "80 vectors in the row"
# --measured: the engine's estimate on its window is fitted, and the file says so
"$bin" ccm invert -q -o "$tmp/fm" --input "$tmp/field.txt" --symmetric --measured $np >/dev/null &&
    grep -q '^# forward model: the engine' "$tmp/fm/ccm_invert.txt" &&
    grep -q 'measured = 1' "$tmp/fm/ccm_invert.txt" && ok || ko "invert --measured"

# errors: usage -> 2, files -> 1, one line on stderr naming the culprit
check() { # expected-rc expected-substring args...
    local rc_want=$1 pat=$2; shift 2
    "$bin" ccm "$@" >/dev/null 2>"$tmp/err"
    local rc=$?
    if [ "$rc" -eq "$rc_want" ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && grep -q -- "$pat" "$tmp/err"; then ok
    else ko "ccm $*: rc=$rc: $(cat "$tmp/err")"; fi
}
check 2 'missing SCENARIO' -q
check 2 "unknown scenario 'nosuch'" nosuch
check 2 'invert needs --input' invert -o "$tmp"
check 2 "'abc' is not a number" rpiv --zop abc
check 2 '--range' ppiv-scan --range 0.1,0.9
check 2 'increasing' convergence --nim 10,5 -o "$tmp"
check 2 'positions' ppiv-scan --range 0.5,0.4,10 -o "$tmp"
check 2 'thickness' ppiv-scan --thickness 0 -o "$tmp"
check 1 'nosuch.txt' invert --input "$tmp/nosuch.txt" -o "$tmp"
printf '0.5 1.0\n0.4 x\n' >"$tmp/bad.txt"
check 1 'bad.txt:2' invert --input "$tmp/bad.txt" -o "$tmp"
check 1 'bad.txt' rpiv --profile "$tmp/bad.txt" -o "$tmp"
check 2 'unexpected argument' rpiv extra
check 2 'outside the vector field' invert --input "$tmp/field.txt" --ystar 0.9 -o "$tmp/f"
"$bin" ccm --help | grep -q '^usage: rpiv ccm' && ok || ko "--help"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
