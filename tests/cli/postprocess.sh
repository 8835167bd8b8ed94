#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Post-processing from the command line (issue 16): --derived on rpiv piv and rpiv derive give
# the same vorticity, with the same physical sign in image and --y-up files; the extra
# validation options run; the honest warnings (double frame, --dt without --scale, an empty
# image, more than 10 % replaced) come on stderr with exit 0; bad values exit 2.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
data=${RPIV_TEST_DATA:?RPIV_TEST_DATA not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
a="$data/Oseen_center_01.tif"
b="$data/Oseen_center_02.tif"
o=(--quiet --window 32 --overlap 0.5)

# the vorticity column (8th) of a file, its values sorted (the row order differs y-up)
col8() { grep -v '^#' "$1" | awk '{ print $8 }' | sort -g; }

"$bin" piv "${o[@]}" --derived vorticity "$a" "$b" -o "$tmp/img.txt" 2>"$tmp/err" && ok ||
    ko "piv --derived vorticity"
[ -s "$tmp/err" ] && ko "a clean run printed on stderr: $(cat "$tmp/err")"
"$bin" piv "${o[@]}" --derived vorticity --y-up "$a" "$b" -o "$tmp/up.txt" && ok ||
    ko "piv --derived vorticity --y-up"
grep -q '^# quantity = vorticity 1/dt$' "$tmp/img.txt" && ok || ko "no vorticity quantity"
# the same physical values in both orientations (sorted values compared)
cmp -s <(col8 "$tmp/img.txt") <(col8 "$tmp/up.txt") && ok ||
    ko "vorticity differs between image and y-up files"
# rpiv derive on the plain file gives the same column, in either orientation
"$bin" piv "${o[@]}" "$a" "$b" -o "$tmp/plain.txt" && ok || ko "piv plain"
"$bin" piv "${o[@]}" --y-up "$a" "$b" -o "$tmp/plain_up.txt" && ok || ko "piv plain --y-up"
"$bin" derive --quiet --derived vorticity "$tmp/plain.txt" -o "$tmp/d.txt" && ok || ko "derive"
"$bin" derive --quiet --derived vorticity "$tmp/plain_up.txt" -o "$tmp/d_up.txt" && ok ||
    ko "derive y-up"
cmp -s <(col8 "$tmp/img.txt") <(col8 "$tmp/d.txt") && ok || ko "derive != piv --derived"
cmp -s <(col8 "$tmp/img.txt") <(col8 "$tmp/d_up.txt") && ok || ko "derive of y-up differs"
"$bin" derive --quiet "$tmp/plain.txt" -o "$tmp/all.nc" && ok || ko "derive all -> .nc"
"$bin" derive --quiet --dt 0.001 --scale 0.05 "$tmp/plain.txt" -o "$tmp/s.txt" && ok ||
    ko "derive --dt --scale"
grep -q 'vorticity_per_s' "$tmp/s.txt" && grep -q 'q_criterion_per_s2' "$tmp/s.txt" && ok ||
    ko "no per-second columns"
"$bin" derive --derived curl "$tmp/plain.txt" -o "$tmp/x.txt" 2>/dev/null
[ $? -eq 2 ] && ok || ko "derive --derived curl: exit not 2"
"$bin" derive "$tmp/missing.txt" -o "$tmp/x.txt" 2>/dev/null
[ $? -ne 0 ] && ok || ko "derive of a missing file exited 0"
# a NetCDF input (its first field) gives what the text file of the same field gives; .vtk is
# refused with a one-line error naming it (it was read as text: "'\x89HDF' is not a number")
"$bin" piv "${o[@]}" "$a" "$b" -o "$tmp/plain.nc" 2>/dev/null && ok || ko "piv -> .nc"
"$bin" derive --quiet --derived vorticity "$tmp/plain.nc" -o "$tmp/dn.txt" && ok ||
    ko "derive of a .nc file"
cmp -s <(col8 "$tmp/d.txt") <(col8 "$tmp/dn.txt") && ok || ko "derive of .nc != derive of .txt"
"$bin" derive "$tmp/all.nc" -o "$tmp/x.txt" --derived vorticity 2>/dev/null && ok ||
    ko "derive of a derived .nc"
touch "$tmp/f.vtk"
"$bin" derive "$tmp/f.vtk" -o "$tmp/x.txt" 2>"$tmp/err"
[ $? -ne 0 ] && grep -q 'f.vtk: rpiv derive reads text' "$tmp/err" && ok || ko "derive of .vtk"

# validation options run; all off by default: the default run is unchanged by naming them off
"$bin" piv "${o[@]}" --peak-ratio 1.2 --std 4 --limits -8,8,-8,8 --replace inpaint \
    --smooth 1 "$a" "$b" -o "$tmp/val.txt" && ok || ko "validation options"
"$bin" piv "${o[@]}" --set piv.peak_ratio_min=0 --set piv.std_k=0 --set piv.smooth=0 \
    "$a" "$b" -o "$tmp/off.txt" && ok || ko "options off"
cmp -s <(grep -v '^#' "$tmp/plain.txt") <(grep -v '^#' "$tmp/off.txt") && ok ||
    ko "the options off change the default result"
for bad in "--peak-ratio -1" "--std -2" "--replace bogus" "--smooth -1" "--limits 1,2,x,4"; do
    # shellcheck disable=SC2086
    "$bin" piv "${o[@]}" $bad "$a" "$b" -o "$tmp/x.txt" 2>/dev/null
    [ $? -eq 2 ] && ok || ko "$bad: exit not 2"
done

# warnings, exit 0
"$bin" piv "${o[@]}" "$a" -o "$tmp/df.txt" 2>"$tmp/err" && ok || ko "double frame run failed"
grep -q 'read as a double frame' "$tmp/err" && ok || ko "no double-frame warning"
grep -q 'of the vectors were replaced' "$tmp/err" && grep -q -- '--preprocess' "$tmp/err" && ok ||
    ko "no replaced-fraction warning suggesting --preprocess"
"$bin" piv "${o[@]}" --dt 0.001 "$a" "$b" -o "$tmp/dt.txt" 2>"$tmp/err" && ok || ko "--dt run"
grep -q -- '--dt without --scale' "$tmp/err" && ok || ko "no --dt without --scale warning"
{ printf 'P2\n64 64\n255\n'; for _ in $(seq 4096); do echo 0; done; } >"$tmp/empty.pgm"
"$bin" piv "${o[@]}" "$tmp/empty.pgm" "$tmp/empty.pgm" -o "$tmp/e.txt" 2>"$tmp/err" && ok ||
    ko "empty image run failed"
grep -q 'is empty (grey 0 everywhere)' "$tmp/err" && ok || ko "no empty-image warning"
[ "$(wc -l <"$tmp/err")" -le 3 ] && ok || ko "too many warning lines: $(cat "$tmp/err")"

echo "postprocess.sh: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
