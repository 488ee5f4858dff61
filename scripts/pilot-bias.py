#!/usr/bin/env python3
"""Where `--quality auto`'s pilots misread a scene's bounces (issue 18): each bounce's bias (relative RMSE) as
the pilots estimate it and as whole-film renders measure it, split into the pilots' three departures from the
truth — which pixels they read (the pilot windows, a sixteenth of the film), how they weigh them (each pixel's
product d_a d_b over the mean of its 3×3 neighbours in its window, not over the converged pixel) and which
4-spp draw they got.

    scripts/pilot-bias.py SCENE [--res 128] [--spp 128] [--pairs 3]

Renders SCENE (flat curves, as auto's choice on the straight-hair scenes) at path lengths 0, 1, 2, 3 and 5 with
two seeds at SPP (the truth: bounce k is path k less path k−1, its bias the mean over the film of the two seeds'
product over (reference² + 0.01), the reference the two path-5 renders' mean), and at path lengths 0, 1, 2 with
2 × PAIRS seeds at the pilots' 4 spp, then prints per bounce: the truth over the film and over the pilot windows
only, and per 4-spp pair the pilots' estimate (neighbours' denominators) and the same products over the
reference's denominators. Needs numpy and oiiotool (Debian `openimageio-tools`); about 15 s for straight-city.
A measurement, not a test: docs/study/auto/README.md quotes its output.
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

C = 0.01  # the relative metric's floor: (x - ref)^2 / (ref^2 + C), as the study and the pilots use
WINDOW = 4


def render(binary, scene, res, spp, path, seed, out):
    subprocess.run(
        [binary, "render", scene, "--res", f"{res}x{res}", "--curves", "flat", "--spp", str(spp),
         "--path-length", str(path), "--seed", str(seed), "--aovs", "none", "--quiet", "-o", out],
        check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    dump = subprocess.run(["oiiotool", "--dumpdata", out], check=True, capture_output=True, text=True).stdout
    img = np.zeros((res, res, 3))
    for line in dump.splitlines():
        line = line.strip()
        if line.startswith("Pixel ("):
            head, values = line.split(":", 1)
            x, y = (int(v) for v in head[len("Pixel ("):-1].split(","))
            img[y, x] = [float(v) for v in values.split()[:3]]
    return img


def windows(res):
    """`quality::pilot::windows` for a square film: WINDOW² squares, centres at (i + ½)/n of the film."""
    count = max(min(max(res * res / 16.0, 576), 9216) / WINDOW**2, 1.0)
    n = min(max(round(np.sqrt(count)), 1), res // WINDOW)
    starts = [min(max((2 * i + 1) * res // (2 * n) - WINDOW // 2, 0), res - WINDOW) for i in range(n)]
    return [(y0, x0) for y0 in starts for x0 in starts]


def neighbour_means(tile):
    """Each pixel's mean over its 3×3 neighbours in the tile, without itself (`neighbour_means`)."""
    h, w, _ = tile.shape
    out = np.zeros_like(tile)
    for y in range(h):
        for x in range(w):
            cells = [tile[yy, xx] for yy in range(max(y - 1, 0), min(y + 2, h))
                     for xx in range(max(x - 1, 0), min(x + 2, w)) if (yy, xx) != (y, x)]
            out[y, x] = np.mean(cells, axis=0) if cells else tile[y, x]
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--seeds", type=int, nargs="*", help="the 4-spp seeds, in pairs (default 11, 12, ...)")
    ap.add_argument("--binary", default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "cuticle"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        def r(spp, path, seed):
            return render(a.binary, a.scene, a.res, spp, path, seed, os.path.join(tmp, f"p{path}-s{seed}-{spp}.exr"))

        truth = {p: [r(a.spp, p, s) for s in (1, 2)] for p in (0, 1, 2, 3, 5)}
        seeds = a.seeds or [11 + k for k in range(2 * a.pairs)]
        a.pairs = len(seeds) // 2
        pilots = {p: {s: r(4, p, s) for s in seeds} for p in (0, 1, 2)}
    ref = (truth[5][0] + truth[5][1]) / 2
    den = ref**2 + C
    mask = np.zeros((a.res, a.res), bool)
    wins = windows(a.res)
    for y0, x0 in wins:
        mask[y0:y0 + WINDOW, x0:x0 + WINDOW] = True
    print(f"{a.scene}, {a.res}², truth from 2 × {a.spp} spp, {len(wins)} pilot windows of {WINDOW}²")
    for k in (1, 2, 3):
        t = (truth[k][0] - truth[k - 1][0]) * (truth[k][1] - truth[k - 1][1]) / den
        print(f"bounce {k}: truth over the film {np.sqrt(max(t.mean(), 0)):.4f}, over the pilot windows "
              f"{np.sqrt(max(t[mask].mean(), 0)):.4f}")
    for k in (1, 2):
        for i in range(a.pairs):
            sa, sb = seeds[2 * i], seeds[2 * i + 1]
            da = pilots[k][sa] - pilots[k - 1][sa]
            db = pilots[k][sb] - pilots[k - 1][sb]
            after = (pilots[k][sa] + pilots[k][sb]) / 2
            est, ref_den = [], []
            for y0, x0 in wins:
                win = (slice(y0, y0 + WINDOW), slice(x0, x0 + WINDOW))
                m = neighbour_means(after[win])
                est.append(da[win] * db[win] / (m**2 + C))
                ref_den.append(da[win] * db[win] / den[win])
            e, t = np.mean(est), np.mean(ref_den)
            print(f"bounce {k}, 4-spp seeds {sa}/{sb}: pilots' estimate {np.sqrt(max(e, 0)):.4f}, the same "
                  f"products over the reference's denominators {np.sqrt(max(t, 0)):.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
