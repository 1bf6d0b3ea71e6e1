#!/usr/bin/env bash
# The whole pipeline on the embedded default data in fixtures/.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=target/release/lucent
out=demo-out

echo "== 1. Optical properties of the Covestro samples (Lorenz–Mie, 380–780 nm)"
echo "   (IOL1068-15 has no known weight percentage and is reported, not computed)"
"$bin" optics fixtures/samples --out "$out/optics" --skip-invalid

echo
echo "Results are in $out/:"
echo "  $out/optics/optical_properties.csv   table of all samples (also .json)"
echo "  $out/optics/optical_properties.png   μs, μa, g against wavelength"
echo "  $out/optics/IOL1068-NN/               phase tables and polar plots per sample"
