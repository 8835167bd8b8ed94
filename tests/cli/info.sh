#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv info: describes the real fixture pair; a truncated or missing file gives a non-zero exit
# and exactly one stderr line naming the file; the other files are still described.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
data=${RPIV_TEST_DATA:?RPIV_TEST_DATA not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() {
    echo "FAIL: $*" >&2
    exit 1
}

# Values verified independently from the raw strip bytes (docs/images.md).
a="$data/Oseen_center_01.tif"
b="$data/Oseen_center_02.tif"
out=$("$bin" info "$a" "$b" 2>"$tmp/err") || fail "info on the fixture pair exited $?"
[ -s "$tmp/err" ] && fail "info printed on stderr: $(cat "$tmp/err")"
want_a="$a: format TIFF width 400 height 300 bits 8 pages 1 min 0 max 255 mean 32.340208"
want_b="$b: format TIFF width 400 height 300 bits 8 pages 1 min 0 max 255 mean 32.480817"
[ "$out" = "$want_a"$'\n'"$want_b" ] || fail "unexpected output:"$'\n'"$out"

jpg="$data/Jet_0001A_crop96x64.jpg"
out=$("$bin" info "$jpg") || fail "info on the JPEG fixture exited $?"
case "$out" in
"$jpg: format JPEG width 96 height 64 bits 8 pages 1 min 0 max 255 mean 10.7"*) ;;
*) fail "unexpected JPEG line: $out" ;;
esac

# one bad file -> exit 1, one stderr line naming it
check_bad() { # file, expected word in the message
    local f=$1 word=$2 rc
    "$bin" info "$f" >"$tmp/out" 2>"$tmp/err"
    rc=$?
    [ "$rc" -eq 1 ] || fail "info $f: exit $rc, expected 1"
    [ "$(wc -l <"$tmp/err")" -eq 1 ] || fail "info $f: stderr is not one line: $(cat "$tmp/err")"
    grep -qF "rpiv: error: $f" "$tmp/err" || fail "info $f: message does not name the file: $(cat "$tmp/err")"
    grep -qi "$word" "$tmp/err" || fail "info $f: message lacks '$word': $(cat "$tmp/err")"
    [ -s "$tmp/out" ] && fail "info $f: printed on stdout: $(cat "$tmp/out")"
    return 0
}
head -c 60000 "$a" >"$tmp/cut.tif"
check_bad "$tmp/cut.tif" truncated
check_bad "$tmp/missing.tif" "cannot open"
: >"$tmp/empty.png"
check_bad "$tmp/empty.png" "0 bytes"
# issue 20 item 8: a FIFO hung in a blocking open() (timeout: exit 124 before the fix)
mkfifo "$tmp/fifo.png"
timeout 10 "$bin" info "$tmp/fifo.png" >/dev/null 2>&1
[ $? -eq 1 ] || fail "info on a FIFO did not fail at once"
check_bad "$tmp/fifo.png" "not a regular file"

# good, bad, good, bad: both good files described, one stderr line per bad file
"$bin" info "$a" "$tmp/cut.tif" "$b" "$tmp/missing.tif" >"$tmp/out" 2>"$tmp/err"
rc=$?
[ "$rc" -eq 1 ] || fail "mixed files: exit $rc, expected 1"
[ "$(wc -l <"$tmp/out")" -eq 2 ] || fail "mixed files: stdout: $(cat "$tmp/out")"
[ "$(wc -l <"$tmp/err")" -eq 2 ] || fail "mixed files: stderr: $(cat "$tmp/err")"
grep -q "cut.tif" "$tmp/err" && grep -q "missing.tif" "$tmp/err" || fail "mixed: $(cat "$tmp/err")"

# usage
"$bin" info --help >"$tmp/out" || fail "info --help exited $?"
grep -q "usage: rpiv info" "$tmp/out" || fail "info --help: $(cat "$tmp/out")"
"$bin" info >/dev/null 2>"$tmp/err"
rc=$?
[ "$rc" -eq 2 ] || fail "info without files: exit $rc, expected 2"
"$bin" info --bogus "$a" >/dev/null 2>"$tmp/err"
rc=$?
[ "$rc" -eq 2 ] || fail "info --bogus: exit $rc, expected 2"
echo "info.sh: all checks passed"
