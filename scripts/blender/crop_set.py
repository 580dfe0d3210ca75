#!/usr/bin/env python3
"""Cut a small test set out of a rendered set: some frames, cropped to a window.

    python3 scripts/blender/crop_set.py SET OUT --frames 3,4,5,6 --window X0,Y0,WIDTH,HEIGHT

Crops every image of the chosen frames (and the manifest's plate) to the window and shifts
the principal point by (X0, Y0): the cameras stay exact. Writes OUT/manifest.json.
"""

import argparse
import json
import os

import cv2


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("set")
    ap.add_argument("out")
    ap.add_argument("--frames", required=True)
    ap.add_argument("--window", required=True)
    o = ap.parse_args()
    x0, y0, w, h = map(int, o.window.split(","))
    keep = set(map(int, o.frames.split(",")))
    with open(os.path.join(o.set, "manifest.json")) as f:
        m = json.load(f)

    def crop(rel, gray=False):
        img = cv2.imread(os.path.join(o.set, rel), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise SystemExit(f"{rel}: not readable")
        if img.shape[0] < y0 + h or img.shape[1] < x0 + w:
            raise SystemExit(f"{rel}: window outside the image")
        dst = os.path.join(o.out, rel)
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        cv2.imwrite(dst, img[y0:y0 + h, x0:x0 + w], [cv2.IMWRITE_PNG_COMPRESSION, 9])

    frames = [f for f in m["frames"] if f["index"] in keep]
    for f in frames:
        for k in ["input", "truth", "key_mask", "truth_mask"]:
            crop(f[k])
        f["plate"] = None
    if m.get("plate"):
        crop(m["plate"]["image"])
    m["frames"] = frames
    m["width"], m["height"] = w, h
    m["intrinsics"]["cx"] -= x0
    m["intrinsics"]["cy"] -= y0
    m["renderer"] += f"; frames {sorted(keep)} cropped to {w}x{h} at ({x0}, {y0})"
    with open(os.path.join(o.out, "manifest.json"), "w") as f:
        json.dump(m, f, indent=1)


main()
