#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv demo: --help, bad options (exit 2, one stderr line naming the option), an output folder
# that cannot be made (exit 1, names it), and a tiny run (--quick shrunk further: a 256 px band,
# 1 pair per P-PIV plane, 4 R-PIV pairs; seconds, also under the sanitizers) that writes the
# report, valid PNG plots, the data files and the summary on stdout, and whose R-PIV field
# rpiv synth + rpiv piv reproduce exactly from the files it wrote. The figures themselves are
# checked by tests/test_demo.c on a larger run. One thread: the results do not depend on it
# (test_demo.c checks), and two threads that spin at OpenMP barriers on a busy machine are
# several times slower.
set -u
bin=${RPIV_BIN:?}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# sanitizer builds: no list of the (fontconfig) suppressions used on stderr at exit
export LSAN_OPTIONS="${LSAN_OPTIONS:+$LSAN_OPTIONS:}print_suppressions=0"
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
is_png() { [ "$(head -c 8 "$1" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]; }
# expect_usage ARGS...: exit 2 and one stderr line
expect_usage() {
    "$bin" demo "$@" >"$tmp/out" 2>"$tmp/err"
    local rc=$?
    [ $rc -eq 2 ] && ok || ko "demo $*: exit $rc, expected 2"
    [ "$(wc -l <"$tmp/err")" -eq 1 ] && ok || ko "demo $*: $(wc -l <"$tmp/err") stderr lines"
}

"$bin" demo --help >"$tmp/help" && ok || ko "--help"
grep -q -- '--quick' "$tmp/help" && grep -q -- '--pairs' "$tmp/help" && ok || ko "help text"

expect_usage --pairs 0
grep -q -- '--pairs' "$tmp/err" && ok || ko "--pairs 0 not named: $(cat "$tmp/err")"
expect_usage --ppiv-pairs abc
grep -q -- '--ppiv-pairs' "$tmp/err" && ok || ko "--ppiv-pairs not named"
expect_usage --width 12
grep -q -- '--width' "$tmp/err" && ok || ko "--width not named"
expect_usage --frobnicate
grep -q -- 'frobnicate' "$tmp/err" && ok || ko "unknown option not named"
expect_usage extra-argument
grep -q -- 'extra-argument' "$tmp/err" && ok || ko "extra argument not named"
expect_usage --set camera.fnumber=-2
grep -q -- 'fnumber' "$tmp/err" && ok || ko "bad --set not named: $(cat "$tmp/err")"

# an output folder under a regular file
: >"$tmp/plain"
"$bin" demo --quick --quiet --out "$tmp/plain/out" >"$tmp/out" 2>"$tmp/err"
rc=$?
[ $rc -eq 1 ] && ok || ko "unwritable --out: exit $rc, expected 1"
grep -q "plain" "$tmp/err" && ok || ko "unwritable --out not named: $(cat "$tmp/err")"

# The --quiet run (checked at the end) starts now, in the background: both demo runs are one
# thread each and take most of this test's time, so running them side by side shortens the
# test's span. It is the tiny run below with --quiet: with 2 R-PIV pairs instead of 4 its
# CCM inversion (step 5) took 5-6 min of CPU under ASan+UBSan, against under a minute for
# the whole 4-pair demo; what it asserts (nothing on stderr over a whole demo) is unchanged.
"$bin" demo --quick --threads 1 --width 256 --ppiv-pairs 1 --pairs 4 --quiet --out "$tmp/q" >"$tmp/qout" \
    2>"$tmp/qerr" &
qpid=$!

# a tiny run
out="$tmp/run"
"$bin" demo --quick --threads 1 --width 256 --ppiv-pairs 1 --pairs 4 --out "$out" >"$tmp/out" 2>"$tmp/err"
rc=$?
[ $rc -eq 0 ] && ok || { ko "tiny run: exit $rc"; cat "$tmp/err" >&2; }
grep -q "report.md" "$tmp/out" && grep -q "R-PIV vs CCM" "$tmp/out" && ok || ko "summary on stdout"
grep -q "step 5/6" "$tmp/err" && ok || ko "no step lines on stderr"
for f in report.md report.html data/sheet_fit.txt data/rpiv.txt data/compare_x.txt \
    images/rpiv_a.tif; do
    [ -s "$out/$f" ] && ok || ko "$f missing"
done
n=0
for png in "$out"/*.png; do
    [ -e "$png" ] || continue
    n=$((n + 1))
    name=$(basename "$png")
    is_png "$png" && ok || ko "$name: not a PNG"
    grep -q "($name)" "$out/report.md" && ok || ko "$name not in report.md"
    # embedded as a data URI that decodes to the PNG's bytes: report.html stands alone
    grep -o "<img data-file=\"$name\" src=\"data:image/png;base64,[^\"]*\"" "$out/report.html" |
        sed 's/.*base64,//; s/"$//' | base64 -d 2>/dev/null | cmp -s - "$png" &&
        ok || ko "$name not embedded in report.html"
done
[ "$n" -ge 14 ] && ok || ko "only $n plots"
grep -q '<img src=' "$out/report.html" && ko "report.html links an image instead of embedding it" || ok
grep -q 'Notation and equations' "$out/report.html" && ok || ko "no notation in report.html"
# the demo composes the commands: the same R-PIV pairs and field through rpiv synth and
# rpiv piv with the parameter file and the mask the demo wrote
"$bin" synth --quiet --threads 1 --config "$out/data/rpiv.ini" --out "$tmp/pairs" && ok || ko "rpiv synth --config data/rpiv.ini"
cmp -s "$tmp/pairs/pair_00001_a.tif" "$out/images/rpiv_a.tif" && ok || ko "rpiv synth made another frame A"
"$bin" piv --quiet --threads 1 --config "$out/data/rpiv.ini" --mask "$out/data/mask.png" "$tmp/pairs/pair_*" \
    -o "$tmp/rpiv.txt" && ok || ko "rpiv piv --config data/rpiv.ini"
"$bin" compare --component u "$out/data/rpiv.txt" "$tmp/rpiv.txt" >"$tmp/cmp" && ok || ko "rpiv compare"
[ "$(awk '$1 == "E1" { print $2 }' "$tmp/cmp")" = 0 ] && ok || ko "rpiv piv field differs: $(cat "$tmp/cmp")"

# --quiet: nothing on stderr (the run started in the background above)
wait "$qpid" && ok || ko "quiet run"
[ ! -s "$tmp/qerr" ] && ok || ko "--quiet wrote on stderr: $(head -3 "$tmp/qerr")"

echo "demo: $pass passed, $fail failed"
[ $fail -eq 0 ]
