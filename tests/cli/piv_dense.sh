#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Dense grids (issue 20's hang): 8 px windows at 0.95 overlap put a vector on every pixel.
# A 512 x 512 pair (255 025 vectors) must finish in seconds: the warning's median peak ratio
# was found by an insertion sort, quadratic in the vectors (5.4 s at 256 x 256, about 90 s
# here, hours at 1024 x 1024). The median it prints must be the median of the file's peak
# ratios. SIGTERM and SIGINT inside a long pair (the passes of a 2048 x 2048 pair) stop it
# within seconds with exit 1 and one line naming the interruption, and write no output.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
cd "$tmp" || exit 1
rows() { grep -v '^#' "$1"; }
now() { date +%s.%N; }

"$bin" synth -q --pairs 1 --size 512x512 --seed 20 --out s || ko "synth 512"
t0=$(now)
timeout 60 "$bin" piv --window 8 --overlap 0.95 s/pair_00001_a.tif s/pair_00001_b.tif \
    -o d.txt 2>d.err
rc=$?
t1=$(now)
echo "512 x 512, 8 px windows at 0.95: exit $rc in $(echo "$t1 - $t0" | bc) s"
[ $rc -eq 0 ] && ok || ko "512 x 512 dense run: exit $rc (124: timed out) $(cat d.err)"
[ "$(rows d.txt | wc -l)" -eq $((505 * 505)) ] && ok || ko "$(rows d.txt | wc -l) vectors, expected 505^2"
# the warning (more than 10 % replaced on this sparse synthetic pair) and its median
med=$(sed -n 's/.*(median peak ratio \([0-9.]*\)).*/\1/p' d.err)
ref=$(rows d.txt | awk '$5 != 2 {print $6}' | sort -g | awk '{a[NR - 1] = $1} END {printf "%.2f", a[int(NR / 2)]}')
[ -n "$med" ] && [ "$med" = "$ref" ] && ok || ko "median peak ratio '$med', the file's is '$ref': $(cat d.err)"

# piv.max_mem_mb counts the fields, not only the frames (issue 20 item 12): the dense run
# needs about 28 MB (the process 18, two 1 MB frames, 255 025 vectors of 17 bytes twice and
# the validation's 12): refused at 20 MB up front, one line naming the estimate and the limit
"$bin" piv --window 8 --overlap 0.95 --set piv.max_mem_mb=20 s/pair_00001_a.tif \
    s/pair_00001_b.tif -o m.txt 2>m.err
rc=$?
[ $rc -eq 1 ] && [ "$(wc -l <m.err)" -eq 1 ] && [ ! -e m.txt ] &&
    grep -Eq '^rpiv: error: piv: the run needs about 2[0-9] MB \(.*\), above piv.max_mem_mb = 20$' m.err \
    && ok || ko "max_mem_mb 20: exit $rc, $(cat m.err)"

# a signal inside the passes of one long pair: stopped within seconds, nothing written
"$bin" synth -q --pairs 1 --size 2048x2048 --seed 21 --out L || ko "synth 2048"
for sig in TERM INT; do
    "$bin" piv -q --window 16,8,8,8 --overlap 0.95 L/pair_00001_a.tif L/pair_00001_b.tif \
        -o "L_$sig.txt" 2>"L_$sig.err" &
    pid=$!
    sleep 1.5
    t0=$(now)
    kill "-$sig" "$pid"
    n=0
    while kill -0 "$pid" 2>/dev/null && [ $n -lt 3000 ]; do sleep 0.01; n=$((n + 1)); done
    t1=$(now)
    kill -KILL "$pid" 2>/dev/null
    wait "$pid"
    rc=$?
    dt=$(echo "$t1 - $t0" | bc)
    echo "SIG$sig during the passes of a 2048 x 2048 pair: exit $rc after $dt s: $(cat "L_$sig.err")"
    [ $rc -eq 1 ] && ok || ko "SIG$sig: exit $rc, expected 1"
    echo "$dt < 5" | bc | grep -q 1 && ok || ko "SIG$sig: stopped after $dt s"
    [ "$(wc -l <"L_$sig.err")" -eq 1 ] && grep -q '^rpiv: error: .*interrupted' "L_$sig.err" \
        && ok || ko "SIG$sig message: $(cat "L_$sig.err")"
    [ ! -e "L_$sig.txt" ] && ok || ko "SIG$sig: an output was written"
done

echo "piv_dense: $pass passed, $fail failed"
[ $fail -eq 0 ]
