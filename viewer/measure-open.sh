#!/usr/bin/env bash
# Measures a replay page: its size and how long headless Chromium takes to open it, parse its
# data and draw the first frame (the page's data-drawn-ms, performance.now() at the first draw,
# from navigation start). Usage: viewer/measure-open.sh [PEGTWIN] [RUNS]
# The trial: the cross at 0.5 mm, the manifold method observing 16 s (about 19 s simulated).
set -euo pipefail
pegtwin="${1:-target/release/pegtwin}"
runs="${2:-5}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
"$pegtwin" trial --geometry cross --clearance-mm 0.5 --seed 5 --t-obs 16 --replay "$work/r.html" \
  | grep -E "^(outcome|time)"
echo "page: $(stat -c %s "$work/r.html") bytes"
for i in $(seq "$runs"); do
  rm -rf "$work/profile"
  chromium --headless --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader \
    --disable-background-networking --disable-component-update --disable-sync --no-first-run \
    --user-data-dir="$work/profile" --window-size=1280,800 --dump-dom "file://$work/r.html#t=5" \
    2>/dev/null | grep -o 'data-drawn-ms="[0-9]*"' | tr -dc '0-9' | sed "s/^/open $i: /; s/$/ ms\n/"
done
