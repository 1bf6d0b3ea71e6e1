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
echo "== 2. BSSRDF slices at 550 nm, the three lab configurations (θi/θo = 45/0, 0/45, 45/15; φi 0°, φo 180°), to 5 % median per-pixel error or 45 s"
for s in IOL1068-09 IOL1068-16; do
  echo "-- $s"
  "$bin" bssrdf --recipe "fixtures/samples/$s.toml" --wavelength 550 --configs 45/0,0/45,45/15 \
    --crop --pixel-rel-error 0.05 --time-s 45 --quiet --out "$out/bssrdf/$s"
done

echo
echo "== 2b. Surface topography: the shipped height map (X3P) → microfacet normals, Trowbridge–Reitz and Beckmann fits"
"$bin" surface fit fixtures/surface/tr_0p0084.x3p --out "$out/surface"

echo
echo "== 3. Colour: ColorChecker calibration of a real chart photo (Argyll's colorchecker.jpg), ΔE2000 table"
"$bin" colour calibrate --image fixtures/colour/colorchecker.png --corners 5,6.5,196,6,195.5,133.5,3.5,133 --out "$out/colour"

echo
echo "== 4. Cameras: calibration from OpenCV's chessboard photos (9x6 inner corners), undistortion, board pose, HDR environment"
"$bin" calibrate --images 'fixtures/camera/chessboard/*.jpg' --board 9x6 --square-mm 25 --out "$out/camera/camera.json"
"$bin" undistort --camera "$out/camera/camera.json" fixtures/camera/chessboard/left12.jpg "$out/camera/left12_undistorted.png"
"$bin" pose --camera "$out/camera/camera.json" --image fixtures/camera/chessboard/left12.jpg --board 9x6 --square-mm 25 \
  --sample-corner 2,1 --sample-size-mm 100,60,6.35 --out "$out/camera/scene.json"
"$bin" env convert fixtures/env/studio.exr "$out/camera/environment.exr"
if [ -f /usr/share/doc/rawtran/IMG_5952.CR2 ]; then
  "$bin" raw decode /usr/share/doc/rawtran/IMG_5952.CR2 "$out/camera/IMG_5952.exr" --preview "$out/camera/IMG_5952.png"
fi
echo
echo "== 5. The digital twin in 3D: IOL1068-09 (from its recipe) on the checkerboard under the studio HDR on the finite sphere"
"$bin" render fixtures/render/demo.toml --spp 64 --time-s 150 --out "$out/render"

echo
echo "== 6. The whole digitisation from one project file (lucent run fixtures/demo/project.toml). The synthetic truth:"
echo "   six board views by a known camera (fixtures/demo/truth_camera.json), and a photo and empty board of IOL1068-09"
echo "   by that camera from view 1 with the environment scaled by 1.6; then every stage"
mkdir -p "$out/truth/views"
for k in 1 2 3 4 5 6; do
  "$bin" render "fixtures/demo/views/view$k.toml" --quiet --out "$out/truth/view$k"
  cp "$out/truth/view$k/render.png" "$out/truth/views/view$k.png"
done
"$bin" render fixtures/demo/truth.toml --size 160x120 --spp 128 --seed 1001 --quiet --out "$out/truth/photo"
"$bin" render fixtures/demo/truth_empty.toml --size 160x120 --spp 128 --seed 1002 --quiet --out "$out/truth/empty"
"$bin" run fixtures/demo/project.toml --out "$out/run"
echo "   truth: environment scale 1.6; recovered: $(grep -m1 '"new_scale"' "$out/run/env-scale/IOL1068-09/env_scale.json" | tr -d ' ,')"
echo "   truth camera: fx 530 fy 530 cx 330.5 cy 236.5 k1 -0.25 k2 0.10; recovered:" \
  $(grep -m7 -E '"(fx|fy|cx|cy|k1|k2|k3)"' "$out/run/calibrate/camera.json" | tr -d ' ,"') "(table in the report)"

echo
echo "Results are in $out/:"
echo "  $out/optics/optical_properties.csv   table of all samples (also .json)"
echo "  $out/optics/optical_properties.png   μs, μa, g against wavelength"
echo "  $out/optics/IOL1068-NN/               phase tables and polar plots per sample"
echo "  $out/bssrdf/IOL1068-NN/tiX_toY/      bssrdf.exr/.png, profile.csv/.png, summary.json; sweep.csv per sample"
echo "  $out/colour/ccm.json, chart.png, delta_e.png   colour-correction matrix, corrected chart, ΔE bars"
echo "  $out/camera/camera.json              intrinsics, distortion, per-view poses and RMS; camera_residuals.png, camera_views/"
echo "  $out/camera/scene.json               board and sample pose in the renderer's convention; left12_undistorted.png"
echo "  $out/render/render.exr, render.png   the rendered twin (linear CIE RGB with per-pixel variance; sRGB preview), render.json"
echo "  $out/camera/IMG_5952.exr/.json       a real CR2 as linear camera RGB with its metadata (if rawtran-doc is installed)"
echo "  $out/run/report/index.html          the run's report (optics, BSSRDF, env scale, triplet with RMSE/SSIM, calibration, manifest); metrics.json"
