#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv calib: target images rendered by rpiv itself are analysed back to the configured sheet
# and object plane (docs/calib.md); the profile file is read by the sheet module; bad input
# gives one stderr line, exit 2 for usage and 1 for files and data.
set -u
bin=${RPIV_BIN:?}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
# is $1 within [$2, $3]?
within() { awk -v x="$1" -v a="$2" -v b="$3" 'BEGIN { exit !(x != "" && x >= a && x <= b) }'; }

# ---- sheet: three plates of the default self-similar sheet (e* = 0.0646 x*, z*_max = 0.0794 x*)
xs="4.1187 5.9731 7.6113"
imgs=()
for x in $xs; do
    "$bin" calib render-sheet -q --size 560x16 --x "$x" --noise 20 --seed 5 \
        -o "$tmp/plate_$x.tif" 2>"$tmp/err" && ok || ko "render-sheet $x: $(cat "$tmp/err")"
    imgs+=("$tmp/plate_$x.tif")
done
xargs=()
for x in $xs; do xargs+=(--x "$x"); done
"$bin" calib sheet --dark 100 --foot-px 40.3187 "${xargs[@]}" --out "$tmp/s" "${imgs[@]}" \
    >"$tmp/sheet.out" 2>"$tmp/err" && ok || ko "calib sheet: $(cat "$tmp/err")"
line=$(grep '^self-similar sheet' "$tmp/sheet.out")
zm1=$(echo "$line" | sed -n 's/.*z\*_max = [-0-9.]* + \([-0-9.]*\) x\*.*/\1/p')
e1=$(echo "$line" | sed -n 's/.*e\* = [-0-9.]* + \([-0-9.]*\) x\*.*/\1/p')
within "$zm1" 0.0744 0.0844 && ok || ko "zm1 '$zm1' (0.0794): $line"
within "$e1" 0.0596 0.0696 && ok || ko "e1 '$e1' (0.0646): $line"
# every plate: e* at x*_max within 0.02 of 0.0646 x*_max, z*_max within 0.02 of 0.0794 x*_max
awk '!/^#/ { x = $5; de = $13 - 0.42 / 6.5 * x; dz = $11 - 0.5 / 6.3 * x;
             if (de < -0.02 || de > 0.02 || dz < -0.02 || dz > 0.02) bad = 1; n++ }
     END { exit (bad || n != 3) }' "$tmp/s/calib_sheet_plates.txt" && ok \
    || ko "plate metrics: $(cat "$tmp/s/calib_sheet_plates.txt")"
head -1 "$tmp/s/calib_sheet_profile.txt" | grep -qx '# rpiv-sheet 1' && ok || ko "profile magic"
[ -s "$tmp/s/calib_sheet_profiles.txt" ] && ok || ko "profiles table"
# the profile file is a sheet the generator can use: render a plate with it
"$bin" calib render-sheet -q --size 560x8 --x 5.9731 --set sheet.profile="$tmp/s/calib_sheet_profile.txt" \
    -o "$tmp/from_profile.tif" 2>"$tmp/err" && ok || ko "render with the measured profile: $(cat "$tmp/err")"
# and re-measuring that image gives the same sheet at that x*
"$bin" calib sheet -q --dark 100 --foot-px 40.3187 --x 5.9731 --out "$tmp/s2" "$tmp/from_profile.tif" \
    >"$tmp/s2.out" 2>"$tmp/err" && ok || ko "sheet of the measured profile: $(cat "$tmp/err")"
a=$(awk '!/^#/ && $1 == 2 { print $9 }' "$tmp/s/calib_sheet_plates.txt")
b=$(awk '!/^#/ { print $9 }' "$tmp/s2/calib_sheet_plates.txt")
d=$(awk -v a="$a" -v b="$b" 'BEGIN { print a - b }')
within "$d" -0.02 0.02 && ok || ko "raw e* of the re-rendered sheet: $a vs $b"

# ---- dof: default camera (f# 5.6, z*_OP 0.45) and a moved object plane
"$bin" calib render-dots -q --size 560x48 --noise 15 -o "$tmp/dots.tif" 2>"$tmp/err" && ok \
    || ko "render-dots: $(cat "$tmp/err")"
"$bin" calib dof --dot-diameter 0.0625 --pitch 0.125 --dark 100 --out "$tmp/d" "$tmp/dots.tif" \
    >"$tmp/dof.out" 2>"$tmp/err" && ok || ko "calib dof: $(cat "$tmp/err")"
zop=$(sed -n 's/^z\*_OP \([0-9.]*\) .*/\1/p' "$tmp/dof.out")
dof=$(sed -n 's/^z\*_OP .*DOF\* \([0-9.]*\) (half.*/\1/p' "$tmp/dof.out")
mdof=$(sed -n 's/^model .*): DOF\* \([0-9.]*\),.*/\1/p' "$tmp/dof.out")
within "$zop" 0.43 0.47 && ok || ko "z*_OP '$zop': $(cat "$tmp/dof.out")"
d=$(awk -v a="$dof" -v b="$mdof" 'BEGIN { print (a != "" && b != "") ? a - b : 99 }')
within "$d" -0.02 0.02 && ok || ko "DOF* '$dof' vs model '$mdof'"
for f in calib_dof_curve.txt calib_dof_dots.txt calib_dof_model.txt; do
    [ -s "$tmp/d/$f" ] && ok || ko "missing $f"
done
"$bin" calib render-dots -q --size 560x32 --set camera.zop=0.3187 -o "$tmp/dots2.tif" && ok || ko "render zop"
zop=$("$bin" calib dof --dark 100 --out "$tmp/d2" "$tmp/dots2.tif" | sed -n 's/^z\*_OP \([0-9.]*\) .*/\1/p')
within "$zop" 0.2987 0.3387 && ok || ko "moved object plane: z*_OP '$zop' (0.3187)"

# ---- errors: one line on stderr naming the culprit; exit 2 for usage, 1 for files and data
check() { # expected-rc expected-substring args...
    local rc_want=$1 pat=$2; shift 2
    "$bin" calib "$@" >/dev/null 2>"$tmp/err"
    local rc=$?
    if [ "$rc" -eq "$rc_want" ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && grep -q -- "$pat" "$tmp/err"; then ok
    else ko "calib $*: rc=$rc: $(cat "$tmp/err")"; fi
}
one="$tmp/plate_4.1187.tif"
check 2 'missing SUBCOMMAND'
check 2 "unknown subcommand 'nosuch'" nosuch
check 2 'no image given' sheet --dark 100
check 1 "$tmp/missing.tif" sheet "$tmp/missing.tif"
check 2 'angle 3' sheet --plate-angle 3 "$one"
check 2 '2 --x for 1 images' sheet --x 4 --x 5 "$one"
check 2 "does not apply to dof" dof --no-floor "$one"
check 2 "does not apply to sheet" sheet --pitch 0.1 "$one"
check 2 'pitch' dof --pitch 0.05 --dot-diameter 0.0625 "$one"
check 2 "'abc' is not a number" sheet --foot-px abc "$one"
check 2 '--rows' sheet --rows 5 "$one"
check 2 'span rows' sheet --rows 5,3 "$one"
check 1 'dark region' sheet --dark-region 500,0,100,16 "$one"
check 1 'dark image is' sheet --dark-image "$tmp/dots.tif" "$one"
check 1 'no dots found' dof --dark 100 --foot-px 40.3187 "$one"
check 2 'missing -o' render-dots
check 2 '--size' render-dots --size 10 -o "$tmp/x.tif"
check 2 'unexpected argument' render-dots -o "$tmp/x.tif" extra
check 2 "unknown option" sheet --bogus "$one"
: >"$tmp/file"
check 1 "$tmp/file" sheet --dark 100 --foot-px 40.3187 --out "$tmp/file/sub" "$one"
check 1 "$tmp/nodir" render-dots --size 64x16 -o "$tmp/nodir/x.tif"
# a blank image: the sheet misses the channel and nothing else is lit
"$bin" calib render-sheet -q --size 300x8 --background 0 --set sheet.zm0=5 -o "$tmp/blank.tif" && ok || ko "render blank"
check 1 'blank image' sheet --foot-px 40 "$tmp/blank.tif"
check 1 'blank image' dof --foot-px 40 "$tmp/blank.tif"
# foot to detect in noise: no edge
"$bin" calib render-sheet -q --size 300x8 --background 0 --noise 5 --set sheet.zm0=5 \
    -o "$tmp/noise.tif" && ok || ko "render noise"
check 1 'cannot detect the plate foot' sheet "$tmp/noise.tif" --dark 100
head -c 300 "$tmp/dots.tif" >"$tmp/trunc.tif"
check 1 "$tmp/trunc.tif" dof "$tmp/trunc.tif"
"$bin" calib --help | grep -q '^usage: rpiv calib sheet' && ok || ko "--help"
"$bin" calib sheet --help | grep -q 'render-dots' && ok || ko "sheet --help"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
