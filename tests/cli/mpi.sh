#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv under mpirun with 2 ranks, against the same commands in one process: rpiv synth makes
# the same bytes; the ensemble field agrees within 1e-6 px (float sums grouped per rank; the
# displacements here are ~2.3 px, where a float ulp is 2.4e-7 px) with the same flags;
# mpirun -np 1 equals no mpirun; per-pair fields (each rank writes its own) and their mean
# (gathered to rank 0) are identical; a 2-rank run stopped by an unreadable pair resumes from
# its per-rank checkpoints to the bits of an uninterrupted 2-rank run (so 2-rank runs are
# reproducible), a 2-rank checkpoint is refused by a 1-process resume; --skip-bad lists the
# pair.
# Skipped (77) when the build has no MPI or mpirun is missing.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
here=$(cd "$(dirname "$0")" && pwd)
"$bin" piv --help | grep -q 'MPI support in this build: yes' || { echo "built without MPI: skipped"; exit 77; }
command -v mpirun >/dev/null || { echo "mpirun not found: skipped"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# sanitizer builds: OpenMPI's process-lifetime allocations (tests/lsan-mpi.supp; their frames
# in dlopen'ed components need the slow unwinder) and the suite's own list. The suppressions
# match module names, so leak stacks need no symbolizing (it took a second per rank); a leak
# in rpiv itself is still reported (rerun with symbolize=1 to read its stack).
cat "$here/../lsan-mpi.supp" "$here/../lsan.supp" >"$tmp/lsan.supp" 2>/dev/null
export LSAN_OPTIONS="suppressions=$tmp/lsan.supp:fast_unwind_on_malloc=0:print_suppressions=0:symbolize=0"
export OMP_NUM_THREADS=1
mpi() { mpirun --oversubscribe --allow-run-as-root --bind-to none -np "$@"; }
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
rows() { grep -v '^#' "$1"; }
# largest |du|, |dv| between two vector files on one grid, and the number of flags that differ
maxdiff() {
    paste <(rows "$1") <(rows "$2") | awk 'NF != 14 || $1 != $8 || $2 != $9 {bad++}
        {du = $3 - $10; dv = $4 - $11; if (du < 0) du = -du; if (dv < 0) dv = -dv
         if (du > m) m = du; if (dv > m) m = dv; if ($5 != $12) f++}
        END {printf "%.3g %d %d\n", m, f + 0, bad + 0}'
}
cd "$tmp" || exit 1

# ---- rpiv synth: rank r writes pairs r, r+2, ...; the same bytes as one process -----------
"$bin" synth --size 256x256 --pairs 6 --seed 4113 --flow uniform:2.3187,-1.1471 --out s1 -q \
    && ok || ko "synth, one process"
mpi 2 "$bin" synth --size 256x256 --pairs 6 --seed 4113 --flow uniform:2.3187,-1.1471 --out s2 -q \
    2>err && ok || ko "synth, 2 ranks: $(cat err)"
for f in pair_00001_a.tif pair_00002_b.tif pair_00005_a.tif pair_00006_b.tif truth.txt; do
    cmp -s "s1/$f" "s2/$f" && ok || ko "synth $f differs between 1 process and 2 ranks"
done
[ "$(ls s2 | wc -l)" -eq 14 ] && ok || ko "synth, 2 ranks: $(ls s2 | wc -l) files, expected 14"

# ---- ensemble: 2 ranks against one process --------------------------------------------------
"$bin" piv --ensemble -q 's1/pair_*_[ab].tif' -o one.txt && ok || ko "ensemble, one process"
mpi 2 "$bin" piv --ensemble -q 's1/pair_*_[ab].tif' -o two.txt 2>err && ok || ko "ensemble, 2 ranks: $(cat err)"
[ -s err ] && ko "2-rank ensemble printed on stderr: $(cat err)"
read -r d nf nbad <<<"$(maxdiff one.txt two.txt)"
echo "ensemble, 2 ranks vs 1 process: max |du|,|dv| = $d px, $nf flags differ"
[ "$nbad" -eq 0 ] && [ "$(rows one.txt | wc -l)" -eq 225 ] && ok || ko "2-rank grid differs"
awk -v d="$d" 'BEGIN {exit !(d <= 1e-6)}' && ok || ko "2 ranks differ by $d px (> 1e-6)"
[ "$nf" -eq 0 ] && ok || ko "$nf flags differ"
grep -q '^# mpi_ranks = 2$' two.txt && ok || ko "rank count not in the header"
# the field is right: the imposed uniform displacement (RMS 0.053 px with the ensemble's
# spline estimator on these 6 pairs, 0.050 px with --subpixel gauss)
rows two.txt | awk '{du = $3 - 2.3187; dv = $4 + 1.1471; e += du * du + dv * dv; n++}
    END {exit !(sqrt(e / n) < 0.06)}' && ok || ko "2-rank field is not (2.3187, -1.1471)"
# the final pass repeated (piv.ensemble_refine, tolerance 0: every repeat runs): every rank
# takes the same decisions from the same reduced field
ref=(-S piv.ensemble_refine=2 -S piv.ensemble_refine_tol_px=0 -S piv.ensemble_denoise=0)
"$bin" piv --ensemble -q "${ref[@]}" 's1/pair_*_[ab].tif' -o oner.txt && ok || ko "refined, one process"
mpi 2 "$bin" piv --ensemble -q "${ref[@]}" 's1/pair_*_[ab].tif' -o twor.txt 2>err && ok ||
    ko "refined, 2 ranks: $(cat err)"
read -r d nf nbad <<<"$(maxdiff oner.txt twor.txt)"
[ "$nbad" -eq 0 ] && [ "$nf" -eq 0 ] && awk -v d="$d" 'BEGIN {exit !(d <= 1e-6)}' && ok ||
    ko "refined ensemble, 2 ranks differ from one process by $d px ($nf flags)"
! cmp -s <(rows oner.txt) <(rows one.txt) && ok || ko "the repeats changed nothing"
mpi 1 "$bin" piv --ensemble -q --threads 1 's1/pair_*_[ab].tif' -o np1.txt &&
    "$bin" piv --ensemble -q --threads 1 's1/pair_*_[ab].tif' -o plain.txt && cmp -s np1.txt plain.txt \
    && ok || ko "mpirun -np 1 differs from a plain run"

# ---- per pair: each rank writes its pairs' files; rank 0 the mean and RMS -----------------
mkdir -p p1 p2
"$bin" piv -q 's1/pair_*_[ab].tif' --mean-rms -o p1/f.txt && ok || ko "per pair, one process"
mpi 2 "$bin" piv -q 's1/pair_*_[ab].tif' --mean-rms -o p2/f.txt 2>err && ok || ko "per pair, 2 ranks: $(cat err)"
for f in f_0001.txt f_0004.txt f_0006.txt f_mean.txt f_rms.txt; do
    cmp -s <(rows "p1/$f") <(rows "p2/$f") && ok || ko "per pair: $f differs between 1 process and 2 ranks"
done
ls p2 | grep -q tmp && ko "temporary files left: $(ls p2)"

# ---- a 2-rank run stopped by an unreadable pair keeps per-rank checkpoints and resumes -----
cp -r s1 s3
mv s3/pair_00004_b.tif s3/saved.tif
head -c 1000 s3/saved.tif >s3/pair_00004_b.tif
mpi 2 "$bin" piv --ensemble -q 's3/pair_*_[ab].tif' -o res.txt --checkpoint ck --checkpoint-every 1 2>err
[ $? -ne 0 ] && ok || ko "2 ranks: an unreadable pair did not stop the run"
grep -q 'pair 4 of 6: s3/pair_00004_b.tif' err && ok || ko "the unreadable pair is not named: $(cat err)"
[ -s ck.rank0 ] && [ -s ck.rank1 ] && ok || ko "per-rank checkpoints missing: $(ls)"
[ -e res.txt ] && ko "a failed run wrote its output"
"$bin" piv --ensemble -q 's3/pair_*_[ab].tif' -o res.txt --checkpoint ck --resume 2>err
[ $? -eq 1 ] && grep -q 'ck.rank0 is one of a run with several MPI ranks' err && ok \
    || ko "1-process resume of a 2-rank checkpoint: $(cat err)"
mv s3/saved.tif s3/pair_00004_b.tif
mpi 2 "$bin" piv --ensemble -q 's3/pair_*_[ab].tif' -o res.txt --checkpoint ck --resume 2>err \
    && ok || ko "2-rank resume: $(cat err)"
cmp -s <(rows res.txt) <(rows two.txt) && ok || ko "2-rank resume differs from an uninterrupted 2-rank run"
[ -e ck.rank0 ] || [ -e ck.rank1 ] && ko "checkpoints not removed after the run completed"

# ---- --skip-bad under 2 ranks: the pair is listed, the field equals one process's ----------
head -c 1000 s1/pair_00004_b.tif >s3/pair_00004_b.tif
mpi 2 "$bin" piv --ensemble -q --skip-bad 's3/pair_*_[ab].tif' -o sk2.txt 2>err && ok || ko "2 ranks --skip-bad: $(cat err)"
[ "$(grep -c 'warning: skipped: pair 4 of 6' err)" -eq 1 ] && ok || ko "skip warning (once, by the rank of pair 4): $(cat err)"
grep -q '^# skipped = 4 s3/pair_00004_a.tif s3/pair_00004_b.tif$' sk2.txt && ok || ko "skipped pair not in the header"
"$bin" piv --ensemble -q --skip-bad 's3/pair_*_[ab].tif' -o sk1.txt 2>/dev/null && ok || ko "1 process --skip-bad"
read -r d nf nbad <<<"$(maxdiff sk1.txt sk2.txt)"
awk -v d="$d" -v f="$nf" 'BEGIN {exit !(d <= 1e-6 && f == 0)}' && ok || ko "--skip-bad: 2 ranks differ by $d px, $nf flags"

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
