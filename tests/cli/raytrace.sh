#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv raytrace: the tables it writes (with the parameters that made them), the same results
# for any thread count, and one-line errors with exit 2 (usage) or 1 (run) for bad input.
set -u
bin=${RPIV_BIN:?}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
rows() { grep -vc '^#' "$1"; }

"$bin" raytrace --rays 20000 --out "$tmp/a" --stations 2:8:1 --fit "$tmp/a/sheet.txt" \
    --sweep beta1:1:2:0.5 --sensitivity >"$tmp/out" 2>"$tmp/err" && ok || ko "raytrace: $(cat "$tmp/err")"
for f in raytrace_profile.txt raytrace_metrics.txt raytrace_sweep.txt \
    raytrace_sweep_profiles.txt raytrace_sensitivity.txt sheet.txt; do
    [ -s "$tmp/a/$f" ] && ok || ko "missing $f"
done
[ "$(rows "$tmp/a/raytrace_profile.txt")" -eq 200 ] && ok || ko "profile rows"
grep -q '^# beta1_deg 1.3 beta1_side air polarisation p$' "$tmp/a/raytrace_profile.txt" && ok \
    || ko "profile header does not record beta1 and the polarisation"
[ "$(rows "$tmp/a/raytrace_metrics.txt")" -eq 7 ] && ok || ko "metrics rows"
[ "$(rows "$tmp/a/raytrace_sweep.txt")" -eq 3 ] && ok || ko "sweep rows"
# the 2 deg row is the I*_peak reference
awk '!/^#/ && $1 == 2 { exit ($8 == 1 ? 0 : 1) }' "$tmp/a/raytrace_sweep.txt" && ok || ko "I*_peak(2) != 1"
[ "$(rows "$tmp/a/raytrace_sensitivity.txt")" -eq 65 ] && ok || ko "sensitivity rows"
# one ray at 1.5 deg in air: deta = -0.016 -> dT/T0 = +0.857 (docs/optics.md)
awk '!/^#/ { printf "%.3f\n", $5; exit }' "$tmp/a/raytrace_sensitivity.txt" | grep -qx '0.857' && ok \
    || ko "sensitivity first row"
head -1 "$tmp/a/sheet.txt" | grep -qx '# rpiv-sheet 1' && ok || ko "fit is not a sheet profile"
grep -q 'inclination' "$tmp/out" && ok || ko "no inclination in the summary"

# polarisation and the beta1 side are recorded
"$bin" raytrace --rays 5000 --polar s --set laser.beta1_side=pmma --out "$tmp/s" >/dev/null 2>&1 && ok || ko "--polar s"
grep -q 'beta1_side pmma polarisation s' "$tmp/s/raytrace_profile.txt" && ok || ko "s not recorded"

# identical tables for 1 and 2 threads
"$bin" raytrace --rays 50001 --threads 1 --out "$tmp/t1" >/dev/null 2>&1 && ok || ko "threads 1"
"$bin" raytrace --rays 50001 --threads 2 --out "$tmp/t2" >/dev/null 2>&1 && ok || ko "threads 2"
cmp -s "$tmp/t1/raytrace_profile.txt" "$tmp/t2/raytrace_profile.txt" && ok || ko "thread count changes the profile"
cmp -s "$tmp/t1/raytrace_metrics.txt" "$tmp/t2/raytrace_metrics.txt" && ok || ko "thread count changes the metrics"

# plots
"$bin" raytrace --rays 20000 --out "$tmp/p" --png --sweep beta1:1:2:0.5 --sensitivity \
    --stations 2:8:1 >/dev/null 2>"$tmp/err" && ok || ko "--png: $(cat "$tmp/err")"
for f in profile metrics map sweep sweep_profiles sensitivity; do
    head -c 8 "$tmp/p/raytrace_$f.png" 2>/dev/null | od -An -tx1 | tr -d ' \n' | grep -qx '89504e470d0a1a0a' \
        && ok || ko "raytrace_$f.png is not a PNG"
done

"$bin" raytrace --help | grep -q '^usage: rpiv raytrace' && ok || ko "--help"

check_err() { # expected-rc expected-substring args...
    want=$1; pat=$2; shift 2
    "$bin" raytrace --out "$tmp/e" "$@" >/dev/null 2>"$tmp/err"
    rc=$?
    lines=$(wc -l <"$tmp/err")
    if [ "$rc" -eq "$want" ] && [ "$lines" -eq 1 ] && grep -q -- "$pat" "$tmp/err"; then ok
    else ko "raytrace $*: rc=$rc lines=$lines: $(cat "$tmp/err")"; fi
}
check_err 2 '--rays' --rays 0
check_err 2 '--rays' --rays many
check_err 2 '--sweep' --sweep beta2:1:2:0.5
check_err 2 '--sweep' --sweep beta1:2:1:0.5
check_err 2 '--stations' --stations 5:4:1
check_err 2 '--dz' --dz 0
check_err 2 '--smooth' --smooth -1
check_err 2 'polarisation' --polar q
check_err 2 'beta1_side' --set laser.beta1_side=water
check_err 2 'unknown option' --bogus
check_err 2 'unexpected argument' extra
check_err 2 'beta1' --set laser.beta1_side=pmma --beta1 44
check_err 1 'totally reflected' --rays 2000 --sensitivity=0.5
check_err 1 'quarter' --rays 2000 --stations -3:-2:1 --fit "$tmp/e/f.txt"
check_err 1 "$tmp/nodir/f.txt" --rays 2000 --fit "$tmp/nodir/f.txt"
: >"$tmp/file"
check_err 1 "$tmp/file" --rays 2000 --out "$tmp/file/sub"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
