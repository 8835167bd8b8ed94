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

"$bin" ccm ppiv-scan -q -o "$tmp" >"$tmp/scan.out" && ok || ko "ppiv-scan"
[ -s "$tmp/ccm_ppiv-scan_e0.05.txt" ] && [ -s "$tmp/ccm_ppiv-scan_e0.19.txt" ] && ok || ko "ppiv-scan tables"
within "$(maxerr "$tmp/scan.out" 'e\*=0.05')" 0.02 0.1 && ok || ko "ppiv-scan e*=0.05: $(cat "$tmp/scan.out")"
within "$(maxerr "$tmp/scan.out" 'e\*=0.19')" 3 8 && ok || ko "ppiv-scan e*=0.19"
[ "$(grep -vc '^#' "$tmp/ccm_ppiv-scan_e0.05.txt")" -eq 15 ] && ok || ko "15 positions"
grep -q '^# rpiv-ccm 1$' "$tmp/ccm_ppiv-scan_e0.05.txt" && ok || ko "table magic"

"$bin" ccm ppiv-fixed -q -o "$tmp" --thickness 0.19 >"$tmp/fixed.out" && ok || ko "ppiv-fixed"
within "$(maxerr "$tmp/fixed.out" 'e\*=0.19')" 18 23 && ok || ko "ppiv-fixed e*=0.19: $(cat "$tmp/fixed.out")"

"$bin" ccm rpiv -q -o "$tmp" >"$tmp/rpiv.out" && ok || ko "rpiv"
within "$(maxerr "$tmp/rpiv.out" rpiv)" 7 9 && ok || ko "rpiv: $(cat "$tmp/rpiv.out")"
[ "$(grep -vc '^#' "$tmp/ccm_rpiv.txt")" -eq 31 ] && ok || ko "rpiv rows (16 + 15 mirrored)"

"$bin" ccm convergence -q -o "$tmp" --repeats 4 --nim 1,10,50 >"$tmp/conv.out" && ok || ko "convergence"
[ "$(grep -vc '^#' "$tmp/ccm_convergence.txt")" -eq 3 ] && ok || ko "convergence rows"
# same seed, other thread count: identical file
"$bin" ccm convergence -q -o "$tmp/t1" -j 1 --repeats 4 --nim 1,10,50 >/dev/null && \
    cmp -s "$tmp/ccm_convergence.txt" "$tmp/t1/ccm_convergence.txt" && ok || ko "convergence depends on threads"

# invert the model's own prediction (object plane 0.5 as in the rpiv scenario)
awk '!/^#/ && $8 == 0 { print $1, $4 }' "$tmp/ccm_rpiv.txt" >"$tmp/meas.txt"
"$bin" ccm invert -q -o "$tmp" --input "$tmp/meas.txt" --zop 0.5 --symmetric --compare >"$tmp/inv.out" && ok || ko "invert"
e1c=$(sed -n 's/.*corrected \([0-9.]*\) %.*/\1/p' "$tmp/inv.out")
e1a=$(sed -n 's/.*association (U at z\*_max) \([0-9.]*\) %.*/\1/p' "$tmp/inv.out")
within "$e1a" 2 2.3 && ok || ko "association E1 '$e1a'"
within "$e1c" 0 0.1 && ok || ko "corrected E1 '$e1c': $(cat "$tmp/inv.out")"
[ "$(grep -vc '^#' "$tmp/ccm_invert.txt")" -eq 129 ] && ok || ko "invert rows"

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
"$bin" ccm --help | grep -q '^usage: rpiv ccm' && ok || ko "--help"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
