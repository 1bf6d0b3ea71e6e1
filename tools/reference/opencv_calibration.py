#!/usr/bin/env python3
"""Generate ``fixtures/reference/opencv_left_calibration.json``: an independent
calibration of OpenCV's sample chessboard photos (``fixtures/camera/chessboard/
left01.jpg`` ... ``left14.jpg``, 9 x 6 inner corners) by OpenCV's Python
bindings, for ``lucent calibrate`` (``calib/src/cv.rs``) to be checked against.

Procedure (the same policy as the Rust side, written independently here)
-----------------------------------------------------------------------
* Per image, grey scale: ``findChessboardCornersSB(img, (9, 6),
  flags=CALIB_CB_ACCURACY)``; where that finds nothing, the classic
  ``findChessboardCorners(img, (9, 6), CALIB_CB_ADAPTIVE_THRESH |
  CALIB_CB_NORMALIZE_IMAGE)`` refined by ``cornerSubPix(11 x 11, zero zone
  (-1, -1), 30 iterations or eps 0.001)``.
* Object points (i * s, j * s, 0) for i = 0..8 fastest, j = 0..5, square s = 1
  (intrinsics and distortion do not depend on s).
* ``calibrateCamera`` with flags 0: fx, fy, cx, cy and k1, k2, p1, p2, k3.
* Per-view RMS reprojection error from ``projectPoints`` with the returned
  poses; the overall RMS is calibrateCamera's return value,
  sqrt(sum of squared residuals / number of points).

For information the file also holds the classic detector alone (every view
through findChessboardCorners + cornerSubPix): on these photos it gives an
RMS of about 0.41 px and fx about 0.7 % larger than the sector-based detector,
which is the detector's own systematic error, not noise.

How to run (from the repository root)::

    pip install opencv-python-headless     # 5.0.0 made the committed file
    python3 tools/reference/opencv_calibration.py [--out FILE]

Versions that produced the committed file: Python 3.11.7, numpy 2.4.6,
opencv-python-headless with OpenCV 5.0.0.
"""

import argparse
import glob
import json
import os
import sys

import cv2
import numpy as np

PATTERN = (9, 6)
SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)


def detect(gray, policy):
    if policy == "auto":
        ok, c = cv2.findChessboardCornersSB(gray, PATTERN, flags=cv2.CALIB_CB_ACCURACY)
        if ok:
            return c.reshape(-1, 2), "sector-based"
    ok, c = cv2.findChessboardCorners(gray, PATTERN, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        return None, None
    c = cv2.cornerSubPix(gray, c, (11, 11), (-1, -1), SUBPIX)
    return c.reshape(-1, 2), "classic"


def calibrate(files, policy):
    objp = np.zeros((PATTERN[0] * PATTERN[1], 3), np.float32)
    objp[:, :2] = np.mgrid[0 : PATTERN[0], 0 : PATTERN[1]].T.reshape(-1, 2)
    obj, img, names, detectors, missing = [], [], [], [], []
    size = None
    for f in files:
        gray = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
        size = gray.shape[::-1]
        corners, det = detect(gray, policy)
        if corners is None:
            missing.append(os.path.basename(f))
            continue
        obj.append(objp)
        img.append(corners.astype(np.float32).reshape(-1, 1, 2))
        names.append(os.path.basename(f))
        detectors.append(det)
    rms, k, d, rvecs, tvecs = cv2.calibrateCamera(obj, img, size, None, None, flags=0)
    views = []
    for name, det, o, i, rv, tv in zip(names, detectors, obj, img, rvecs, tvecs):
        proj, _ = cv2.projectPoints(o, rv, tv, k, d)
        err = np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - i.reshape(-1, 2)) ** 2, axis=1)))
        views.append({"image": name, "detector": det, "rms_px": float(err), "rvec": rv.ravel().tolist(), "tvec_squares": tv.ravel().tolist()})
    return {
        "image_size": list(size),
        "rms_px": float(rms),
        "fx": float(k[0, 0]),
        "fy": float(k[1, 1]),
        "cx": float(k[0, 2]),
        "cy": float(k[1, 2]),
        "distortion_k1_k2_p1_p2_k3": d.ravel().tolist(),
        "views": views,
        "not_found": missing,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--images", default="fixtures/camera/chessboard")
    ap.add_argument("--out", default="fixtures/reference/opencv_left_calibration.json")
    a = ap.parse_args()
    files = sorted(glob.glob(os.path.join(a.images, "left[0-9][0-9].jpg")))
    if not files:
        sys.exit(f"no left??.jpg in {a.images}")
    out = {
        "generator": "tools/reference/opencv_calibration.py",
        "versions": {"opencv": cv2.__version__, "numpy": np.__version__, "python": sys.version.split()[0]},
        "board_inner_corners": list(PATTERN),
        "square": 1.0,
        "images": [os.path.basename(f) for f in files],
        "auto": calibrate(files, "auto"),
        "classic_only": calibrate(files, "classic"),
    }
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    r = out["auto"]
    print(f"wrote {a.out}: rms {r['rms_px']:.4f} px, fx {r['fx']:.3f}, fy {r['fy']:.3f}, cx {r['cx']:.3f}, cy {r['cy']:.3f}")


if __name__ == "__main__":
    main()
