#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Bad input through the rpiv program (issue 2 "bad input", issue 8 "hostile input"): each case
# must exit non-zero (2 for usage and configuration errors, 1 for bad files), print exactly
# one line on stderr, "rpiv: error: ...", that names the file (or key, or option) and the
# problem, and never crash (exit status < 128: no signal, no sanitizer abort).
# Cases needing a command that is still a placeholder ("not implemented yet") are skipped with
# a note; they run as soon as the command exists.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
data=${RPIV_TEST_DATA:?RPIV_TEST_DATA not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0 skip=0

ko() {
    echo "FAIL: $*" >&2
    fail=$((fail + 1))
}

# expect RC NAME WORD... -- ARGS...: run rpiv ARGS; stderr must be one line starting with
# "rpiv: error: " and containing NAME and each WORD (case-insensitive); stdout empty.
expect() {
    local rc_want=$1 name=$2
    shift 2
    local words=()
    while [ "$1" != "--" ]; do
        words+=("$1")
        shift
    done
    shift
    "$bin" "$@" >"$tmp/out" 2>"$tmp/err"
    local rc=$? what="rpiv $*"
    if [ "$rc" -ge 128 ]; then
        ko "$what: crashed (exit $rc): $(head -c 2000 "$tmp/err")"
        return
    fi
    if [ "$rc" -ne "$rc_want" ]; then
        ko "$what: exit $rc, expected $rc_want; stderr: $(head -c 500 "$tmp/err")"
        return
    fi
    local lines
    lines=$(wc -l <"$tmp/err")
    if [ "$lines" -ne 1 ]; then
        ko "$what: $lines stderr lines, expected 1: $(head -c 1000 "$tmp/err")"
        return
    fi
    if ! grep -q '^rpiv: error: ' "$tmp/err"; then
        ko "$what: stderr is not 'rpiv: error: ...': $(cat "$tmp/err")"
        return
    fi
    if ! grep -qF -- "$name" "$tmp/err"; then
        ko "$what: message does not name '$name': $(cat "$tmp/err")"
        return
    fi
    for w in "${words[@]}"; do
        if ! grep -qiF -- "$w" "$tmp/err"; then
            ko "$what: message lacks '$w': $(cat "$tmp/err")"
            return
        fi
    done
    if [ -s "$tmp/out" ]; then
        ko "$what: printed on stdout: $(head -c 300 "$tmp/out")"
        return
    fi
    pass=$((pass + 1))
}

note_skip() {
    echo "SKIP: $*"
    skip=$((skip + 1))
}

# A command exists when its --help succeeds (placeholders fail with "not implemented yet").
has_cmd() {
    "$bin" "$1" --help >/dev/null 2>&1
}

# ---- image files: rpiv info ------------------------------------------------------------
tif="$data/Oseen_center_01.tif"
: >"$tmp/zero.tif"
expect 1 "$tmp/zero.tif" "empty" "0 bytes" -- info "$tmp/zero.tif"
head -c 60000 "$tif" >"$tmp/cut.tif" # the strip is cut; the directory at the start stays
expect 1 "$tmp/cut.tif" "truncated" -- info "$tmp/cut.tif"
head -c 7 "$tif" >"$tmp/header_only.tif"
expect 1 "$tmp/header_only.tif" "TIFF" -- info "$tmp/header_only.tif"
expect 1 "$tmp/missing.tif" "cannot open" -- info "$tmp/missing.tif"
mkdir "$tmp/folder.tif"
expect 1 "$tmp/folder.tif" "not a regular file" -- info "$tmp/folder.tif"

# 6x5 16-bit grey PNG (fuzz/corpus/png/g16.png)
png64='iVBORw0KGgoAAAANSUhEUgAAAAYAAAAFEAAAAAATox55AAAAPUlEQVQImWNkYODUhUGGguYXSxKO3HgayHZSjfEh+3MRGGQM7A5jD+MIYw9jD+NgOMTfzuXDIvD/6i+b0wCELxXNIgpHZAAAAABJRU5ErkJggg=='
echo "$png64" | base64 -d >"$tmp/good.png"
if ! "$bin" info "$tmp/good.png" >"$tmp/out" 2>&1 ||
    ! grep -q "format PNG width 6 height 5 bits 16" "$tmp/out"; then
    ko "the reference PNG does not read: $(cat "$tmp/out")"
else
    pass=$((pass + 1))
fi
head -c 80 "$tmp/good.png" >"$tmp/cut.png" # inside the IDAT chunk
expect 1 "$tmp/cut.png" "truncated" -- info "$tmp/cut.png"
head -c 20 "$tmp/good.png" >"$tmp/cut_header.png" # inside IHDR
expect 1 "$tmp/cut_header.png" "PNG" -- info "$tmp/cut_header.png"
# flip one byte of the IDAT data (offset 50): its CRC no longer matches
cp "$tmp/good.png" "$tmp/crc.png"
printf '\x55' | dd of="$tmp/crc.png" bs=1 seek=50 conv=notrunc status=none
expect 1 "$tmp/crc.png" "CRC" -- info "$tmp/crc.png"
# flip one byte of the IHDR CRC itself (offset 29)
cp "$tmp/good.png" "$tmp/crc_ihdr.png"
printf '\x00' | dd of="$tmp/crc_ihdr.png" bs=1 seek=29 conv=notrunc status=none
expect 1 "$tmp/crc_ihdr.png" "CRC" -- info "$tmp/crc_ihdr.png"

# unsupported depth, unknown format, absurd and implausible sizes (refused before allocating)
printf 'P5 2 2 70000\n\0\0\0\0\0\0\0\0' >"$tmp/depth.pgm"
expect 1 "$tmp/depth.pgm" "maxval" -- info "$tmp/depth.pgm"
printf 'GIF89a\1\0\1\0' >"$tmp/image.gif"
expect 1 "$tmp/image.gif" "unknown image format" -- info "$tmp/image.gif"
printf 'P5 99999 99999 255\n\1\2' >"$tmp/absurd.pgm"
expect 1 "$tmp/absurd.pgm" "absurd" -- info "$tmp/absurd.pgm"
printf 'P5 40000 40000 255\n\1\2' >"$tmp/bomb.pgm" # 1.6 Gpx announced, 2 bytes present
expect 1 "$tmp/bomb.pgm" "truncated" -- info "$tmp/bomb.pgm"

# ---- configuration: rpiv config --------------------------------------------------------
printf '[piv]\nwindowz = 32\n' >"$tmp/key.ini"
expect 2 "$tmp/key.ini:2" "unknown key" "windowz" -- config --config "$tmp/key.ini"
printf '[camera]\nfnumber = 5.6\n\n[piv]\noverlap = nan\n' >"$tmp/nan.ini"
expect 2 "$tmp/nan.ini:5" "piv.overlap" "nan" -- config --config "$tmp/nan.ini"
expect 2 "camera.fnumber" "nan" -- config --set camera.fnumber=NaN
printf '[camera]\nwidth_px = -64\n' >"$tmp/negative.ini"
expect 2 "$tmp/negative.ini:2" "width_px" -- config --config "$tmp/negative.ini"
expect 2 "--set" "needs a value" -- config --set
expect 1 "$tmp/none.ini" "cannot open" -- config --config "$tmp/none.ini"

# ---- unknown options: every implemented command ----------------------------------------
expect 2 "--no-such-option" -- --no-such-option
expect 2 "frobnicate" -- frobnicate
for cmd in $("$bin" --help | awk '/^  [a-z]+ / {print $1}'); do
    if has_cmd "$cmd"; then
        expect 2 "--no-such-option" "unknown option" -- "$cmd" --no-such-option
    else
        note_skip "rpiv $cmd --no-such-option: '$cmd' is not implemented yet"
    fi
done

# ---- vector and profile files: rpiv compare --------------------------------------------
printf '0 0 1 0\n16 0 1 0\n0 16 1 0\n16 16 1 0\n' >"$tmp/ref.txt"
printf '0 0 1 0\n16 0 nan 0\n0 16 1 0\n16 16 1 0\n' >"$tmp/nan.txt"
expect 1 "$tmp/nan.txt:2" "NaN" -- compare "$tmp/ref.txt" "$tmp/nan.txt"
printf '0 0 1 0\n16 0 1 0\n7 0 1 0\n' >"$tmp/grid.txt"
expect 1 "$tmp/grid.txt:" "regular grid" -- compare "$tmp/grid.txt" "$tmp/ref.txt"
: >"$tmp/empty.txt"
expect 1 "$tmp/empty.txt" "no data" -- compare "$tmp/empty.txt" "$tmp/ref.txt"

# ---- image pairs and runs: rpiv piv ------------------------------------------------------
if has_cmd piv; then
    b16="$tmp/small.pgm" # 4x4 frame: a mismatched partner of the 400x300 fixture
    printf 'P5 4 4 255\n0123456789abcdef' >"$b16"
    expect 1 "$b16" "$tif" "differ" -- piv --out "$tmp/o1" "$tif" "$b16"
    printf '%s %s\n%s %s\n' "$tif" "$data/Oseen_center_02.tif" "$tif" "$tmp/gone.tif" \
        >"$tmp/list.txt"
    expect 1 "$tmp/gone.tif" "pair 2 of 2" "cannot open" -- piv --out "$tmp/o2" "$tmp/list.txt"
    expect 2 "piv.windows" "larger than the image" -- piv --out "$tmp/o3" \
        --set piv.windows=512,256 "$tif" \
        "$data/Oseen_center_02.tif"
else
    note_skip "mismatched pair, missing file in a list (with its index), window larger than" \
        "the image: 'rpiv piv' is not implemented yet"
fi

# A vector file with a NUL byte in a line (binary junk) is refused, not read up to the NUL.
printf '# x y u v\n1 2 3 4\n\0 5 6 7 8\n' >"$tmp/nul.txt"
printf '# x y u v\n1 2 3 4\n5 6 7 8\0 9\n' >"$tmp/nul2.txt"
expect 1 "$tmp/nul.txt:3" "NUL byte" -- compare "$tmp/nul.txt" "$tmp/nul.txt"
expect 1 "$tmp/nul2.txt:3" "NUL byte" -- compare "$tmp/nul2.txt" "$tmp/nul2.txt"

# Options: an option that takes a value but is given none, and an unknown one, for every
# command (getopt's two errors, told apart).
for c in piv synth raytrace ccm duct compare demo config; do
    expect 2 "--threads" "needs a value" -- "$c" --threads
    expect 2 "--no-such-option" "unknown option" -- "$c" --no-such-option
done
expect 2 "--rays" "needs a value" -- raytrace --rays
expect 2 "--threads" "needs a value" -- calib sheet --threads
expect 2 "-Q" "unknown option" -- info -Q

echo "bad_input: $pass passed, $fail failed, $skip skipped"
[ "$fail" -eq 0 ]
