#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Unreadable pairs in a series (a truncated TIFF, a missing file, frames of another size):
# without --skip-bad the run stops with exit 1 and one message naming the pair and the file,
# keeps its checkpoint, and leaves an existing output as it was (no temporary file either);
# with --skip-bad each is reported on stderr, listed in the output header, and the field
# equals, to the bit, the one of the series without those pairs (also with a background
# subtracted, and per pair with --mean-rms); a series where no pair reads fails clearly.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
rows() { grep -v '^#' "$1"; }
cd "$tmp" || exit 1

"$bin" synth --size 192x160 --pairs 7 --seed 9173 --flow uniform:1.6421,0.8713 --out s -q || ko "synth"
"$bin" synth --size 160x160 --pairs 1 --seed 9174 --out small -q || ko "synth (small)"
head -c 2000 s/pair_00003_b.tif >cut.tif && mv cut.tif s/pair_00003_b.tif   # truncated
rm s/pair_00005_a.tif                                                       # missing
cp small/pair_00001_a.tif s/pair_00006_a.tif                                # 160x160
cp small/pair_00001_b.tif s/pair_00006_b.tif
good() { for i in 1 2 4 7; do printf 's/pair_0000%d_a.tif s/pair_0000%d_b.tif\n' $i $i; done; }
good >good.txt
for i in 1 2 3 4 5 6 7; do printf 's/pair_0000%d_a.tif s/pair_0000%d_b.tif\n' $i $i; done >all.txt

# ---- without --skip-bad: the first bad pair stops the run -------------------------------------
printf 'an earlier result\n' >out.txt
cp out.txt out.keep
"$bin" piv --ensemble -q all.txt -o out.txt --checkpoint ck 2>err
[ $? -eq 1 ] && ok || ko "an unreadable pair did not fail the run"
[ "$(wc -l <err)" -eq 1 ] && grep -q '^rpiv: error: pair 3 of 7: .*s/pair_00003_b.tif: truncated or corrupt TIFF.*; checkpoint ck saved (pass 1, 2 pairs summed' err \
    && ok || ko "message: $(cat err)"
[ -s ck ] && ok || ko "the checkpoint was not kept"
cmp -s out.txt out.keep && ok || ko "the failed run changed the existing output"
ls | grep -q 'tmp' && ko "temporary files left: $(ls | tr '\n' ' ')"
# per pair, into a .nc series: the existing file stays, the temporary series is removed
printf 'an earlier series\n' >ser.nc
cp ser.nc ser.keep
"$bin" piv -q all.txt -o ser.nc 2>err
[ $? -eq 1 ] && grep -q 'pair 3 of 7' err && ok || ko "per pair: $(cat err)"
cmp -s ser.nc ser.keep && ok || ko "the failed run changed the existing .nc"
ls | grep -q 'tmp' && ko "temporary files left: $(ls | tr '\n' ' ')"
# the missing file, first in its own list
printf 's/pair_00005_a.tif s/pair_00005_b.tif\ns/pair_00001_a.tif s/pair_00001_b.tif\n' >miss.txt
"$bin" piv --ensemble -q miss.txt -o m.txt 2>err
[ $? -eq 1 ] && grep -q 'pair_00005_a.tif' err && ok || ko "missing file: $(cat err)"

# ---- with --skip-bad: reported, listed, and the field of the readable pairs ------------------
"$bin" piv --ensemble -q good.txt -o ref.txt || ko "ensemble of the good pairs"
"$bin" piv --ensemble -q --skip-bad all.txt -o skip.txt 2>err && ok || ko "--skip-bad: $(cat err)"
[ "$(grep -c '^rpiv piv: warning: skipped: pair [356] of 7: ' err)" -eq 3 ] && ok || ko "warnings: $(cat err)"
grep -q 'pair 3 of 7: .*pair_00003_b.tif' err && grep -q 'pair 5 of 7: .*pair_00005_a.tif' err &&
    grep -q 'pair 6 of 7: .*pair_00006_a.tif: 160x160 frames, the series. are 192x160' err \
    && ok || ko "warnings do not name the files: $(cat err)"
grep -q '^# skipped_pairs = 3$' skip.txt && ok || ko "skipped count not in the header"
grep -q '^# skipped = 3 s/pair_00003_a.tif s/pair_00003_b.tif; 5 s/pair_00005_a.tif s/pair_00005_b.tif; 6 s/pair_00006_a.tif s/pair_00006_b.tif$' skip.txt \
    && ok || ko "skipped list: $(grep skipped skip.txt)"
cmp -s <(rows ref.txt) <(rows skip.txt) && ok || ko "--skip-bad field differs from the good pairs' field"
# the same with a background (min) computed over the readable pairs
"$bin" piv --ensemble -q --background min good.txt -o refbg.txt || ko "background, good pairs"
"$bin" piv --ensemble -q --background min --skip-bad all.txt -o skipbg.txt 2>/dev/null && ok || ko "--skip-bad --background"
cmp -s <(rows refbg.txt) <(rows skipbg.txt) && ok || ko "--skip-bad with background differs"
# per pair: no file for a skipped pair, the mean lists them
mkdir -p pp
"$bin" piv -q --skip-bad --mean-rms all.txt -o pp/f.txt 2>/dev/null && ok || ko "per pair --skip-bad"
[ "$(ls pp | tr '\n' ' ')" = "f_0001.txt f_0002.txt f_0004.txt f_0007.txt f_mean.txt f_rms.txt " ] \
    && ok || ko "per-pair files: $(ls pp | tr '\n' ' ')"
grep -q '^# skipped_pairs = 3$' pp/f_mean.txt && ok || ko "skipped pairs not in the mean's header"
# a checkpointed run that stopped on the bad pair resumes with --skip-bad to the same field
"$bin" piv --ensemble -q --skip-bad all.txt -o res.txt --checkpoint ck --resume 2>/dev/null &&
    cmp -s <(rows ref.txt) <(rows res.txt) && ok || ko "resume with --skip-bad"
# the first pair unreadable: the frame size comes from the next one
"$bin" piv --ensemble -q --skip-bad miss.txt -o m.txt 2>/dev/null && ok || ko "first pair unreadable"
# nothing readable
printf 's/pair_00003_a.tif s/pair_00003_b.tif\ns/pair_00005_a.tif s/pair_00005_b.tif\n' >none.txt
"$bin" piv --ensemble -q --skip-bad none.txt -o n.txt 2>err
[ $? -eq 1 ] && grep -q 'none of the 2 pairs can be read' err && ok || ko "no readable pair: $(cat err)"

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
