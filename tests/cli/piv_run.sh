#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv piv on the fixture pair (UVmat's synthetic Oseen vortex, 400 x 300): the grid, the
# ensemble of a pair listed twice equals the per-pair result, physical columns, [piv] keys
# from --config, series outputs (.nc and one file per pair), mean and RMS, the quiver plot,
# a mask, background subtraction, and identical results with 1 and 2 threads.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
data=${RPIV_TEST_DATA:?RPIV_TEST_DATA not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# sanitizer builds: fontconfig's process-lifetime caches (through PLplot's cairo driver)
printf 'leak:libfontconfig.so\n' >"$tmp/lsan.supp"
export LSAN_OPTIONS="suppressions=$tmp/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
data=$(cd "$data" && pwd) # list files resolve relative paths from their own folder
a="$data/Oseen_center_01.tif"
b="$data/Oseen_center_02.tif"
rows() { grep -v '^#' "$1"; }

# one pair: 32 px windows every 16 px centred in 400 x 300 -> 24 x 17 vectors, at the window
# centres plus the quarter pixel of the deformed passes
"$bin" piv --quiet "$a" "$b" -o "$tmp/one.txt" || ko "one pair"
[ "$(rows "$tmp/one.txt" | wc -l)" -eq 408 ] && ok || ko "one pair: $(rows "$tmp/one.txt" | wc -l) vectors, expected 408"
rows "$tmp/one.txt" | head -1 | awk '{exit !($1 == 15.75 && $2 == 21.75)}' && ok || ko "first point: $(rows "$tmp/one.txt" | head -1)"
# a good pair: few vectors replaced, peaks well defined
rows "$tmp/one.txt" | awk '{n++; r += ($5 == 1); if ($6 > 1.5) g++} END {exit !(r <= 0.03 * n && g >= 0.9 * n)}' \
    && ok || ko "one pair: too many replaced vectors or weak peaks"
grep -q '^# windows = 64x64,32x32,32x32$' "$tmp/one.txt" && ok || ko "parameters not recorded"

# the ensemble of the pair listed twice: summed planes twice as high, same peaks (with the
# single pair's estimator: an ensemble's default is spline; and the predictor continued
# linearly beyond the grid, as a pair's, whatever piv.edge_curvature's default)
printf '%s %s\n%s %s\n' "$a" "$b" "$a" "$b" >"$tmp/pairs.txt"
"$bin" piv --quiet --ensemble --subpixel gauss -S piv.edge_curvature=0 "$tmp/pairs.txt" \
    -o "$tmp/ens.txt" || ko "ensemble"
# (the ensemble runs the listed passes: the pair without the refinement's repeats)
"$bin" piv --quiet -S piv.refine_max=0 "$a" "$b" -o "$tmp/one0.txt" || ko "one pair, no repeats"
diff <(rows "$tmp/one0.txt" | cut -d' ' -f1-5) <(rows "$tmp/ens.txt" | cut -d' ' -f1-5) >/dev/null \
    && ok || ko "ensemble of a pair twice differs from the pair"
grep -q '^# mode = ensemble$' "$tmp/ens.txt" && ok || ko "ensemble mode not recorded"
# piv.ensemble_refine: one repeat of the final pass does not converge this vortex (its
# field still changes by 0.03 px): a warning says so. The default's final pass changes the
# field by 0.1 px: a warning says the listed passes did not converge it; six repeats do
# (below 0.002 px) and say nothing.
"$bin" piv --quiet --ensemble -S piv.ensemble_refine=1 -S piv.ensemble_denoise=0 \
    "$tmp/pairs.txt" -o "$tmp/ensr.txt" 2>"$tmp/ensr.err" || ko "ensemble_refine"
grep -q 'warning: the ensemble.s final pass was repeated 1 time and .*not converged' \
    "$tmp/ensr.err" && ok || ko "ensemble_refine: no warning: $(cat "$tmp/ensr.err")"
grep -q '^# ensemble_refine = 1 (tol 0.002 px)$' "$tmp/ensr.txt" &&
    grep -q '^# ensemble_denoise = 0' "$tmp/ensr.txt" && ok || ko "ensemble_refine not recorded"
"$bin" piv --quiet --ensemble "$tmp/pairs.txt" -o "$tmp/ens0.txt" 2>"$tmp/ens0.err" \
    && grep 'did not converge it' "$tmp/ens0.err" |
        sed -n 's/.*final pass still changed its field by \([0-9.]*\) px.*/\1/p' |
        awk '{good = $1 > 0.05 && $1 < 0.2} END {exit !(NR == 1 && good)}' &&
    ok || ko "default ensemble, no warning: $(cat "$tmp/ens0.err")"
"$bin" piv --quiet --ensemble -S piv.ensemble_refine=6 "$tmp/pairs.txt" -o "$tmp/ens6.txt" \
    2>"$tmp/ens6.err" && [ ! -s "$tmp/ens6.err" ] && ok || ko "converged ensemble warns: $(cat "$tmp/ens6.err")"
! cmp -s <(rows "$tmp/ensr.txt") <(rows "$tmp/ens0.txt") && ok || ko "ensemble_refine changed nothing"

# physical units: x_mm = 0.05 x, u_ms = u * 0.05e-3 / 2e-3
"$bin" piv --quiet "$a" "$b" --scale 0.05 --dt 0.002 -o "$tmp/phys.txt" || ko "--scale --dt"
rows "$tmp/phys.txt" | awk 'NF != 11 || ($8 - 0.05 * $1) > 1e-6 || ($8 - 0.05 * $1) < -1e-6 ||
    ($10 - 0.025 * $3) > 1e-6 || ($10 - 0.025 * $3) < -1e-6 {bad++} END {exit bad > 0}' \
    && ok || ko "physical columns: $(rows "$tmp/phys.txt" | head -1)"

# [piv] keys from a configuration file, overridden by an option
printf '[piv]\nwindows = 48,24\noverlap = 0.5\nsubpixel = parabola\n' >"$tmp/run.ini"
"$bin" piv --quiet --config "$tmp/run.ini" "$a" "$b" -o "$tmp/cfg.txt" || ko "--config"
[ "$(rows "$tmp/cfg.txt" | wc -l)" -eq 768 ] && ok || ko "--config windows: $(rows "$tmp/cfg.txt" | wc -l) vectors, expected 32 x 24"
grep -q '^# subpixel = parabola$' "$tmp/cfg.txt" && ok || ko "--config subpixel"
"$bin" piv --quiet --config "$tmp/run.ini" --step 20 "$a" "$b" -o "$tmp/cfg2.txt" || ko "--step"
[ "$(rows "$tmp/cfg2.txt" | wc -l)" -eq $((19 * 14)) ] && ok || ko "--step 20: $(rows "$tmp/cfg2.txt" | wc -l) vectors"

# series: .nc along t, one text file per pair, mean and RMS (identical pairs: RMS 0)
"$bin" piv --quiet "$tmp/pairs.txt" --mean-rms -o "$tmp/s.nc" --plot "$tmp/q.png" || ko "series .nc"
for f in s.nc s_mean.nc s_rms.nc; do [ -s "$tmp/$f" ] && ok || ko "$f missing"; done
head -c 8 "$tmp/q.png" | od -An -tx1 | grep -q '89 50 4e 47 0d 0a 1a 0a' && ok || ko "plot is not a PNG"
"$bin" piv --quiet "$tmp/pairs.txt" --mean-rms -o "$tmp/t.txt" || ko "series .txt"
cmp -s <(rows "$tmp/t_0001.txt") <(rows "$tmp/t_0002.txt") && ok || ko "per-pair files"
diff <(rows "$tmp/t_mean.txt" | cut -d' ' -f1-5) <(rows "$tmp/one.txt" | cut -d' ' -f1-5) >/dev/null \
    && ok || ko "mean of two identical fields differs from the field"
rows "$tmp/t_rms.txt" | awk '$3 != 0 || $4 != 0 {bad++} END {exit bad > 0}' && ok || ko "RMS of identical fields is not 0"

# a mask (ASCII PGM, 0 = masked): a band across the vortex
awk 'BEGIN {print "P2\n400 300\n255"; for (y = 0; y < 300; y++) {l = ""; for (x = 0; x < 400; x++) l = l ((y >= 120 && y < 170) ? "0 " : "255 "); print l}}' >"$tmp/mask.pgm"
"$bin" piv --quiet "$a" "$b" --mask "$tmp/mask.pgm" -o "$tmp/mask.txt" || ko "--mask"
rows "$tmp/mask.txt" | awk '$5 == 2 {n++; if ($3 != 0 || $4 != 0 || $2 < 100 || $2 > 190) bad++}
    END {exit !(n >= 24 && !bad)}' && ok || ko "masked vectors"

# background subtraction runs over the series
"$bin" piv --quiet "$tmp/pairs.txt" --background mean -o "$tmp/bg.txt" && ok || ko "--background"

# 1 and 2 threads: the same numbers
"$bin" piv --quiet --threads 1 "$a" "$b" -o "$tmp/t1.txt" || ko "--threads 1"
"$bin" piv --quiet --threads 2 "$a" "$b" -o "$tmp/t2.txt" || ko "--threads 2"
cmp -s <(rows "$tmp/t1.txt") <(rows "$tmp/t2.txt") && ok || ko "1 and 2 threads differ"

# --out DIR: the folder is made, the field written as DIR/piv.txt (DIR/ensemble.txt)
"$bin" piv --quiet "$a" "$b" --out "$tmp/dir/sub" || ko "--out DIR"
cmp -s <(rows "$tmp/dir/sub/piv.txt") <(rows "$tmp/one.txt") && ok || ko "--out DIR: piv.txt differs"
"$bin" piv --quiet --ensemble "$a" "$b" --out "$tmp/dir/sub" && [ -s "$tmp/dir/sub/ensemble.txt" ] \
    && ok || ko "--out DIR --ensemble"

"$bin" piv --help | grep -q '^usage: rpiv piv' && ok || ko "--help"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
