#!/usr/bin/env bash
# The whole pipeline on the embedded default data in fixtures/.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=target/release/lucent
out=demo-out

# Expected duration first: the renders and slices are capped by time, so the total hardly depends on the machine
# beyond its core count (16.8 min measured on 2 cores, issue 52).
cores=$(nproc 2>/dev/null || echo 2)
echo "make demo: the whole pipeline on the shipped samples, into $out/."
if [ "$cores" -le 2 ]; then
  echo "Expect about 15-17 minutes on this machine's $cores core(s); the longest steps (2, 2c, 5, 6) say what they run."
else
  echo "Expect about 15-17 minutes on 2 cores, less on this machine's $cores (the slices and renders stop at error targets"
  echo "or time caps); the longest steps (2, 2c, 5, 6) say what they run."
fi
echo

echo "== 1. Optical properties of the Covestro samples (Lorenz–Mie, 380–780 nm)"
echo "   (IOL1068-15 has no known weight percentage and is reported, not computed)"
"$bin" optics fixtures/samples --out "$out/optics" --skip-invalid

echo
echo "== 2. (at most 90 s per slice, 6 slices) BSSRDF slices at 550 nm, the three lab configurations (θi/θo = 45/0, 0/45, 45/15; φi 0°, φo 180°), to 5 % median per-pixel error or 90 s"
for s in IOL1068-09 IOL1068-16; do
  echo "-- $s"
  "$bin" bssrdf --recipe "fixtures/samples/$s.toml" --wavelength-nm 550 --configs 45/0,0/45,45/15 \
    --crop --pixel-rel-error 0.05 --time-s 90 --quiet --out "$out/bssrdf/$s"
done

echo
echo "== 2b. Surface topography: the shipped height map (X3P) → microfacet normals, Trowbridge–Reitz and Beckmann fits"
"$bin" surface fit fixtures/surface/tr_0p0084.x3p --out "$out/surface"

echo
echo "== 2c. (at most 180 s) The same IOL1068-09 slice (45°/15°) through a rough top: the measured normals of 2b (--roughness measured:fit.json)"
"$bin" bssrdf --recipe fixtures/samples/IOL1068-09.toml --wavelength-nm 550 --theta-i 45 --theta-o 15 \
  --roughness "measured:$out/surface/fit.json" --crop --pixel-rel-error 0.05 --time-s 180 --quiet --out "$out/bssrdf/IOL1068-09-rough"

echo
echo "== 2d. Inverse fit (lucent fit): slices of IOL1068-09 simulated at 0.425 wt-% play the measurement"
echo "   (45°/0°, 30°/0°); the fit starts from the recipe's 0.65 wt-%, the lab's example"
"$bin" bssrdf --recipe fixtures/fit/IOL1068-09_truth_0425.toml --wavelength-nm 550 --configs 45/0,30/0 \
  --crop --paths 100000 --seed 101 --quiet --out "$out/fit_measured"
"$bin" fit --recipe fixtures/samples/IOL1068-09.toml --free weight_percent --rel-error 0.01 --quiet \
  --measured "$out/fit_measured/ti45_to0/bssrdf.exr" "$out/fit_measured/ti30_to0/bssrdf.exr" --out "$out/fit"
echo "   truth: 0.425 wt-% (the weight percentage the lab reached by hand from 0.65)"

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
echo "== 4b. 360° camera → the environment the render (5) uses: a synthetic panorama (studio.exr at 2048 × 1024, turned to"
echo "   CIE XYZ (D50), with a ColorChecker and the level 9x6 board pasted in) seen by a 360° camera with a known colour"
echo "   matrix, shot as five 8-bit brackets through the sRGB curve; merged back (camera response recovered), the chart"
echo "   view cut out and its colour calibrated, the map converted to CIE RGB with that matrix and oriented from the board"
e="$out/env360"
mkdir -p "$e"
# studio.exr is CIE RGB (white E); as CIE XYZ adapted to D50 (Bradford), the inverse of `colour apply --to cie-rgb`.
"$bin" env convert fixtures/env/studio.exr "$e/studio_xyz.exr" \
  --matrix "0.488178,0.305648,0.170374;0.175361,0.824177,0.000462;-0.001259,0.016741,0.809418" >/dev/null
"$bin" synth chart --size 480x320 --out "$e/chart_xyz.exr" >/dev/null
"$bin" env paste "$e/studio_xyz.exr" --image "$e/chart_xyz.exr" --yaw 150 --pitch -20 --fov 40 --width 2048 --out "$e/with_chart.exr"
"$bin" env paste "$e/with_chart.exr" --chessboard 9x6 --yaw 27 --pitch -90 --fov 70 --out "$e/truth_xyz.exr"
# The 360° camera's RGB: a known XYZ → camera matrix (the truth the colour stage recovers, up to a scale).
"$bin" env convert "$e/truth_xyz.exr" "$e/truth_camera.exr" --matrix "1.6,-0.3,-0.2;-0.6,1.5,0.1;0.05,-0.2,1.1"
"$bin" env brackets "$e/truth_camera.exr" --exposures 1/128,1/32,1/8,1/2,2 --out "$e/brackets"
"$bin" env merge "$e"/brackets/bracket_{1,2,3,4,5}.png --exposures 1/128,1/32,1/8,1/2,2 --out "$e/env.exr"
"$bin" env view "$e/env.exr" --yaw 150 --pitch -20 --fov 50 --size 960x720 --out "$e/chart_view.exr"
"$bin" env view "$e/env.exr" --yaw 150 --pitch -20 --fov 50 --size 960x720 --out "$e/chart_preview.png" >/dev/null
"$bin" colour calibrate --image "$e/chart_view.exr" --clip-level none --out "$e/colour" | grep -E "found|mean"
echo "   truth: camera → XYZ = s · inverse(XYZ → camera) = s · [[0.678 0.150 0.110] [0.270 0.718 -0.016] [0.018 0.124 0.901]];"
echo "   recovered (ccm.json):" $(tr -d ' \n' < "$e/colour/ccm.json" | grep -o '"matrix":\[\[[^]]*\],\[[^]]*\],\[[^]]*\]\]')
"$bin" colour apply --ccm "$e/colour/ccm.json" "$e/env.exr" "$e/env_cie.exr" --to cie-rgb
"$bin" env orient "$e/env_cie.exr" --board-view 0,-90,100 --board 9x6 --square-mm 30 --out "$e/env_cie_oriented.exr"
echo "   truth: numbered from its light outer square, the board's i axis is at azimuth 117° in the map (pasted at yaw 27°),"
echo "   so the orienting yaw is −117°"
# The truth in CIE RGB: the pasted panorama through the inverse of the first matrix (XYZ D50 → CIE RGB, as colour apply).
"$bin" env convert "$e/truth_xyz.exr" "$e/truth_cie.exr" \
  --matrix "2.357608,-0.864255,-0.495758;-0.501639,1.397237,0.104792;0.014042,-0.030243,1.232517" >/dev/null
echo "   the map against its truth (the pasted panorama in CIE RGB), mean radiance over the sphere, R G B:"
echo "     truth   $("$bin" env info "$e/truth_cie.exr" | tr -d ' \n' | grep -o '"mean_over_sphere":\[[^]]*\]' | cut -d: -f2)"
echo "     env_cie $("$bin" env info "$e/env_cie.exr" | tr -d ' \n' | grep -o '"mean_over_sphere":\[[^]]*\]' | cut -d: -f2)"
"$bin" env convert "$e/env_cie_oriented.exr" "$e/env_cie_oriented.png" >/dev/null
# The render's scene: fixtures/render/demo.toml with this map, its yaw from the orientation file (paths from $e).
{
  echo "# Written by scripts/demo.sh (4b) from fixtures/render/demo.toml: its map is the 360° camera's env_cie.exr, the yaw"
  echo "# from env_cie_oriented.json (the board found in the map); paths are relative to this file."
  sed -e 's#^recipe = "\.\./#recipe = "../../fixtures/#' -e 's#^map = "\.\./env/studio\.exr"#map = "env_cie.exr"#' \
    -e 's#^yaw_deg = 0\.0#orientation = "env_cie_oriented.json"#' fixtures/render/demo.toml
} > "$e/scene.toml"
[ "$(grep -cE '^(recipe = "\.\./\.\./fixtures/|map = "env_cie\.exr"|orientation = )' "$e/scene.toml")" = 3 ] \
  || { echo "demo.sh: fixtures/render/demo.toml changed; cannot point its copy at the 360° map" >&2; exit 1; }
rm -f "$e/studio_xyz.exr" "$e/with_chart.exr" "$e/truth_xyz.exr" "$e/truth_cie.exr"
echo
echo "== 5. (at most 150 s) The digital twin in 3D: IOL1068-09 (from its recipe) on the checkerboard under the 360° camera's environment"
echo "   of 4b (merged, colour-calibrated to CIE RGB, oriented) on the finite sphere: fixtures/render/demo.toml with that map"
"$bin" render "$out/env360/scene.toml" --spp 4096 --target-rel-error 0.05 --time-s 150 --out "$out/render"

echo
echo "== 6. (the longest step: truth renders, then every stage with one status line each) The whole digitisation from one project file (lucent run fixtures/demo/project.toml). The synthetic truth:"
echo "   six board views by a known camera (fixtures/demo/truth_camera.json), and a photo and empty board of IOL1068-09"
echo "   by that camera from view 1 with the environment scaled by 1.6, captured as Bayer DNGs by a phone"
echo "   with a known colour response; then every stage"
mkdir -p "$out/truth/views"
for k in 1 2 3 4 5 6; do
  "$bin" render "fixtures/demo/views/view$k.toml" --quiet --out "$out/truth/view$k"
  cp "$out/truth/view$k/render.png" "$out/truth/views/view$k.png"
done
# At the camera's 640 × 480: the pipeline bins the photos 2 × 2 to its 320 × 240 renders (a photo at the
# render's own size would carry the Bayer mosaic's colour fringes into the comparison). Uniform
# sampling, as a camera's noise is: an error target alone would weight the samples towards the plaque.
"$bin" render fixtures/demo/truth.toml --spp 1024 --target-rel-error 0.05 --sampling uniform --seed 1001 --quiet \
  --out "$out/truth/photo"
echo "   IOL1068-09's \"measured\" slices (45°/0°, 30°/0°) simulated at the hidden 0.425 wt-% (Monte Carlo noise ≈ 3 %)"
"$bin" bssrdf --recipe fixtures/fit/IOL1068-09_truth_0425.toml --wavelength-nm 550 --configs 45/0,30/0 \
  --crop --paths 100000 --seed 301 --quiet --out "$out/truth/slices"
"$bin" render fixtures/demo/truth_empty.toml --spp 16 --seed 1002 --quiet --out "$out/truth/empty"
echo "   the synthetic phone (fixtures/demo/truth_colour.json) captures a ColorChecker and both photos as Bayer DNGs with noise"
"$bin" synth chart --out "$out/truth/chart.exr"
"$bin" synth raw "$out/truth/chart.exr" "$out/truth/chart.dng" --truth fixtures/demo/truth_colour.json --space xyz-d50 --exposure 0.8 --seed 11
"$bin" synth raw "$out/truth/photo/render.exr" "$out/truth/photo.dng" --truth fixtures/demo/truth_colour.json --exposure 0.8 --seed 12
"$bin" synth raw "$out/truth/empty/render.exr" "$out/truth/empty.dng" --truth fixtures/demo/truth_colour.json --exposure 0.8 --seed 13
"$bin" run fixtures/demo/project.toml --out "$out/run"
# The loop's truth vs recovered, as the report states it (samples.IOL1068-09.loop of its metrics.json;
# the truth from the sample's truth_recipe, which no stage reads).
loop_value() { grep -A40 '"loop": {' "$out/run/report/metrics.json" | grep -m1 "\"$1\"" | sed -E 's/^[^:]*: *//; s/[",]//g'; }
echo "   the loop: truth $(loop_value truth) wt-% (fixtures/fit/IOL1068-09_truth_0425.toml, hidden from the pipeline);" \
  "fitted from the slices: $(loop_value recovered)," \
  "95 %:" $(grep -m1 -A3 '"interval_95"' "$out/run/fit/IOL1068-09/fit.json" | tr -d ' "[]' | tr -s ',\n' '  ' | sed 's/interval_95://')
echo "   which twin is closer to the photo over the plaque's pixels, A (recipe, 0.65 wt-%) or B (fitted): $(loop_value verdict)" \
  "(p = $(loop_value p_value)); the fitted twin named closer at p < 0.01: $(loop_value fitted_named_closer_at_p_below_0_01)"
echo "   the photo's noise model (develop/IOL1068-09/photo_variance.noise.json): from" \
  "$(grep -m1 '"source"' "$out/run/develop/IOL1068-09/photo_variance.noise.json" | sed -E 's/^[^:]*: *//; s/[",]//g')"
echo "   truth: environment scale 1.6; recovered: $(grep -m1 '"new_scale"' "$out/run/env-scale/IOL1068-09/env_scale.json" | tr -d ' ,')"
echo "   truth colour response (fixtures/demo/truth_colour.json) vs the matrix recovered from the captured chart:" \
  $(grep -A4 '"truth_vs_recovered": {' "$out/run/report/metrics.json" | grep -A3 -m1 '"de2000_max"' | tr -d ' ,"{}' | tr '\n' ' ')
echo "   truth camera: fx 530 fy 530 cx 330.5 cy 236.5 k1 -0.25 k2 0.10; recovered:" \
  $(grep -m7 -E '"(fx|fy|cx|cy|k1|k2|k3)"' "$out/run/calibrate/camera.json" | tr -d ' ,"') "(table in the report)"

echo
echo "Results are in $out/:"
echo "  $out/optics/optical_properties.csv   table of all samples (also .json)"
echo "  $out/optics/optical_properties.png   μs, μa, g against wavelength"
echo "  $out/optics/IOL1068-NN/               phase tables and polar plots per sample"
echo "  $out/bssrdf/IOL1068-NN/tiX_toY/      bssrdf.exr/.png, profile.csv/.png, summary.json; sweep.csv per sample"
echo "  $out/fit/                            fit.json (weight-% ± error), objective.png, IOL1068-09_fitted.toml (fit_measured/: its slices)"
echo "  $out/surface/                        fit.json, heightmap.png, distribution.png, normals.exr of the shipped height map"
echo "  $out/bssrdf/IOL1068-09-rough/         the 45°/15° slice through the measured rough surface (summary.json: config.roughness)"
echo "  $out/colour/ccm.json, chart.png, delta_e.png   colour-correction matrix, corrected chart, ΔE bars"
echo "  $out/camera/camera.json              intrinsics, distortion, per-view poses and RMS; camera_residuals.png, camera_views/"
echo "  $out/camera/scene.json               board and sample pose in the renderer's convention; left12_undistorted.png"
echo "  $out/render/render.exr, render.png   the rendered twin under env360/env_cie.exr (linear CIE RGB with per-pixel variance; sRGB preview), render.json"
echo "  $out/camera/IMG_5952.exr/.json       a real CR2 as linear camera RGB with its metadata (if rawtran-doc is installed)"
echo "  $out/run/report/index.html          the run's report (optics, BSSRDF, env scale, triplet with RMSE/SSIM, calibration, manifest); metrics.json"
echo "  $out/env360/env.exr, env.json          the 360° panorama merged from brackets/ (camera RGB; dynamic range, response)"
echo "  $out/env360/chart_preview.png, colour/    the chart cut out of the panorama and the 360° camera's colour matrix (ccm.json, ΔE)"
echo "  $out/env360/env_cie.exr, env_cie_oriented.exr/.json/.png/_board.png, scene.toml   the map in CIE RGB, its orientation, the render's scene"
