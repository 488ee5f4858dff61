#!/usr/bin/env python3
"""Where `--quality auto`'s pilots misread a scene's bounces: each bounce's bias (relative RMSE) as
the pilots estimate it and as whole-film renders measure it, split into the pilots' three departures from the
truth — which pixels they read (the pilot windows, a sixteenth of the film), how they weigh them (each pixel's
product d_a d_b over the mean of its 3×3 neighbours in its window, not over the converged pixel) and which
4-spp draw they got.

    scripts/pilot-bias.py SCENE [--res 128] [--spp 128] [--pairs 3] [--seeds A B ...] [--denominators]

Renders SCENE (flat curves, as auto's choice on the straight-hair scenes) at path lengths 0, 1, 2, 3 and 5 with
two seeds at SPP (the truth: bounce k is path k less path k−1, its bias the mean over the film of the two seeds'
product over (reference² + 0.01), the reference the two path-5 renders' mean), and at path lengths 0, 1, 2 with
2 × PAIRS seeds at the pilots' 4 spp, then prints per bounce: the truth over the film and over the pilot windows
only, and per 4-spp pair the pilots' estimate (neighbours' denominators) and the same products over the
reference's denominators. `--seeds` gives the 4-spp seeds (the pilots' own are 1592590337 1592590338, i.e.
0x5eed0001/2); `--denominators` also prints, over all pairs, each of five other denominators' estimate ÷ the
reference-denominator products, mean ± its standard error (the pair after the last wraps to the first for the
third seed). Needs numpy and oiiotool (Debian `openimageio-tools`); about 15 s for straight-city.
A measurement, not a test: docs/measured/auto.md quotes its output.
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


def neighbour_means(tile, centre=False):
    """Each pixel's mean over its 3×3 neighbours in the tile, without itself (`neighbour_means`; with it if
    `centre`)."""
    h, w, _ = tile.shape
    out = np.zeros_like(tile)
    for y in range(h):
        for x in range(w):
            cells = [tile[yy, xx] for yy in range(max(y - 1, 0), min(y + 2, h))
                     for xx in range(max(x - 1, 0), min(x + 2, w)) if centre or (yy, xx) != (y, x)]
            out[y, x] = np.mean(cells, axis=0) if cells else tile[y, x]
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--seeds", type=int, nargs="*", help="the 4-spp seeds, in pairs (default 11, 12, ...)")
    ap.add_argument("--denominators", action="store_true", help="also compare five other denominators")
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
    if a.denominators:
        for k in (1, 2):
            ratios = {name: [] for name in DENOMINATORS}
            for i in range(a.pairs):
                sa, sb = seeds[2 * i], seeds[2 * i + 1]
                third = pilots[k][seeds[(2 * i + 2) % len(seeds)]]
                terms = {name: [] for name in DENOMINATORS}
                ref_terms = []
                for y0, x0 in wins:
                    win = (slice(y0, y0 + WINDOW), slice(x0, x0 + WINDOW))
                    xa, xb = pilots[k][sa][win], pilots[k][sb][win]
                    p = (xa - pilots[k - 1][sa][win]) * (xb - pilots[k - 1][sb][win])
                    ref_terms.append(p / den[win])
                    for name, f in DENOMINATORS.items():
                        terms[name].append(p * f(xa, xb, third[win]))
                t = np.sqrt(max(np.mean(ref_terms), 0))
                for name in DENOMINATORS:
                    ratios[name].append(np.sqrt(max(np.mean(terms[name]), 0)) / t)
            for name, r in ratios.items():
                r = np.array(r)
                print(f"bounce {k}, {name}: {r.mean():.3f} ± {r.std() / np.sqrt(len(r)):.3f} of the reference's")
    return 0


def _own(xa, xb, _):
    return 1 / (((xa + xb) / 2) ** 2 + C)


def _neighbours(xa, xb, _):
    return 1 / (((neighbour_means(xa) + neighbour_means(xb)) / 2) ** 2 + C)


def _with_centre(xa, xb, _):
    return 1 / (((neighbour_means(xa, True) + neighbour_means(xb, True)) / 2) ** 2 + C)


def _geometric(xa, xb, third):
    return np.sqrt(_own(xa, xb, third) * _neighbours(xa, xb, third))


def _third_seed(xa, xb, third):
    # The third seed's 3×3 with its pixel, and the pair's neighbours without theirs, sample for sample.
    h, w, _ = xa.shape
    m = np.zeros_like(xa)
    for y in range(h):
        for x in range(w):
            cells = []
            for yy in range(max(y - 1, 0), min(y + 2, h)):
                for xx in range(max(x - 1, 0), min(x + 2, w)):
                    cells.append(third[yy, xx])
                    if (yy, xx) != (y, x):
                        cells += [xa[yy, xx], xb[yy, xx]]
            m[y, x] = np.mean(cells, axis=0)
    return 1 / (m**2 + C)


def _delta(xa, xb, _):
    # The neighbours' mean less the delta-method term for its noise and its mismatch with the pixel.
    ma, mb = neighbour_means(xa), neighbour_means(xb)
    m, own = (ma + mb) / 2, (xa + xb) / 2
    mismatch = (own - m) ** 2 - (xa - xb) ** 2 / 4 - (ma - mb) ** 2 / 4
    second = (6 * m**2 - 2 * C) / (m**2 + C) ** 3
    return 1 / (m**2 + C) - 0.5 * second * mismatch


DENOMINATORS = {
    "neighbours' mean, without the pixel (the pilots')": _neighbours,
    "3x3 mean with the pixel": _with_centre,
    "the pixel's own mean": _own,
    "geometric mean of the first and the third": _geometric,
    "a third seed's 3x3 with its pixel, with the pair's neighbours": _third_seed,
    "the neighbours' mean less the delta-method term": _delta,
}


if __name__ == "__main__":
    sys.exit(main())
