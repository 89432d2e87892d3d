#!/usr/bin/env python3
"""Cross-check of vmsim run's normal deviation on walls: for the nodes whose vertical deviation exceeds a threshold,
the exact distance of the predicted node to the reference grid's piecewise-linear surface (two triangles a cell,
brute force over 12 cells around). Usage: wall_distance.py RUN_DIR THRESHOLD_MM (numpy)."""
import numpy as np, json, sys
d = sys.argv[1]
s = np.loadtxt(d + '/surface.csv', delimiter=',', comments='#'); r = np.loadtxt(d + '/reference.csv', delimiter=',', comments='#')
n = np.load(d + '/deviation.npy'); v = np.load(d + '/deviation_vertical.npy')
g = json.load(open(d + '/report.json'))['surface']['grid']; h = g['dx_mm']
def tri_dist(p, a, b, c):
    # closest point on triangle (Ericson)
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = ab @ ap, ac @ ap
    if d1 <= 0 and d2 <= 0: return np.linalg.norm(p - a)
    bp = p - b; d3, d4 = ab @ bp, ac @ bp
    if d3 >= 0 and d4 <= d3: return np.linalg.norm(p - b)
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0: return np.linalg.norm(p - (a + d1 / (d1 - d3) * ab))
    cp = p - c; d5, d6 = ab @ cp, ac @ cp
    if d6 >= 0 and d5 <= d6: return np.linalg.norm(p - c)
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0: return np.linalg.norm(p - (a + d2 / (d2 - d6) * ac))
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6)); return np.linalg.norm(p - (b + w * (c - b)))
    den = 1 / (va + vb + vc); vv, ww = vb * den, vc * den
    return np.linalg.norm(p - (a + ab * vv + ac * ww))
idx = np.argwhere(np.abs(v) > float(sys.argv[2]))
K = 12
out = []
for j, i in idx:
    p = np.array([i * h, j * h, s[j, i]])
    best = 1e9
    for jj in range(max(0, j - K), min(r.shape[0] - 1, j + K)):
        for ii in range(max(0, i - K), min(r.shape[1] - 1, i + K)):
            P = lambda a, b: np.array([b * h, a * h, r[a, b]])
            for t in ((P(jj, ii), P(jj, ii + 1), P(jj + 1, ii + 1)), (P(jj, ii), P(jj + 1, ii + 1), P(jj + 1, ii))):
                best = min(best, tri_dist(p, *t))
    out.append((i * h, j * h, v[j, i] * 1e3, n[j, i] * 1e3, best * 1e3))
out = np.array(out)
print('min exact %.1f, min |normal| %.1f' % (out[:,4].min(), np.abs(out[:,3]).min()))
print('nodes', len(out), 'vertical |max| %.1f um, first-order normal |max| %.1f um, exact to the reference mesh max %.1f um (median %.1f)' % (
    np.abs(out[:, 2]).max(), np.abs(out[:, 3]).max(), out[:, 4].max(), np.median(out[:, 4])))
for row in out[np.argsort(-np.abs(out[:, 2]))][:8]: print('x %.1f y %.1f vertical %.1f normal %.2f exact %.2f' % tuple(row))
