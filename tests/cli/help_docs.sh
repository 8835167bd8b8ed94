#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Every option of every command (rpiv --list-options, made from the commands' option tables)
# appears in that command's --help and in docs/rpiv.1: in the command's section of COMMAND
# OPTIONS, or, for the options every command takes, in COMMON OPTIONS. So neither the help
# nor the manual can drift from what the parser accepts.
set -u
bin=${RPIV_BIN:?}
man=${RPIV_SOURCE_DIR:?}/docs/rpiv.1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }

# the manual's text with roff's \- and font escapes removed; one file per section
sed -e 's/\\-/-/g' -e 's/\\f[BIRP]//g' "$man" >"$tmp/man"
awk -v dir="$tmp" '/^\.SH / { sh = $2 " " $3; ss = "" }
                   /^\.SS / { ss = $2 }
                   sh == "COMMAND OPTIONS" && ss != "" { print > (dir "/man_" ss) }
                   sh == "COMMON OPTIONS" { print > (dir "/man_common") }' "$tmp/man"
# an option as a word: --x matches "--x X*" and "--x," but not "--xstar"
has() { grep -qE -- "(^|[^a-z0-9-])$2([^a-z0-9-]|$)" "$1" 2>/dev/null; }

"$bin" --list-options >"$tmp/list" && [ -s "$tmp/list" ] && ok || ko "rpiv --list-options"
"$bin" --help >"$tmp/help_rpiv" && ok || ko "rpiv --help"
while read -r cmd opt; do
    if [ "$cmd" = common ]; then
        has "$tmp/help_rpiv" "$opt" && ok || ko "rpiv --help does not list the common option $opt"
        has "$tmp/man_common" "$opt" && ok || ko "docs/rpiv.1: COMMON OPTIONS lacks $opt"
        continue
    fi
    [ -s "$tmp/help_$cmd" ] || "$bin" "$cmd" --help >"$tmp/help_$cmd" 2>&1 || ko "rpiv $cmd --help"
    has "$tmp/help_$cmd" "$opt" && ok || ko "rpiv $cmd --help does not list $opt"
    if grep -qx "common $opt" "$tmp/list"; then
        has "$tmp/man_common" "$opt" && ok || ko "docs/rpiv.1: COMMON OPTIONS lacks $opt"
    else
        has "$tmp/man_$cmd" "$opt" && ok || ko "docs/rpiv.1: the section of $cmd lacks $opt"
    fi
done <"$tmp/list"
# every command of rpiv --help has its section in the manual
for cmd in $(awk '/^  [a-z]+ / {print $1}' "$tmp/help_rpiv"); do
    [ -s "$tmp/man_$cmd" ] && ok || ko "docs/rpiv.1: no section for $cmd under COMMAND OPTIONS"
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
