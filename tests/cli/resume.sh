#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Checkpoints of ensemble runs: a run killed with SIGKILL in its first pass, resumed and killed
# again in a later pass, then resumed to the end, writes the same bytes as a run never
# interrupted; SIGTERM saves the checkpoint and exits 1 with a message; a checkpoint of
# another plan or series, a corrupt or truncated one, is refused with a message naming it, and
# a run without --resume does not overwrite a checkpoint; --resume without a checkpoint starts
# from the beginning; option errors exit 2. A per-pair .nc series stopped by SIGINT, SIGTERM or
# SIGHUP leaves a complete OUT.nc untouched and writes the fields done into OUT_partial.nc.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
export RPIV_PROGRESS_DELAY=0 # the test watches the progress lines
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
cd "$tmp" || exit 1

# Run "$@" in the background, stderr to $1; send signal $3 once its progress line (one every
# 10 %; a checkpoint is on disk before each) reaches decile $2. Returns the exit status.
run_until() {
    local log=$1 dec=$2 sig=$3 pid n=0
    shift 3
    "$@" 2>"$log" &
    pid=$!
    while kill -0 "$pid" 2>/dev/null && [ $n -lt 12000 ]; do
        if awk -v d="$dec" '/^(ensemble|piv): [0-9]+\/[0-9]+ \(/ {split($2, a, "/");
            if (10 * a[1] >= d * a[2]) f = 1} END {exit !f}' "$log"; then
            kill "-$sig" "$pid"
            break
        fi
        n=$((n + 1))
        sleep 0.01
    done
    wait "$pid"
}

"$bin" synth --size 256x256 --pairs 8 --seed 6271 --flow oseen:3.7,45 --out s -q || ko "synth"
pairs='s/pair_*_[ab].tif'
"$bin" piv --ensemble -q "$pairs" -o ref.txt || ko "uninterrupted run"

# ---- SIGKILL in pass 1, again in pass 2 or 3, then to the end ----------------------------------
run_until err1 1 KILL "$bin" piv --ensemble "$pairs" -o out.txt --checkpoint ck --checkpoint-every 1
[ $? -eq 137 ] && ok || ko "run 1 was not killed (it ended before the first progress line?)"
[ -s ck ] && ok || ko "no checkpoint after SIGKILL"
[ -e out.txt ] && ko "a killed run wrote its output"
run_until err2 5 KILL "$bin" piv --ensemble "$pairs" -o out.txt --checkpoint ck --checkpoint-every 1 --resume
[ $? -eq 137 ] && ok || ko "run 2 was not killed"
"$bin" piv --ensemble "$pairs" -o out.txt --checkpoint ck --checkpoint-every 1 --resume 2>err3 \
    && ok || ko "final resume: $(cat err3)"
grep -Eq '^rpiv piv: resumed from ck: pass [23], [0-9]+ pairs? already summed$' err3 && ok \
    || ko "the second resume did not start in pass 2 or 3: $(grep resumed err3)"
cmp -s ref.txt out.txt && ok || ko "killed twice and resumed: the field differs from an uninterrupted run"
[ -e ck ] && ko "checkpoint left after the run completed"
ls | grep -q 'ck\.tmp' && ko "temporary checkpoint files of the killed runs left: $(ls | tr '\n' ' ')"

# ---- SIGTERM: checkpoint saved, exit 1, a message; resumed to the same bytes ----------------
# (a checkpoint after every pair and one thread make the run slow enough for the signal to
# arrive before its end on a fast machine: --checkpoint-every 1000 raced)
run_until err4 2 TERM "$bin" piv --ensemble "$pairs" -o term.txt --checkpoint ck --checkpoint-every 1 --threads 1
[ $? -eq 1 ] && ok || ko "SIGTERM: exit status is not 1"
grep -Eq '^rpiv: error: ensemble: interrupted in pass [0-9] after [0-9]+ of 8 pairs; checkpoint ck saved' err4 \
    && ok || ko "SIGTERM message: $(grep error err4)"
"$bin" piv --ensemble -q "$pairs" -o term.txt --checkpoint ck --resume && cmp -s ref.txt term.txt \
    && ok || ko "resumed after SIGTERM: differs"

# issue 20 item 13: SIGHUP killed the run (no checkpoint); now handled as SIGTERM
run_until err4h 2 HUP "$bin" piv --ensemble "$pairs" -o hup.txt --checkpoint ckh --checkpoint-every 1 --threads 1
[ $? -eq 1 ] && [ -s ckh ] && ok || ko "SIGHUP: not stopped as SIGTERM: $(grep error err4h)"
ls | grep -q 'ckh\.tmp' && ko "SIGHUP left a temporary file: $(ls | tr '\n' ' ')"
"$bin" piv --ensemble -q "$pairs" -o hup.txt --checkpoint ckh --resume && cmp -s ref.txt hup.txt \
    && ok || ko "resumed after SIGHUP: differs"

# ---- a per-pair .nc series stopped by a signal: never over a complete file ----------------------
# (issue 20 item 13: SIGINT published the partial series over the complete one)
"$bin" synth --size 256x256 --pairs 24 --seed 6272 --flow oseen:3.7,45 --out s24 -q || ko "synth 24"
# one thread and a dense grid: ~50 ms a pair, so that the signal comes mid-run on an idle machine
slow=(--threads 1 --overlap 0.9)
"$bin" piv -q "${slow[@]}" 's24/pair_*_[ab].tif' -o ser.nc || ko "per-pair .nc series"
cp ser.nc ser.keep
for sig in INT TERM HUP; do
    rm -f ser_partial.nc
    run_until "errs$sig" 3 $sig "$bin" piv "${slow[@]}" 's24/pair_*_[ab].tif' -o ser.nc
    st=$?
    [ $st -eq 1 ] && ok || ko "SIG$sig in a .nc series: exit $st, $(tr "\n" " " <"errs$sig")"
    cmp -s ser.nc ser.keep && ok || ko "SIG$sig: the complete series was replaced"
    if grep -q 'no field done' "errs$sig"; then
        ko "SIG$sig came before the first field: $(grep error "errs$sig")"
    else
        grep -Eq '^rpiv: error: piv: interrupted after [0-9]+ of 24 pairs; the fields done are in ser_partial.nc \(ser.nc not written\)$' "errs$sig" \
            && ok || ko "SIG$sig message: $(grep error "errs$sig")"
        /usr/bin/python3 - ser_partial.nc ser.keep <<'PY' && ok || ko "SIG$sig: the partial series"
import sys
import netCDF4
part, full = (netCDF4.Dataset(p) for p in sys.argv[1:3])
n = len(part.dimensions["t"])
assert 1 <= n < 24, n
assert part.getncattr("rpiv_partial").startswith("piv: interrupted after"), part.ncattrs()
assert "rpiv_partial" not in full.ncattrs()
for v in ("u", "v"):  # the fields done equal the complete run's first n
    assert (part[v][:] == full[v][:, :, :n]).all(), v
PY
    fi
    ls | grep -q 'ser.*\.tmp' && ko "SIG$sig left a temporary file: $(ls | tr '\n' ' ')"
done

# ---- checkpoints that do not belong to the run -------------------------------------------------
run_until err5 1 TERM "$bin" piv --ensemble "$pairs" -o x.txt --checkpoint ck --checkpoint-every 1000
[ -s ck ] || ko "no checkpoint for the refusal tests"
cp ck ck.keep
# a new run does not overwrite it without --resume
"$bin" piv --ensemble -q "$pairs" -o x.txt --checkpoint ck 2>err
[ $? -eq 2 ] && grep -q '^rpiv: error: ck: a checkpoint is already there: continue it (rpiv piv --resume) or remove it' err \
    && ok || ko "existing checkpoint without --resume: $(cat err)"
"$bin" piv --ensemble -q --window 48,24 "$pairs" -o x.txt --checkpoint ck --resume 2>err
[ $? -eq 1 ] && grep -q "^rpiv: error: ck: checkpoint of another plan (.*windows 64x64,32x32,32x32.*); this run: .*windows 48x48,24x24" err \
    && ok || ko "another plan: $(cat err)"
"$bin" piv --ensemble -q 's/pair_0000[1-7]_[ab].tif' -o x.txt --checkpoint ck --resume 2>err
[ $? -eq 1 ] && grep -q "^rpiv: error: ck: checkpoint of another series of pairs (8 pairs, .*); this run has 7 pairs" err \
    && ok || ko "another series: $(cat err)"
# the same count, first and last pair, but two pairs in between swapped: the message must not
# show two identical descriptions (issue 20 item 14)
for i in 1 2 4 3 5 6 7 8; do echo "s/pair_0000${i}_a.tif s/pair_0000${i}_b.tif"; done >swapped.txt
"$bin" piv --ensemble -q swapped.txt -o x.txt --checkpoint ck --resume 2>err
[ $? -eq 1 ] && grep -q "^rpiv: error: ck: checkpoint of another series of pairs (8 pairs, .*); this run has 8 pairs, .*: the same count, first and last pair, another pair or order in between" err \
    && ok || ko "another series, same ends: $(cat err)"
# junk appended to a checkpoint (issue 20 item 13: it was accepted)
cp ck appended
printf 'junk' >>appended
"$bin" piv --ensemble -q "$pairs" -o x.txt --checkpoint appended --resume 2>err
[ $? -eq 1 ] && grep -q "^rpiv: error: appended: 4 bytes after the checkpoint's end (byte [0-9]*): refused$" err \
    && ok || ko "junk appended: $(cat err)"
printf 'not a checkpoint\n' >junk
"$bin" piv --ensemble -q "$pairs" -o x.txt --checkpoint junk --resume 2>err
[ $? -eq 1 ] && grep -q '^rpiv: error: junk: not an rpiv checkpoint$' err && ok || ko "junk: $(cat err)"
head -c 3000 ck >trunc
"$bin" piv --ensemble -q "$pairs" -o x.txt --checkpoint trunc --resume 2>err
[ $? -eq 1 ] && grep -q '^rpiv: error: trunc: truncated checkpoint$' err && ok || ko "truncated: $(cat err)"
cp ck flipped
size=$(stat -c %s flipped)
printf '\x7f' | dd of=flipped bs=1 seek=$((size - 100)) conv=notrunc 2>/dev/null
"$bin" piv --ensemble -q "$pairs" -o x.txt --checkpoint flipped --resume 2>err
[ $? -eq 1 ] && grep -q '^rpiv: error: flipped: corrupt checkpoint (checksum mismatch)$' err && ok || ko "corrupt: $(cat err)"
[ -e x.txt ] && ko "a refused resume wrote an output"
cmp -s ck ck.keep && ok || ko "a refused resume changed the checkpoint"
# no checkpoint: the run begins, says so, and ends with the same field
"$bin" piv --ensemble "$pairs" -o fresh.txt --checkpoint none.ck --resume 2>err && cmp -s ref.txt fresh.txt \
    && ok || ko "--resume without a checkpoint"
grep -q '^rpiv piv: no checkpoint none.ck: started from the beginning$' err && ok || ko "no notice: $(cat err)"

# ---- option errors: exit 2, one line naming the option -------------------------------------------
for args in "--checkpoint c.ck" "--resume" "--ensemble --resume" "--ensemble --checkpoint-every 5" \
    "--ensemble --checkpoint c.ck --checkpoint-every 0" "--ensemble --checkpoint="; do
    # shellcheck disable=SC2086
    "$bin" piv $args "$pairs" -o y.txt 2>err
    st=$?
    [ $st -eq 2 ] && [ "$(wc -l <err)" -eq 1 ] && grep -q -- '--checkpoint\|--resume' err && ok \
        || ko "'$args': exit $st, $(cat err)"
done

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
