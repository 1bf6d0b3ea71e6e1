#!/usr/bin/env python3
"""Time Mitsuba 3 on the reference scene of ``mitsuba_render.py`` and measure its error.

Renders a reference scene (``--scene plaque_dense`` or ``plaque_envmap``, same camera, integrator
and parameters as the committed reference: no Russian roulette, which on
this scene is Mitsuba's better setting; ``--rr-depth 5``, Mitsuba's default,
measured 4 Dec 2026: 3.4x less time and 3.3x the RMSE at 256 spp, i.e. 3.2x
less efficient) at each ``--spp`` with
``--threads`` Dr.Jit threads and prints one JSON object: wall and CPU seconds
(``time.process_time()`` of the process, i.e. all worker threads),
samples per CPU-second (= pixels x spp / CPU seconds), and the RMSE against
the committed mean EXR over all pixels and channels, and over the plaque's
pixels alone (``rmse_object``; ``object_pixels`` lists them).  ``rmse_expected`` is
what an unbiased renderer with this many samples should get:
``sqrt(mean(var_of_mean * K * S) / spp + mean(var_of_mean))`` from the
committed variance EXR (K passes of S spp; the second term is the
reference's own noise).

Each timed render is preceded by an untimed one at the same spp with another
seed, so the Dr.Jit kernel is compiled (or loaded from its cache) before the
clock starts; ``warmup_wall_seconds`` shows what that cost.

    pip install mitsuba==3.9.1 drjit==1.5.0 numpy==2.4.6     # + apt-get install libllvm19
    nice python3 tools/reference/bench_render_mitsuba.py --spp 16 64 256 1024 --threads 2 \\
        --out fixtures/reference/render/mitsuba_bench_plaque_dense.json
    nice python3 tools/reference/bench_render_mitsuba.py --scene plaque_envmap --spp 16 64 256 1024 \\
        --threads 2 --out fixtures/reference/render/mitsuba_bench_plaque_envmap.json
"""

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_render as ref  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spp", type=int, nargs="+", default=[64])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1_000_000, help="seed of the timed render (the reference used 0..)")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--integrator", choices=["volpathmis", "volpath"], default=None,
                    help="default: the one recorded in the reference JSON")
    ap.add_argument("--rr-depth", type=int, default=100000,
                    help="path depth where Mitsuba's Russian roulette starts (default 100000, i.e. none, "
                         "as in the reference renders; Mitsuba's own default is 5)")
    ap.add_argument("--scene", choices=["plaque_dense", "plaque_envmap"], default="plaque_dense",
                    help="the reference scene: plaque_dense (constant sky) or plaque_envmap (a sky map with a "
                         "small sun, env_32x16.exr)")
    ap.add_argument("--reference", default=None,
                    help="path prefix of the reference _mean.exr, _var.exr and .json "
                         "(default: fixtures/reference/render/<scene>)")
    ap.add_argument("--chunk-spp", type=int, default=None,
                    help="samples per mi.render call (default: all in one for plaque_dense, 64 for plaque_envmap, "
                         "as in its reference, whose sphere emitter can return NaN)")
    ap.add_argument("--no-warmup", action="store_true")
    ap.add_argument("--out", help="also write the JSON here")
    ap.add_argument("--allow-other-version", action="store_true")
    args = ap.parse_args()

    mi, dr = ref.setup(args.variant, args.threads, args.allow_other_version)
    import numpy as np

    if args.reference is None:
        args.reference = os.path.join(ref.OUT_DIR, args.scene)
    with open(args.reference + ".json") as f:
        info = json.load(f)
    mean = np.array(mi.Bitmap(args.reference + "_mean.exr"), dtype=np.float64)
    var_of_mean = np.array(mi.Bitmap(args.reference + "_var.exr"), dtype=np.float64)
    per_sample_var = var_of_mean * info["total_spp"]  # K * S * var_of_mean
    integrator = args.integrator or info["integrator"]["type"]

    if args.scene == "plaque_envmap":
        env, env_path = "envmap", os.path.join(ref.OUT_DIR, f"env_{ref.ENV_W}x{ref.ENV_H}.exr")
    else:
        env, env_path = "constant", None
    scene = mi.load_dict(ref.scene_dict(mi, args.spp[0], integrator, env, env_path, rr_depth=args.rr_depth))
    H, W = ref.SCENE["camera"]["height"], ref.SCENE["camera"]["width"]
    chunk = args.chunk_spp or (64 if args.scene == "plaque_envmap" else max(args.spp))
    obj = ref.object_mask()
    runs = []
    for spp in args.spp:
        warm = None
        if not args.no_warmup:
            w = time.perf_counter()
            dr.eval(mi.render(scene, seed=args.seed + 500_000, spp=min(spp, chunk)))
            dr.sync_thread()
            warm = time.perf_counter() - w
        w, c = time.perf_counter(), time.process_time()
        # In calls of at most --chunk-spp samples, as in the reference.
        sizes = ref.call_sizes(spp, chunk)
        img, dropped, _ = ref.render_in_calls(mi, scene, sizes, args.seed, f"{spp} spp")
        wall, cpu = time.perf_counter() - w, time.process_time() - c
        rmse = float(np.sqrt(np.mean((img - mean) ** 2)))
        expected = float(np.sqrt(np.mean(per_sample_var) / spp + np.mean(var_of_mean)))
        runs.append({
            "spp": spp,
            "wall_seconds": round(wall, 3),
            "cpu_seconds": round(cpu, 3),
            "samples_per_cpu_second": round(W * H * spp / cpu, 1),
            "samples_per_wall_second": round(W * H * spp / wall, 1),
            "rmse_vs_reference": rmse,
            "rmse_expected": expected,
            "rmse_per_channel": [float(v) for v in np.sqrt(np.mean((img - mean) ** 2, axis=(0, 1)))],
            "rmse_object": float(np.sqrt(np.mean((img[obj] - mean[obj]) ** 2))),
            "rmse_object_expected": float(np.sqrt(np.mean(per_sample_var[obj]) / spp + np.mean(var_of_mean[obj]))),
            "calls": len(sizes),
            "non_finite_pixel_calls": sum(dropped),
            "warmup_wall_seconds": None if warm is None else round(warm, 3),
            "load_average_1min": round(os.getloadavg()[0], 2),
        })
        print(json.dumps(runs[-1]), file=sys.stderr, flush=True)
    out = {
        "scene": info["scene"],
        "reference": os.path.relpath(args.reference, ref.REPO) if args.reference.startswith(ref.REPO) else args.reference,
        "reference_total_spp": info["total_spp"],
        "mitsuba": mi.__version__,
        "drjit": dr.__version__,
        "variant": args.variant,
        "integrator": integrator,
        "rr_depth": args.rr_depth,
        "threads": int(dr.thread_count()),
        "pixels": W * H,
        "object_pixels": [int(i) for i in np.flatnonzero(obj)],
        "object_pixels_rule": "row-major indices (row 0 at the top) of the pixels where at least half of 4 x 4 "
                              "pinhole rays meet the plaque's box (mitsuba_render.object_mask)",
        "cpu": _cpu_name(),
        "note": f"wall/cpu seconds of the mi.render calls of at most {chunk} spp after an untimed warm-up at the first call's spp; shared 2-core machine, run under nice",
        "runs": runs,
    }
    text = json.dumps(out, indent=1, allow_nan=False)  # a NaN would make the file unreadable JSON
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


def _cpu_name():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


if __name__ == "__main__":
    main()
