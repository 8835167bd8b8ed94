#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv plot and rpiv piv --plot: the figure is a complete PNG of 1000 x 800 px (every chunk's
# CRC checked, IEND last); a non-.png output, a missing field file, an unknown quantity and a
# file format plot cannot read give a one-line error naming the file, exit 2 (or 1 for a
# missing file), and write nothing; --plot p.jpg fails before any PIV work. A NetCDF file of
# rpiv piv (image or y-up, pixels or physical units) gives the same figure numbers as the text
# file of the same field; --time out of range, --time on a text file, a .vtk file and a file
# that is not NetCDF are one-line errors.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
data=${RPIV_TEST_DATA:?RPIV_TEST_DATA not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() {
    echo "FAIL: $*" >&2
    exit 1
}

# "W H" of a complete PNG (signature, chunks with valid CRCs up to IEND, nothing after), or
# "bad: why".
png_check() {
    /usr/bin/python3 - "$1" <<'PY'
import struct, sys, zlib
b = open(sys.argv[1], "rb").read()
if b[:8] != b"\x89PNG\r\n\x1a\n":
    print("bad: signature"); sys.exit()
at, size, end = 8, None, False
while at + 12 <= len(b):
    n, = struct.unpack(">I", b[at:at + 4]); kind = b[at + 4:at + 8]
    body = b[at + 8:at + 8 + n]
    if len(body) != n or struct.unpack(">I", b[at + 8 + n:at + 12 + n])[0] != zlib.crc32(kind + body):
        print("bad: chunk %r" % kind); sys.exit()
    if kind == b"IHDR": size = struct.unpack(">II", body[:8])
    at += 12 + n
    if kind == b"IEND": end = True; break
if not end or at != len(b) or size is None:
    print("bad: no IEND at the end"); sys.exit()
print(size[0], size[1])
PY
}

a="$data/Oseen_center_01.tif"
b="$data/Oseen_center_02.tif"
"$bin" piv "$a" "$b" -o "$tmp/f.txt" --plot "$tmp/p.png" -q || fail "piv --plot exited $?"
[ "$(png_check "$tmp/p.png")" = "1000 800" ] || fail "piv --plot: $(png_check "$tmp/p.png")"

out=$("$bin" plot "$tmp/f.txt" -o "$tmp/m.png" 2>"$tmp/err") || fail "plot exited $?: $(cat "$tmp/err")"
[ "$(png_check "$tmp/m.png")" = "1000 800" ] || fail "plot: $(png_check "$tmp/m.png")"
# the Oseen pair's displacements are 1.1..4.2 px: the reference arrow is 2 px/dt
case "$out" in
*"magnitude "*", reference 2 px/dt") ;;
*) fail "unexpected summary: $out" ;;
esac

# every option, a y-up file with physical units, the image underneath
"$bin" piv "$a" "$b" -o "$tmp/up.txt" --y-up --scale 0.1 --dt 0.001 -q || fail "piv --y-up exited $?"
out=$("$bin" plot "$tmp/up.txt" -o "$tmp/u.PNG" --quantity v --background "$a" --every 2 \
    --arrow-scale 1.5) || fail "plot with every option exited $?"
[ "$(png_check "$tmp/u.PNG")" = "1000 800" ] || fail "plot options: $(png_check "$tmp/u.PNG")"
case "$out" in
*"arrows every 2, reference "*" m/s") ;;
*) fail "unexpected summary: $out" ;;
esac
"$bin" plot "$tmp/f.txt" -o "$tmp/n.png" --quantity none --background "$a" -q ||
    fail "plot --quantity none exited $?"
[ "$(png_check "$tmp/n.png")" = "1000 800" ] || fail "plot none: $(png_check "$tmp/n.png")"

# errors: exit code, one stderr line naming the file and the fault, nothing written
check_err() { # expected exit, file named, word, command...
    local want=$1 name=$2 word=$3 rc
    shift 3
    "$@" >"$tmp/out" 2>"$tmp/err"
    rc=$?
    [ "$rc" -eq "$want" ] || fail "$*: exit $rc, expected $want"
    [ "$(wc -l <"$tmp/err")" -eq 1 ] || fail "$*: stderr is not one line: $(cat "$tmp/err")"
    grep -qF "rpiv: error: " "$tmp/err" || fail "$*: not an rpiv error: $(cat "$tmp/err")"
    grep -qF -- "$name" "$tmp/err" || fail "$*: message does not name $name: $(cat "$tmp/err")"
    grep -qF -- "$word" "$tmp/err" || fail "$*: message lacks '$word': $(cat "$tmp/err")"
}
check_err 2 "$tmp/x.jpg" "PNG only" "$bin" plot "$tmp/f.txt" -o "$tmp/x.jpg"
[ -e "$tmp/x.jpg" ] && fail "plot -o x.jpg wrote x.jpg"
check_err 2 "$tmp/x" "PNG only" "$bin" plot "$tmp/f.txt" -o "$tmp/x"
check_err 2 "$tmp/p.jpg" "PNG only" "$bin" piv "$a" "$b" -o "$tmp/g.txt" --plot "$tmp/p.jpg"
[ -e "$tmp/p.jpg" ] || [ -e "$tmp/g.txt" ] && fail "piv --plot p.jpg wrote a file"
check_err 1 "$tmp/missing.txt" "missing.txt" "$bin" plot "$tmp/missing.txt" -o "$tmp/y.png"
check_err 2 "$tmp/f.txt" "unknown quantity 'vorticity'" "$bin" plot "$tmp/f.txt" -o "$tmp/y.png" \
    --quantity vorticity
grep -qF "magnitude, u, v, peak_ratio, correlation" "$tmp/err" ||
    fail "unknown quantity: the message does not list the field's quantities: $(cat "$tmp/err")"
# NetCDF: the same field as the text file gives the same figure's numbers, in both
# orientations and with physical units; --time picks a step, out of range is an error
"$bin" piv "$a" "$b" -o "$tmp/f.nc" -q || fail "piv -o f.nc exited $?"
"$bin" piv "$a" "$b" -o "$tmp/up.nc" --y-up --scale 0.1 --dt 0.001 -q || fail "piv -o up.nc exited $?"
for base in f up; do
    t=$("$bin" plot "$tmp/$base.txt" -o "$tmp/t.png" --every 2) || fail "plot $base.txt exited $?"
    n=$("$bin" plot "$tmp/$base.nc" -o "$tmp/c.png" --every 2 --time 0) || fail "plot $base.nc exited $?"
    [ "${t#*.png: }" = "${n#*.png: }" ] || fail "$base.nc and $base.txt differ: '$n' vs '$t'"
    [ "$(png_check "$tmp/c.png")" = "1000 800" ] || fail "plot $base.nc: $(png_check "$tmp/c.png")"
done
rm -f "$tmp/y.png"
check_err 2 "$tmp/f.nc" "time step 1 outside 0..0" "$bin" plot "$tmp/f.nc" -o "$tmp/y.png" --time 1
check_err 2 "--time" ".nc" "$bin" plot "$tmp/f.txt" -o "$tmp/y.png" --time 0
"$bin" piv "$a" "$b" -o "$tmp/f.vtk" -q || fail "piv -o f.vtk exited $?"
check_err 2 "$tmp/f.vtk" ".nc" "$bin" plot "$tmp/f.vtk" -o "$tmp/y.png"
printf 'not netcdf\n' >"$tmp/bad.nc"
check_err 1 "$tmp/bad.nc" "not a NetCDF file" "$bin" plot "$tmp/bad.nc" -o "$tmp/y.png"
check_err 1 "$tmp/nope.tif" "nope.tif" "$bin" plot "$tmp/f.txt" -o "$tmp/y.png" --background "$tmp/nope.tif"
check_err 2 "--every" "range" "$bin" plot "$tmp/f.txt" -o "$tmp/y.png" --every -1
check_err 2 "-o OUT.png" "no output" "$bin" plot "$tmp/f.txt"
[ -e "$tmp/y.png" ] && fail "a failed plot wrote y.png"
echo "plot: all checks passed"
