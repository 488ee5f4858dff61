"""Independent NumPy transcription of cuticle's SSIM (src/measure/pixels.rs) on the test's maps.

Wang et al. 2004 eq. 13, 11x11 Gaussian window (sigma 1.5) clipped at the border and renormalised, C1 = 1e-4,
C2 = 9e-4, mean over every pixel. Run: python3 docs/study/ssim_check.py
"""
import numpy as np

h, w = 12, 16
i, j = np.mgrid[0:h, 0:w]
x = ((3 * i + 5 * j) % 7) / 7.0
y = 0.8 * x + 0.1 + 0.05 * ((i * j) % 3)
g = np.exp(-np.arange(-5, 6) ** 2 / (2 * 1.5 ** 2))
win = np.outer(g, g)
c1, c2 = 1e-4, 9e-4
s = []
for py in range(h):
    for px in range(w):
        y0, y1, x0, x1 = max(py - 5, 0), min(py + 6, h), max(px - 5, 0), min(px + 6, w)
        wt = win[y0 - py + 5:y1 - py + 5, x0 - px + 5:x1 - px + 5]
        wt = wt / wt.sum()
        a, b = x[y0:y1, x0:x1], y[y0:y1, x0:x1]
        mx, my = (wt * a).sum(), (wt * b).sum()
        vx, vy = (wt * a * a).sum() - mx * mx, (wt * b * b).sum() - my * my
        cxy = (wt * a * b).sum() - mx * my
        s.append((2 * mx * my + c1) * (2 * cxy + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2)))
print(f"{np.mean(s):.12f}")
