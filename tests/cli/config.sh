#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# rpiv config: the printed configuration reproduces itself; bad keys and values give exit 2
# and one stderr line naming file:line and the key.
set -u
bin=${RPIV_BIN:?}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }

"$bin" config --set camera.fnumber=8 --set piv.windows=96,48 >"$tmp/a.ini" && ok || ko "config"
"$bin" config --config "$tmp/a.ini" >"$tmp/b.ini" && ok || ko "config reload"
cmp -s "$tmp/a.ini" "$tmp/b.ini" && ok || ko "config does not reproduce itself"
grep -q '^fnumber = 8$' "$tmp/b.ini" && ok || ko "override lost"

check_err() { # file-content expected-substring
    printf '%b' "$1" >"$tmp/bad.ini"
    "$bin" config --config "$tmp/bad.ini" >/dev/null 2>"$tmp/err"
    rc=$?
    lines=$(wc -l <"$tmp/err")
    if [ "$rc" -eq 2 ] && [ "$lines" -eq 1 ] && grep -q "$2" "$tmp/err"; then ok
    else ko "bad config '$1': rc=$rc lines=$lines: $(cat "$tmp/err")"; fi
}
check_err '[piv]\noverlapp = 0.5\n' 'bad.ini:2.*overlapp'
check_err '[camera]\n\nfnumber = -1\n' 'bad.ini:3.*fnumber'
check_err '[nosuch]\nx = 1\n' 'nosuch'
check_err '[piv]\nwindows = 64,2000\n' 'windows'

# issue 20 item 3: libinih cut lines at 199 characters, so a long path did not read back
long=/$(printf 'p%.0s' $(seq 1 400))/profile.txt
"$bin" config --set "sheet.profile=$long" >"$tmp/long.ini" && ok || ko "config with a long path"
"$bin" config --config "$tmp/long.ini" >"$tmp/long2.ini" 2>"$tmp/err" && ok || ko "long path does not read back: $(cat "$tmp/err")"
cmp -s "$tmp/long.ini" "$tmp/long2.ini" && ok || ko "long path changed on the round trip"
# a value the reader would not give back is refused by the writer
"$bin" config --set "output.dir=a ; b" >/dev/null 2>"$tmp/err"; rc=$?
[ "$rc" -ne 0 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && grep -q "output.dir" "$tmp/err" && ok || ko "unreadable value written: rc=$rc $(cat "$tmp/err")"
# issue 20 item 5: --config DIRECTORY was accepted silently
"$bin" config --config "$tmp" >/dev/null 2>"$tmp/err"; rc=$?
[ "$rc" -eq 1 ] && grep -q "not a regular file" "$tmp/err" && ok || ko "--config DIR: rc=$rc $(cat "$tmp/err")"
mkfifo "$tmp/fifo.ini"
timeout 10 "$bin" config --config "$tmp/fifo.ini" >/dev/null 2>"$tmp/err"; rc=$?
[ "$rc" -eq 1 ] && ok || ko "--config FIFO: rc=$rc $(cat "$tmp/err")"
"$bin" config --config "$tmp/missing.ini" >/dev/null 2>"$tmp/err"
rc=$?
[ "$rc" -eq 1 ] && grep -q 'missing.ini' "$tmp/err" && ok || ko "missing file rc=$rc"
"$bin" nosuchcommand 2>/dev/null; [ $? -eq 2 ] && ok || ko "unknown command"
"$bin" config --bogus 2>"$tmp/err"; [ $? -eq 2 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && ok || ko "unknown option"
"$bin" --version | grep -q '^rpiv ' && ok || ko "--version"
# docs/config.md carries the generated key reference: it must match the table
if [ -n "${RPIV_SOURCE_DIR:-}" ]; then
    "$bin" config --doc >"$tmp/doc.md"
    sed -n '/^## Keys$/,$p' "$RPIV_SOURCE_DIR/docs/config.md" | tail -n +2 >"$tmp/have.md"
    cmp -s "$tmp/doc.md" "$tmp/have.md" && ok || ko "docs/config.md is stale: regenerate with rpiv config --doc"
fi
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
