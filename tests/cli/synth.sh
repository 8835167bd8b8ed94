#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv synth: a small run writes the pairs, truth.txt and synth.ini; the same seed gives the
# same bytes (also from --config DIR/synth.ini, and for any thread count), another seed other
# bytes; double-frame files; the truth of a uniform flow; bad option values give exit 2 and
# one stderr line naming the option, a missing file exit 1 naming the file.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }

# ---- a small run ----------------------------------------------------------------------------
"$bin" synth --size 256x256 --pairs 2 --seed 2385 --out "$tmp/r1" -q 2>"$tmp/err" && ok || ko "run 1: $(cat "$tmp/err")"
[ -s "$tmp/err" ] && ko "--quiet run printed on stderr: $(cat "$tmp/err")"
for f in pair_00001_a.tif pair_00001_b.tif pair_00002_a.tif pair_00002_b.tif truth.txt synth.ini; do
    [ -s "$tmp/r1/$f" ] && ok || ko "missing $f"
done
[ "$(ls "$tmp/r1" | wc -l)" -eq 6 ] && ok || ko "unexpected files: $(ls "$tmp/r1")"
"$bin" info "$tmp/r1/pair_00002_b.tif" | grep -q "format TIFF width 256 height 256 bits 16" && ok || ko "pair_00002_b.tif is not a 256x256 16-bit TIFF"
grep -q '^seed = 2385$' "$tmp/r1/synth.ini" && ok || ko "seed not in synth.ini"
grep -q '^flow = duct$' "$tmp/r1/synth.ini" && ok || ko "flow not in synth.ini"
grep -q '^width_px = 256$' "$tmp/r1/synth.ini" && ok || ko "size not in synth.ini"
# the final [piv] grid of rpiv piv (32 px windows at 50 %, deformation): 15 x 15 points
[ "$(grep -vc '^#' "$tmp/r1/truth.txt")" -eq 225 ] && ok || ko "truth.txt: 225 points expected"
awk '!/^#/ { print $1, $2; exit }' "$tmp/r1/truth.txt" | grep -qx '15.75 15.75' && ok || ko "first truth point not at rpiv piv's (15.75, 15.75)"

# same seed again: identical bytes; through --config DIR/synth.ini; with 1 thread
"$bin" synth --size 256x256 --pairs 2 --seed 2385 --out "$tmp/r2" -q && ok || ko "run 2"
"$bin" synth --config "$tmp/r1/synth.ini" --out "$tmp/r3" --threads 1 -q && ok || ko "run from synth.ini"
for f in pair_00001_a.tif pair_00001_b.tif pair_00002_a.tif pair_00002_b.tif truth.txt; do
    cmp -s "$tmp/r1/$f" "$tmp/r2/$f" && ok || ko "$f differs between two runs with the same seed"
    cmp -s "$tmp/r1/$f" "$tmp/r3/$f" && ok || ko "$f differs when made again from synth.ini with 1 thread"
done
# the same configuration but the output folder and [piv] threads (set by --threads)
diff <(grep -v '^dir = \|^threads = ' "$tmp/r1/synth.ini") <(grep -v '^dir = \|^threads = ' "$tmp/r3/synth.ini") >/dev/null && ok || ko "synth.ini not reproduced"
# another seed: other images, same truth
"$bin" synth --size 256x256 --pairs 1 --seed 2386 --out "$tmp/r4" -q && ok || ko "run 4"
cmp -s "$tmp/r1/pair_00001_a.tif" "$tmp/r4/pair_00001_a.tif" && ko "another seed gave the same image" || ok
cmp -s "$tmp/r1/truth.txt" "$tmp/r4/truth.txt" && ko "truth.txt records the seed: should differ" || ok

# ---- double frame, another flow and sheet, progress --------------------------------------------
RPIV_PROGRESS_DELAY=0 "$bin" synth --size 128x96 --pairs 1 --double-frame --flow uniform:3.3187,-1.7421 --sheet volume \
    --set piv.windows=32 --out "$tmp/d" >"$tmp/out" 2>"$tmp/err" && ok || ko "double frame: $(cat "$tmp/err")"
[ -s "$tmp/d/pair_00001.tif" ] && [ ! -e "$tmp/d/pair_00001_a.tif" ] && ok || ko "double-frame file names"
"$bin" info "$tmp/d/pair_00001.tif" | grep -q "width 128 height 192 bits 16" && ok || ko "double frame is not 128x192"
grep -q "synth: 1/1 (100%)" "$tmp/err" && ok || ko "no progress line: $(cat "$tmp/err")"
grep -q "^rpiv synth: 1 pair of 128x96 px" "$tmp/out" && ok || ko "summary line: $(cat "$tmp/out")"
grep -q '^kind = uniform$' "$tmp/d/synth.ini" && ok || ko "--sheet volume not recorded"
# every truth vector is (3.3187, -1.7421), flag 0: 7 x 5 points
awk '!/^#/ { n++; if ($3 != 3.3187 || $4 != -1.7421 || $5 != 0) bad++ } END { exit !(n == 35 && !bad) }' \
    "$tmp/d/truth.txt" && ok || ko "uniform truth wrong"

# ---- errors ---------------------------------------------------------------------------------
err2() { # expected-substring args...: exit 2 and one stderr line
    want=$1; shift
    "$bin" synth -q --out "$tmp/bad" "$@" >/dev/null 2>"$tmp/err"; rc=$?
    if [ "$rc" -eq 2 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && grep -q -- "$want" "$tmp/err"; then ok
    else ko "synth $*: rc=$rc: $(cat "$tmp/err")"; fi
}
err2 "--pairs: 0 outside" --pairs 0
err2 "--pairs: 'x' is not an integer" --pairs x
err2 "--seed: -1 outside" --seed -1
err2 "--size: '7x300'" --size 7x300
err2 "--size: 'abc'" --size abc
# issue 20 item 7: 4294967360x64 wrapped to 64x64
err2 "--size: '4294967360x64' outside" --size 4294967360x64
err2 "--size: '64x-4294967232' outside" --size 64x-4294967232
# issue 20 item 9: oseen:1e300,1 wrote inf into truth.txt
err2 "number 1 (a displacement" --flow oseen:1e300,1
err2 "number 2 (the wavelength" --flow sine:1,1e300
err2 "--flow: flow 'vortex'" --flow vortex
err2 "uniform takes 2 to 2 numbers" --flow uniform:1
err2 "core radius" --flow oseen:6,0
err2 "--sheet: 'laser'" --sheet laser
err2 "unknown option '--bogus'" --bogus
err2 "needs a value" --seed
err2 "unexpected argument 'extra'" extra
err2 "synth.bits" --set synth.bits=10
err2 "synth.flow" --set synth.flow=vortex
[ ! -e "$tmp/bad" ] && ok || ko "a failed run created its output folder"
err1() { # expected-substring args...: exit 1 and one stderr line
    want=$1; shift
    "$bin" synth -q --out "$tmp/bad1" "$@" >/dev/null 2>"$tmp/err"; rc=$?
    if [ "$rc" -eq 1 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && grep -q -- "$want" "$tmp/err"; then ok
    else ko "synth $*: rc=$rc: $(cat "$tmp/err")"; fi
}
err1 "no-such.ini" --config "$tmp/no-such.ini"
err1 "no-such-pz.txt" --size 64x64 --set "synth.pz_profile=$tmp/no-such-pz.txt"
err1 "is larger than the image" --size 16x16
# issue 20 item 13: synth into a used folder left the earlier run's extra pairs
"$bin" synth --size 64x64 --pairs 3 --out "$tmp/used" -q && ok || ko "used folder run 1"
"$bin" synth --size 64x64 --pairs 1 --out "$tmp/used" -q 2>"$tmp/err"; rc=$?
[ "$rc" -eq 2 ] && grep -q "not empty" "$tmp/err" && ok || ko "non-empty folder accepted: rc=$rc $(cat "$tmp/err")"
[ -e "$tmp/used/pair_00003_b.tif" ] && ok || ko "a refused run removed files"
touch "$tmp/used/notes.txt"
"$bin" synth --size 64x64 --pairs 1 --out "$tmp/used" --overwrite -q && ok || ko "--overwrite"
[ "$(ls "$tmp/used" | sort | tr '\n' ' ')" = "notes.txt pair_00001_a.tif pair_00001_b.tif synth.ini truth.txt " ] && ok || ko "--overwrite left: $(ls "$tmp/used")"
"$bin" synth --help | grep -q '^usage: rpiv synth' && ok || ko "synth --help"

echo "synth.sh: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
