#!/usr/bin/env bash
# Long renders of the exact walk (no estimator approximation) of the demo
# scene's plaque, the reference the similar medium's bias is measured
# against on the plaque's interior (tests/render.rs reads them):
#   fixtures/reference/render/exact_IOL1068-09.exr  (the demo plaque)
#   fixtures/reference/render/exact_IOL1068-13.exr  (the PVP plaque)
# The scene is fixtures/render/demo.toml with its estimator keys removed
# (similarity_g, similarity_floor_events) and its spp, the recipe swapped
# for the family. Each render runs one thread for TIME_S seconds (default
# 7200) or to 1 % per pixel on the plaque, whichever comes first.
# Usage: tools/reference/exact_walk.sh [LUCENT] [TIME_S]   (from the repository root)
set -euo pipefail
lucent=${1:-target/release/lucent}
time_s=${2:-7200}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
root=$(pwd)
for family in 09 13; do
  sed -e '/^similarity_g/d' -e '/^similarity_floor_events/d' -e '/^spp = /d' \
      -e "s#\"\.\./samples/IOL1068-09.toml\"#\"$root/fixtures/samples/IOL1068-$family.toml\"#" \
      -e "s#\"\.\./env/studio.exr\"#\"$root/fixtures/env/studio.exr\"#" \
      fixtures/render/demo.toml > "$work/exact_$family.toml"
  "$lucent" render "$work/exact_$family.toml" --out "$work/out_$family" --size 160x120 --seed "7$family" \
    --threads 1 --time-s "$time_s" --target-rel-error 0.01 --quiet &
done
wait
mkdir -p fixtures/reference/render
for family in 09 13; do
  cp "$work/out_$family/render.exr" "fixtures/reference/render/exact_IOL1068-$family.exr"
  cp "$work/out_$family/render.json" "fixtures/reference/render/exact_IOL1068-$family.json"
done
