"""Writes the bad-input corpus of tests/bad_inputs.rs (run from the repository root).

numpy 2.4.6, Pillow 13.0.0, OpenEXR 3.5.3. Each file is one class of bad input
for one reader; tests/bad/README.md lists them with the command that reads them.
"""
import json, os
import numpy as np
from PIL import Image

B = "tests/bad/"
def w(path, data, mode="w"):
    os.makedirs(os.path.dirname(B + path), exist_ok=True)
    with open(B + path, mode) as f:
        f.write(data)

# --- recipes (lucent optics)
good = open("fixtures/samples/IOL1068-09.toml").read()
w("recipe/not_toml.toml", "name = \"x\nthickness_mm = [6.35\n")
w("recipe/unknown_key.toml", good.replace("thickness_mm = 6.35", "thickness_mm = 6.35\nthicknes_mm = 6.0"))
w("recipe/negative_weight.toml", good.replace("weight_percent = 0.65", "weight_percent = -0.65"))
w("recipe/missing_index_file.toml", good.replace('index = "builtin:PC_Zhang2020"', 'index = "no_such_index.yml"'))
w("recipe/zero_thickness.toml", good.replace("thickness_mm = 6.35", "thickness_mm = 0"))

# --- refractive-index YAML (read through a recipe naming it)
def index_case(name, yml):
    w(f"index/{name}.yml", yml)
    w(f"index/{name}.toml", good.replace('index = "builtin:PC_Zhang2020"', f'index = "{name}.yml"'))
index_case("bad_number", "DATA:\n  - type: tabulated nk\n    data: |\n        0.4 1.5 0\n        0.5 1,49 0\n        0.8 1.48 0\n")
index_case("not_increasing", "DATA:\n  - type: tabulated nk\n    data: |\n        0.4 1.5 0\n        0.8 1.49 0\n        0.5 1.48 0\n")
index_case("no_data", "REFERENCES: nothing\n")
index_case("unknown_type", "DATA:\n  - type: tabulated xyz\n    data: |\n        0.4 1.5 0\n        0.8 1.49 0\n")
index_case("negative_kappa", "DATA:\n  - type: tabulated nk\n    data: |\n        0.4 1.5 -0.1\n        0.8 1.49 0\n")
# Sellmeier-2 with C0 and C1 only: the term's C2 was taken as 0 without a word.
index_case("formula_half_pair", "DATA:\n  - type: formula 2\n    wavelength_range: 0.3 1.5\n    coefficients: 0 1.4182\n")

# --- project files (lucent run)
w("project/not_toml.toml", '[project]\nname = "x\nseed = 1\n')
w("project/unknown_key.toml", '[project]\nname = "x"\nsead = 1\n')
w("project/missing_recipe.toml", '[[sample]]\nname = "a"\nrecipe = "no_such_recipe.toml"\n')
w("project/bad_configs.toml", '[bssrdf]\nconfigs = "45-0"\npaths = 10\n')
w("project/executor_kind.toml", '[executor]\nkind = "pbs"\n')
w("project/executor_shards.toml", '[executor]\nkind = "slurm"\nshards = 0\n')
w("project/executor_time_limit.toml", '[executor]\nkind = "slurm"\ntime_limit = "2 hours"\n')
w("project/executor_sbatch.toml", '[executor]\nkind = "slurm"\nsbatch = ["--array=0-9"]\n')

# --- slices (lucent bssrdf compare --measured)
os.makedirs(B + "slice", exist_ok=True)
Image.fromarray((np.arange(33 * 33).reshape(33, 33) % 256).astype(np.uint8)).save(B + "slice/integer_8bit.tif")
w("slice/not_square.csv", "1,2,3\n4,5,6\n")
w("slice/nan.csv", "1,2\nnan,4\n")
w("slice/ragged.csv", "1,2\n3\n")
w("slice/text.tif", "this is not a TIFF\n")
w("slice/no_rows.csv", "# only a comment\n")
w("slice/negative_pixel.csv", "1,2,1\n2,4,-2\n1,2,1\n")
w("slice/semicolons.csv", "1;2;1\n2;4;2\n1;2;1\n")
exr = open("fixtures/reference/compare/base.exr", "rb").read()
w("slice/truncated.exr", exr[: len(exr) // 3], "wb")
w("slice/empty.exr", b"", "wb")

# --- EXR files (every reader of lucent::exr: an image, a compare input, a
# render's object layer, a slice, a height map); huge_size_claimed.exr is copied from slice/
w("exr/truncated.exr", exr[: len(exr) // 3], "wb")
w("exr/empty.exr", b"", "wb")
w("exr/cut_in_header.exr", exr[:300], "wb")
w("exr/text.exr", "this is not an OpenEXR file\n")

# --- beam maps (lucent bssrdf --beam-map)
w("beam/negative.csv", "0,1\n-1,0\n")
w("beam/all_zero.csv", "0,0\n0,0\n")
w("beam/nan.csv", "0,1\nnan,0\n")
# Uniform 1.5 mm square at the corpus command's 0.01 mm: Gaussian-equivalent FWHM 1.02 mm > the 9-pixel slice (0.93 mm).
w("beam/wider_than_slice.csv", "".join(",".join(["1"] * 150) + "\n" for _ in range(150)))

# --- camera files (lucent undistort --camera)
cam = json.load(open("fixtures/demo/truth_camera.json"))
def camera_case(name, edit):
    c = json.loads(json.dumps(cam)); edit(c["camera"])
    w(f"camera/{name}.json", json.dumps(c, indent=1) + "\n")
camera_case("fx_zero", lambda c: c["intrinsics"].update(fx=0.0))
camera_case("fy_negative", lambda c: c["intrinsics"].update(fy=-530.0))
camera_case("k1_huge", lambda c: c["distortion"].update(k1=1e6))
camera_case("principal_point_far", lambda c: c["intrinsics"].update(cx=5000.0))
camera_case("folding_distortion", lambda c: c["distortion"].update(k1=-1.5, k2=0.0))
camera_case("zero_width", lambda c: c.update(image_width=0))
w("camera/truncated.json", json.dumps(cam, indent=1)[:300])

# --- scene files of lucent pose (read by a render scene's [camera] scene_json)
w("scene/not_json.json", "camera at (NaN, NaN, NaN)\n")
w("scene/null_intrinsics.json", json.dumps({"units": "metres", "intrinsics": None}) + "\n")
for name in ["not_json", "null_intrinsics"]:
    w(f"scene/{name}.toml", f'[camera]\nscene_json = "{name}.json"\n\n[environment]\nconstant = [1.0, 1.0, 1.0]\n')

# --- RAW (lucent raw decode)
w("raw/text.cr2", "this is not a raw photo\n")
w("raw/truncated.dng", b"II*\x00\x08\x00\x00\x00\x20\x00\x00\x01\x03\x00", "wb")

# --- JPEG / PNG (lucent calibrate, undistort)
jpg = open("fixtures/camera/chessboard/left01.jpg", "rb").read()
w("jpeg/truncated.jpg", jpg[:20000], "wb")
w("jpeg/text.jpg", "this is not a JPEG\n")
png = open("fixtures/colour/colorchecker.png", "rb").read()
w("png/truncated.png", png[: len(png) // 2], "wb")

# --- Radiance HDR (lucent env info)
w("hdr/text.hdr", "this is not an HDR map\n")
w("hdr/truncated.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 64 +X 128\n" + bytes(100), "wb")
