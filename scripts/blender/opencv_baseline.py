#!/usr/bin/env python3
"""OpenCV inpainting baselines on a set folder (the format `propsalive eval --set` reads).

    python3 scripts/blender/opencv_baseline.py SET [SET ...] [--dilate 4] [--radius 5]

For every frame: the fill mask is the set's key-prop mask dilated by a disc of `--dilate`
pixels (our pipeline's default dilation; note: the baseline gets the *true* key mask, ours
the tracked twin's), filled with cv2.inpaint (Telea, Navier-Stokes). Measured as `eval
--set` measures: PSNR over the revealed region (key mask and not in-between mask) against
the in-between render, and flicker as `pa_scene::flicker` measures it: the mean absolute
frame-to-frame change (8-bit levels, mean of R, G, B) after the table-plane homography of the
true cameras, over pixels revealed in both frames, at least 2 pixels from the in-between's
silhouette and seeing the table (`table_m`), for the fill and for the ground truth.
Needs numpy and opencv-python-headless (not part of the product's build).
"""

import argparse
import json
import math
import os
import time

import cv2
import numpy as np


def load(set_dir, rel, mask=False):
    img = cv2.imread(os.path.join(set_dir, rel), cv2.IMREAD_COLOR)
    if img is None:
        raise SystemExit(f"{os.path.join(set_dir, rel)}: not a readable image")
    img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return img[:, :, 0] >= 128 if mask else img


def psnr(a, b, region):
    if not region.any():
        return None
    d = a[region].astype(np.float64) - b[region].astype(np.float64)
    mse = np.mean(d * d)
    return float("inf") if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def plane(m):
    m = np.asarray(m, dtype=np.float64)
    return np.stack([m[:3, 0], m[:3, 1], m[:3, 3]], axis=1)


def change(prev, cur, k, cam_prev, cam_cur, r_prev, r_cur):
    """Mean |cur - prev warped| over pixels of r_cur whose warp lands in r_prev (bilinear)."""
    h, w = r_cur.shape
    prev_from_cur = k @ plane(cam_prev) @ np.linalg.inv(plane(cam_cur)) @ np.linalg.inv(k)
    ys, xs = np.nonzero(r_cur)
    p = prev_from_cur @ np.stack([xs, ys, np.ones_like(xs)]).astype(np.float64)
    qx, qy = p[0] / p[2], p[1] / p[2]
    rx, ry = np.round(qx).astype(int), np.round(qy).astype(int)
    ok = (p[2] > 0) & (qx >= 0) & (qy >= 0) & (qx <= w - 1) & (qy <= h - 1)
    ok &= r_prev[np.clip(ry, 0, h - 1), np.clip(rx, 0, w - 1)]
    if not ok.any():
        return None
    xs, ys, qx, qy = xs[ok], ys[ok], qx[ok], qy[ok]
    x0, y0 = np.floor(qx).astype(int), np.floor(qy).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (qx - x0)[:, None], (qy - y0)[:, None]
    P = prev.astype(np.float64)
    s = (1 - fy) * ((1 - fx) * P[y0, x0] + fx * P[y0, x1]) + fy * ((1 - fx) * P[y1, x0] + fx * P[y1, x1])
    return float(np.mean(np.abs(cur[ys, xs].astype(np.float64) - s)))


def on_table(region, k, cam, half):
    """`region` less the pixels whose ray misses the table square of half-side `half`."""
    h, w = region.shape
    ys, xs = np.mgrid[0:h, 0:w]
    q = np.linalg.inv(plane(cam)) @ np.linalg.inv(k) @ np.stack([xs.ravel(), ys.ravel(), np.ones(h * w)])
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = (q[2] > 1e-12) & (np.abs(q[0] / q[2]) <= half) & (np.abs(q[1] / q[2]) <= half)
    return region & ok.reshape(h, w)


def run(set_dir, dilate, radius):
    with open(os.path.join(set_dir, "manifest.json")) as f:
        m = json.load(f)
    k = m["intrinsics"]
    K = np.array([[k["fx"], 0, k["cx"]], [0, k["fy"], k["cy"]], [0, 0, 1.0]])
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * dilate + 1, 2 * dilate + 1))
    res = {}
    for name, flag in [("Telea", cv2.INPAINT_TELEA), ("Navier-Stokes", cv2.INPAINT_NS)]:
        ps, fl, ft, ms = [], [], [], []
        prev = None
        for fr in m["frames"]:
            inp, truth = load(set_dir, fr["input"]), load(set_dir, fr["truth"])
            key, tm = load(set_dir, fr["key_mask"], True), load(set_dir, fr["truth_mask"], True)
            fill = cv2.dilate(key.astype(np.uint8) * 255, disc)
            t0 = time.perf_counter()
            out = cv2.inpaint(inp, fill, radius, flag)
            ms.append(1000 * (time.perf_counter() - t0))
            revealed = key & ~tm
            near = cv2.dilate(tm.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
            region = key & ~near
            if m.get("table_m"):
                region = on_table(region, K, fr["camera_from_marker"], 0.5 * m["table_m"])
            p = psnr(out, truth, revealed)
            if p is not None:
                ps.append(p)
            cam = fr["camera_from_marker"]
            if prev is not None:
                a = change(prev[0], out, K, prev[2], cam, prev[3], region)
                b = change(prev[1], truth, K, prev[2], cam, prev[3], region)
                if a is not None and b is not None:
                    fl.append(a)
                    ft.append(b)
            prev = (out, truth, cam, region)
        res[name] = {
            "revealed_psnr_db": float(np.mean(ps)) if ps else None,
            "flicker_ours": float(np.mean(fl)) if fl else None,
            "flicker_truth": float(np.mean(ft)) if ft else None,
            "fill_ms_median": float(np.median(ms)),
            "frames": len(m["frames"]),
        }
    return res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("sets", nargs="+")
    ap.add_argument("--dilate", type=int, default=4)
    ap.add_argument("--radius", type=float, default=5.0)
    o = ap.parse_args()
    print("| set | method | revealed PSNR dB | flicker ours / truth | fill ms (median) | frames |")
    print("|---|---|---|---|---|---|")
    f = lambda v, d=2: "-" if v is None else f"{v:.{d}f}"
    for s in o.sets:
        for name, r in run(s, o.dilate, o.radius).items():
            print(f"| {os.path.basename(os.path.normpath(s))} | cv2.inpaint {name} | {f(r['revealed_psnr_db'])} | "
                  f"{f(r['flicker_ours'])} / {f(r['flicker_truth'])} | {f(r['fill_ms_median'], 1)} | {r['frames']} |")


main()
