#!/usr/bin/env bash
# Condenses a CMake build's output (stdin) into its progress: cmake's "[ NN%] Building ..."
# lines become "  [ NN%] building FILE". On a terminal one line is rewritten in place; otherwise
# (a log, CI) a line is printed each time the percentage passes a multiple of 10. Compiler
# warnings and errors pass through whole. scripts/demo.sh pipes its build through it.
#   build_progress.sh [--tty | --no-tty]   (default: whether stdout is a terminal)
set -euo pipefail
tty=0
[[ -t 1 ]] && tty=1
case "${1:-}" in
  --tty) tty=1 ;;
  --no-tty) tty=0 ;;
  "") ;;
  *) echo "usage: build_progress.sh [--tty | --no-tty]" >&2; exit 2 ;;
esac
exec awk -v tty="$tty" '
  function finish_line() { if (tty && shown) { printf "\n"; shown = 0 } }
  /^\[ *[0-9]+%\] / {
    pct = $0; sub(/^\[ */, "", pct); sub(/%\].*/, "", pct); pct += 0
    what = $0; sub(/^\[ *[0-9]+%\] /, "", what)
    n = split(what, w, " "); file = w[n]; sub(/.*\//, "", file); sub(/\.o$/, "", file)
    line = sprintf("  [%3d%%] %s %s", pct, tolower(w[1]), file)
    if (tty) { printf "\r\033[K%s", line; shown = 1; fflush() }
    else if (pct >= next_pct) { print line; fflush(); next_pct = (int(pct / 10) + 1) * 10 }
    next
  }
  /warning:|error:|Error|\*\*\*/ { finish_line(); print; fflush() }
  END { finish_line() }
'
