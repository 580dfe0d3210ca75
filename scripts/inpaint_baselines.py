#!/usr/bin/env python3
"""OpenCV's inpainting (Telea, Navier-Stokes) next to our fills on the same masks.

Reads what `propsalive eval --dump-fills DIR` writes (one folder per background and seed,
per frame `fNNN_input.png`, `fNNN_truth.png`, `fNNN_revealed.png`, `fNNN_fillmask.png` and
each fill's diminished plate `fNNN_fill_<name>.png`), inpaints every input with
cv2.INPAINT_TELEA and cv2.INPAINT_NS on its fill mask, and prints the revealed-background
PSNR (dB, peak 255, over R, G, B of the revealed pixels, each frame's MSE averaged over the
frames of a folder the way `eval` averages its PSNR: the mean of the per-frame PSNRs) of every
method, per folder and per background, twice:

With `--off-edge`, the region is `fNNN_offedge.png` instead: the revealed pixels 3 px or more
(Chebyshev) from the in-between's silhouette, eval's "revealed off edge" column, where the
truth is background alone and the fills differ.

- "plate": the diminished plates themselves (no twin). At the in-between's silhouette the
  2x2-supersampled truth mixes prop and background, which no fill can know, so this measure
  compresses the differences between fills (`--erode N` leaves that rim out);
- "output": OpenCV's plates under the same twin as the pipeline composites it (anti-aliased
  edge, linear light, from `fNNN_twin_over_black/white.png`), and our fills' own outputs
  (`fNNN_out_<name>.png`; `_shadows` fills have the key prop's shadow lifted and the twin's
  cast, which OpenCV's do not): the region and the measure `eval` reports, on the frames the
  dump holds (from the tracker's first pose on; `eval`'s rows also count the frames before).
  The script checks the recomposition against our outputs without shadows and prints the
  largest difference.

    pip install numpy opencv-python-headless
    python3 scripts/inpaint_baselines.py DIR [--radius 3] [--erode 2 | --off-edge] [--markdown]

Not part of the build or CI. The fill times of OpenCV are printed too (median per frame,
single call, this machine).
"""

import argparse
import glob
import os
import re
import statistics
import sys
import time

try:
    import cv2
    import numpy as np
except ImportError as e:  # pragma: no cover
    sys.exit(f"{e}: pip install numpy opencv-python-headless")


def read_rgb(path):
    img = cv2.imread(path, cv2.IMREAD_COLOR)
    if img is None:
        sys.exit(f"cannot read {path}")
    return img


def read_mask(path):
    m = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if m is None:
        sys.exit(f"cannot read {path}")
    return m > 127


def psnr(a, b, region):
    if not region.any():
        return None
    d = a[region].astype(np.float64) - b[region].astype(np.float64)
    mse = float(np.mean(d * d))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 * 255.0 / mse)


_DEC = np.array(
    [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in np.arange(256) / 255.0]
)


def encode(lin):
    lin = np.clip(lin, 0.0, 1.0)
    c = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    return np.clip(np.round(c * 255.0), 0, 255).astype(np.uint8)


def under_twin(plate, black, white):
    """`plate` under the twin: black + (white - black) * plate, in linear light."""
    b, w, p = _DEC[black], _DEC[white], _DEC[plate]
    return encode(b + (w - b) * p)


CHECK = {"max": 0}


def folder_scores(folder, radius, erode, off_edge=False):
    """{method: [psnr per frame]} of the plates and of the outputs, and {method: [seconds per
    frame]}, of one dump folder."""
    frames = sorted(
        {m.group(1) for f in os.listdir(folder) if (m := re.match(r"(f\d+)_input\.png$", f))}
    )
    scores, outputs, times = {}, {}, {}
    for fr in frames:
        p = lambda what: os.path.join(folder, f"{fr}_{what}.png")
        fills = sorted(glob.glob(p("fill_*")))
        if not fills:
            continue  # no pose yet (tracker locking on): nothing was filled
        inp, truth = read_rgb(p("input")), read_rgb(p("truth"))
        revealed, fill = read_mask(p("revealed")), read_mask(p("fillmask"))
        if erode > 0:
            # Drop the revealed pixels within `erode` px of its border: the ground truth's
            # pixels at the in-between's silhouette mix prop and background (2x2 supersampled),
            # which no fill can know.
            k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * erode + 1, 2 * erode + 1))
            revealed = cv2.erode(revealed.astype(np.uint8), k) > 0
        region = revealed & fill
        if off_edge:
            path = p("offedge")
            if not os.path.exists(path):
                sys.exit(f"{path} missing: dump again with this release's `eval --dump-fills`")
            region = read_mask(path) & fill
        if not region.any():
            continue
        twin = None
        if os.path.exists(p("twin_over_black")):
            twin = (read_rgb(p("twin_over_black")), read_rgb(p("twin_over_white")))

        def score(name, plate):
            scores.setdefault(name, []).append(psnr(plate, truth, region))
            if twin is not None:
                out = under_twin(plate, *twin)
                own = p(f"out_{name}")
                if os.path.exists(own):
                    # Our fills: the pipeline's own output is scored. Without shadows it is
                    # the plate under the twin, which checks the recomposition that OpenCV's
                    # fills go through; with them it also holds the twin's cast shadow.
                    real = read_rgb(own)
                    if not name.endswith("_shadows"):
                        d = np.abs(out.astype(int) - real.astype(int)).max()
                        CHECK["max"] = max(CHECK["max"], int(d))
                    out = real
                outputs.setdefault(name, []).append(psnr(out, truth, region))

        for path in fills:
            score(re.search(r"_fill_(.+)\.png$", path).group(1), read_rgb(path))
        mask8 = fill.astype(np.uint8) * 255
        for name, flag in (("opencv_telea", cv2.INPAINT_TELEA), ("opencv_ns", cv2.INPAINT_NS)):
            t = time.perf_counter()
            out = cv2.inpaint(inp, mask8, radius, flag)
            times.setdefault(name, []).append(time.perf_counter() - t)
            score(name, out)
    return scores, outputs, times


def mean(v):
    v = [x for x in v if x is not None and np.isfinite(x)]
    return sum(v) / len(v) if v else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", help="the folder given to `propsalive eval --dump-fills`")
    ap.add_argument("--radius", type=int, default=3, help="cv2.inpaint radius (px)")
    ap.add_argument("--markdown", action="store_true", help="print Markdown tables")
    ap.add_argument(
        "--erode",
        type=int,
        default=0,
        help="leave out revealed pixels within this many px of the region's border (0: the "
        "region eval measures)",
    )
    ap.add_argument(
        "--off-edge",
        action="store_true",
        help="measure on fNNN_offedge.png (eval's 'revealed off edge' region) instead",
    )
    args = ap.parse_args()
    if args.off_edge and args.erode:
        sys.exit("--off-edge and --erode are two different regions: give one")
    folders = sorted(d for d in glob.glob(os.path.join(args.dir, "*")) if os.path.isdir(d))
    if not folders:
        sys.exit(f"no dump folders in {args.dir}")
    tables = {"plate": {}, "output": {}}
    all_times = {}
    for folder in folders:
        scores, outputs, times = folder_scores(folder, args.radius, args.erode, args.off_edge)
        bg = os.path.basename(folder).rsplit("_s", 1)[0]
        for what, got in (("plate", scores), ("output", outputs)):
            for k, v in got.items():
                tables[what].setdefault(bg, {}).setdefault(k, []).extend(v)
        for k, v in times.items():
            all_times.setdefault(k, []).extend(v)
        row = "  ".join(f"{k} {mean(v):.2f}" for k, v in sorted(scores.items()))
        print(f"{os.path.basename(folder)}: {row}")
    for what, by_bg in tables.items():
        if not by_bg:
            continue
        methods = sorted({m for s in by_bg.values() for m in s})
        print()
        print(f"revealed-background PSNR, dB (mean over frames), measured on the {what}")
        if args.markdown:
            print("| background | " + " | ".join(methods) + " | frames |")
            print("|---" * (len(methods) + 2) + "|")
            for bg, s in sorted(by_bg.items()):
                n = max(len(v) for v in s.values())
                cells = " | ".join(f"{mean(s.get(m, [])):.2f}" for m in methods)
                print(f"| {bg} | {cells} | {n} |")
        else:
            for bg, s in sorted(by_bg.items()):
                print(f"  {bg}: " + "  ".join(f"{m} {mean(s.get(m, [])):.2f}" for m in methods))
    if tables["output"]:
        print(f"recomposition against the pipeline's own outputs: largest difference "
              f"{CHECK['max']} levels")
    for k, v in sorted(all_times.items()):
        print(f"{k}: median {1e3 * statistics.median(v):.2f} ms a frame")


if __name__ == "__main__":
    main()
