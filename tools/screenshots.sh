#!/usr/bin/env bash
# Regenerates the README's pictures (docs/images/*.png): runs the showcase
# scenes with frames, serves each with `cloth view` and lets headless
# Chromium take the page in its check mode (one frame drawn, no controls
# moving). Needs chromium-headless-shell (Debian; .ci/run installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p cloth-tools
cloth=target/release/cloth
chromium=${CHROMIUM:-$(command -v chromium-headless-shell)}
out=$(mktemp -d)
trap 'rm -rf "$out"; kill $(jobs -p) 2>/dev/null || true' EXIT

# scene, picture, frame (every 9 steps: 0.1 s), port, and optionally a
# camera (yaw,pitch,distance,x,y,z: radians and metres) instead of the
# viewer's own
shoot() {
    "$cloth" run "fixtures/scenes/$1.toml" --out "$out/$1" --frames 9 --quiet
    "$cloth" view "$out/$1" --port "$4" --seconds 60 >/dev/null &
    sleep 0.5
    local camera=${5:+&camera=$5}
    "$chromium" --no-sandbox --use-gl=swiftshader --enable-unsafe-swiftshader --window-size=800,600 \
        --virtual-time-budget=30000 --screenshot="docs/images/$2.png" \
        "http://127.0.0.1:$4/?check&frame=$3$camera" 2>/dev/null
}
shoot drape-sphere drape-sphere last 8201
shoot flag flag 12 8202
shoot curtain curtain 41 8203
# The one-piece mid-stride, 2 s in (the mannequin 1 m along x).
shoot one-piece-walk one-piece 20 8204 0.9,0.2,2.0,1.0,0,1.0
