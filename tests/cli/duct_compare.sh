#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv duct and rpiv compare: profile values at the centre and on the walls, symmetry, E1 of a
# file with itself (0) and with a copy scaled by 1.1 (0.1 for a uniform profile or field, and
# 0.1 sqrt(int U^2) / int U for the duct profile), PNG output, and bad input: exit != 0 and one
# stderr line naming the file or option.
set -u
bin=${RPIV_BIN:?}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# sanitizer builds: fontconfig's process-lifetime font caches (reached through PLplot's cairo
# driver) are never freed; they are not rpiv's leaks
printf 'leak:libfontconfig.so\n' >"$tmp/lsan.supp"
export LSAN_OPTIONS="suppressions=$tmp/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
# near A B TOL: |A - B| <= TOL
near() { awk -v a="$1" -v b="$2" -v t="$3" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= t) }'; }
# value KEY FILE: the number after KEY on a "KEY value" line
value() { awk -v k="$1" '$1 == k { print $2 }' "$2"; }
is_png() { [ "$(head -c 8 "$1" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]; }

# ---- duct ----------------------------------------------------------------------------------
"$bin" duct --y 0.5 --z 0:1:0.01 >"$tmp/z.txt" && ok || ko "duct along z"
[ "$(grep -vc '^#' "$tmp/z.txt")" -eq 101 ] && ok || ko "101 rows expected"
u_mid=$(awk '$1 == 0.5 { print $2 }' "$tmp/z.txt")
# the centre of the square duct: U_max / U_bulk = 2.0962 (the flow issue's figure 2.096)
near "$u_mid" 2.09626 5e-5 && ok || ko "centre U* = $u_mid, expected 2.0963"
[ "$(awk '$1 == 0 { print $2 }' "$tmp/z.txt")" = 0 ] && ok || ko "U* at z* = 0 not 0"
[ "$(awk '$1 == 1 { print $2 }' "$tmp/z.txt")" = 0 ] && ok || ko "U* at z* = 1 not 0"
a=$(awk '$1 == 0.3 { print $2 }' "$tmp/z.txt"); b=$(awk '$1 == 0.7 { print $2 }' "$tmp/z.txt")
near "$a" "$b" 1e-9 && ok || ko "profile not symmetric: $a vs $b"
# the other way: along y at z* = 0.5 goes through the same centre value; the default is y* = 0.5
"$bin" duct --z 0.5 --y 0:1:0.05 >"$tmp/y.txt" && ok || ko "duct along y"
[ "$(grep -vc '^#' "$tmp/y.txt")" -eq 21 ] && ok || ko "21 rows expected along y"
near "$(awk '$1 == 0.5 { print $2 }' "$tmp/y.txt")" "$u_mid" 1e-9 && ok || ko "y and z centres differ"
grep -q '^# y\* U\*$' "$tmp/y.txt" && ok || ko "header along y"
"$bin" duct >"$tmp/d.txt" && cmp -s "$tmp/d.txt" "$tmp/z.txt" && ok || ko "default differs from --y 0.5 --z 0:1:0.01"
# the square's symmetry: U*(y*=0.3, z*) = U*(y*=z, z*=0.3)
"$bin" duct --y 0.3 --z 0:1:0.1 | grep -v '^#' >"$tmp/a" && "$bin" duct --z 0.3 --y 0:1:0.1 | grep -v '^#' >"$tmp/b"
cmp -s "$tmp/a" "$tmp/b" && ok || ko "U*(y,z) != U*(z,y)"
"$bin" duct --z 0:1:0.02 --png "$tmp/duct.png" >/dev/null && is_png "$tmp/duct.png" && ok || ko "duct --png"

duct_err() { # expected-substring args...
    want=$1; shift
    "$bin" duct "$@" >/dev/null 2>"$tmp/err"; rc=$?
    if [ "$rc" -eq 2 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && grep -q -- "$want" "$tmp/err"; then ok
    else ko "duct $*: rc=$rc: $(cat "$tmp/err")"; fi
}
duct_err "step 0 must be > 0" --z 0:1:0
duct_err "neither a value nor START:STOP:STEP" --z 0:1
duct_err "stop 0.2 is below start 0.7" --z 0.7:0.2:0.1
duct_err "both ranges" --y 0:1:0.1 --z 0:1:0.1
duct_err "leaves the duct" --y 1.5
duct_err "start 'a' is not a number" --z a:1:0.1
duct_err "more than" --z 0:1:1e-9
duct_err "unknown option" --bogus
"$bin" duct --help | grep -q '^usage: rpiv duct' && ok || ko "duct --help"

# ---- compare: profiles ---------------------------------------------------------------------
"$bin" compare "$tmp/z.txt" "$tmp/z.txt" >"$tmp/out" && ok || ko "compare with itself"
[ "$(value E1 "$tmp/out")" = 0 ] && [ "$(value max "$tmp/out")" = 0 ] && ok || ko "E1 with itself: $(cat "$tmp/out")"
awk '/^#/ { print; next } { printf "%.12g %.12g\n", $1, 1.1 * $2 }' "$tmp/z.txt" >"$tmp/z11.txt"
"$bin" compare "$tmp/z.txt" "$tmp/z11.txt" --png "$tmp/cmp.png" >"$tmp/out" && ok || ko "compare scaled"
# Eq. "E1" with cmp = 1.1 ref: 0.1 sqrt(int U^2) / int U (trapezoids, alpha 0..1)
want=$(awk '!/^#/ { if (n++) { h = $1 - x; s2 += h * (u * u + $2 * $2) / 2; s1 += h * (u + $2) / 2 } x = $1; u = $2 }
            END { printf "%.9f", 0.1 * sqrt(s2) / s1 }' "$tmp/z.txt")
near "$(value E1 "$tmp/out")" "$want" 1e-6 && ok || ko "duct E1 $(value E1 "$tmp/out") != $want"
is_png "$tmp/cmp.png" && ok || ko "compare --png"
printf '# uniform\n0 2.5\n0.25 2.5\n0.5 2.5\n0.75 2.5\n1 2.5\n' >"$tmp/uni.txt"
printf '0 2.75\n0.4 2.75\n1 2.75\n' >"$tmp/uni11.txt"   # other alpha: interpolated
"$bin" compare "$tmp/uni.txt" "$tmp/uni11.txt" >"$tmp/out" && ok || ko "compare uniform"
near "$(value E1 "$tmp/out")" 0.1 1e-9 && ok || ko "uniform E1 $(value E1 "$tmp/out") != 0.1"
near "$(value RMS "$tmp/out")" 0.25 1e-9 && ok || ko "uniform RMS"
# a coarser grid of the same profile, interpolated: small E1, range limited to the overlap
"$bin" duct --z 0:1:0.037 >"$tmp/coarse.txt"
"$bin" compare "$tmp/z.txt" "$tmp/coarse.txt" >"$tmp/out" && ok || ko "compare coarse"
awk '$1 == "E1" { exit !($2 > 0 && $2 < 0.005) }' "$tmp/out" && ok || ko "coarse E1: $(cat "$tmp/out")"
grep -q '^range 0 0.99$' "$tmp/out" && ok || ko "coarse range: $(grep range "$tmp/out")"

# ---- compare: vector files -----------------------------------------------------------------
awk 'BEGIN { print "# x y u v flag"; for (j = 0; j < 5; j++) for (i = 0; i < 6; i++)
            printf "%d %d 3.3187 -1.25 0\n", 16 + 32 * i, 16 + 32 * j }' >"$tmp/f.txt"
awk '/^#/ { next } { printf "%s %s %.10g %.10g %s\n", $1, $2, 1.1 * $3, 1.1 * $4, $5 }' "$tmp/f.txt" >"$tmp/f11.txt"
"$bin" compare "$tmp/f.txt" "$tmp/f.txt" >"$tmp/out" && [ "$(value E1 "$tmp/out")" = 0 ] && ok || ko "field with itself"
"$bin" compare "$tmp/f.txt" "$tmp/f11.txt" >"$tmp/out" && ok || ko "field scaled"
near "$(value E1 "$tmp/out")" 0.1 1e-7 && ok || ko "field E1 $(value E1 "$tmp/out") != 0.1"
[ "$(value n "$tmp/out")" = 30 ] && [ "$(value component "$tmp/out")" = mag ] && ok || ko "field n/component"
"$bin" compare "$tmp/f.txt" "$tmp/f11.txt" --component v --png "$tmp/diff.png" >"$tmp/out" && ok || ko "field v"
near "$(value E1 "$tmp/out")" 0.1 1e-7 && near "$(value max "$tmp/out")" 0.125 1e-6 && ok || ko "field v: $(cat "$tmp/out")"
is_png "$tmp/diff.png" && ok || ko "field --png"

# ---- compare: bad input --------------------------------------------------------------------
cmp_err() { # expected-rc expected-substring args...
    want_rc=$1; want=$2; shift 2
    "$bin" compare "$@" >/dev/null 2>"$tmp/err"; rc=$?
    if [ "$rc" -eq "$want_rc" ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && grep -q -- "$want" "$tmp/err"; then ok
    else ko "compare $*: rc=$rc: $(cat "$tmp/err")"; fi
}
printf '0 1\n0.5 x\n1 1\n' >"$tmp/nonnum.txt"
printf '0 1\n0.5 1\n0.4 1\n' >"$tmp/nonmono.txt"
printf '2 1\n3 1\n' >"$tmp/far.txt"
printf '0 0 1 1 0\n32 0 1 1 0\n' >"$tmp/g2.txt"
printf '0 0 1 1\n32 0 1 1\n50 0 1 1\n' >"$tmp/offgrid.txt"
cmp_err 1 "missing.txt: cannot open" "$tmp/z.txt" "$tmp/missing.txt"
cmp_err 1 "nonnum.txt:2: column 2: 'x' is not a number" "$tmp/z.txt" "$tmp/nonnum.txt"
cmp_err 1 "nonmono.txt:3: alpha 0.4 is not increasing" "$tmp/nonmono.txt" "$tmp/z.txt"
cmp_err 1 "far.txt: profiles do not overlap" "$tmp/z.txt" "$tmp/far.txt"
cmp_err 1 "f.txt: 5 columns, but .*z.txt is a profile" "$tmp/z.txt" "$tmp/f.txt"
cmp_err 1 "z.txt: 2 columns, but .*f.txt is a vector file" "$tmp/f.txt" "$tmp/z.txt"
cmp_err 1 "g2.txt: compare: grids differ" "$tmp/f.txt" "$tmp/g2.txt"
cmp_err 1 "offgrid.txt:2: not a regular grid: x = 32 is not on x0 + i\*dx (x0 = 0, dx = 18)" "$tmp/f.txt" "$tmp/offgrid.txt"
cmp_err 2 "need two files" "$tmp/z.txt"
cmp_err 2 "'w' is not u, v or mag" --component w "$tmp/f.txt" "$tmp/f11.txt"
cmp_err 2 "applies to vector files" --component u "$tmp/z.txt" "$tmp/z11.txt"
cmp_err 1 "nodir/out.png: cannot create" "$tmp/z.txt" "$tmp/z11.txt" --png "$tmp/nodir/out.png"
"$bin" compare --help | grep -q '^usage: rpiv compare' && ok || ko "compare --help"

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
