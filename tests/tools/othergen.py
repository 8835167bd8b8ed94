#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Synthetic PIV pairs from a generator that is not rpiv's (docs/uncertainty.md, "Session 14"),
to check rpiv's vectors and their sigma on images it did not make, and the coverage of sigma.

Pairs: particles uniform over the frame and 10 px beyond it (0.04 per px), lognormal diameters
(sigma of ln d 0.2) around D, peak intensities uniform in 0.4-1, each a Gaussian of standard
deviation d/4 integrated over the pixels (erf), placed at x_m -+ u(x_m)/2 in frames A and B
(the displacement at the midpoint x_m: the truth at a vector's position), background 0.05,
Gaussian noise of NOISE (a fraction of full scale), scaled by 0.8 and quantised to 8 or 16 bit
(binary PGM).

  othergen.py make FLOW SIZE D NOISE SEED PREFIX [BITS]   -> PREFIX_a.pgm, PREFIX_b.pgm
  othergen.py cover FLOW SIZE FILE...                     coverage of rpiv's text output(s)
  othergen.py where FLOW SIZE FILE...                     the same by ring of grid nodes from
                                                          the grid's edge (0: the edge nodes)

FLOW: uniform (3.27, -1.61) px; rot (solid body, 0.02 rad a frame about the centre); tg
(Taylor-Green cells of 128 px, 2.5 px); oseen (Lamb-Oseen, 5 px at most, core radius 40 px, a
core turning 0.2 rad a frame); jet (u = 1 + 3 sech^2((y - c) / 30) px); cosx, sinx, cosxy
(v = 2.5 cos(k x), u = 2.5 sin(k x), v = 2.5 cos(k x) cos(k y), k = 2 pi / 256). `cover` reads files of
`rpiv piv --uncertainty -o F.txt` and prints, for u and v over their valid vectors: the share
with |error| <= sigma, the RMS error, the median sigma and its ratio to the RMS error.
tests/tools/othergen_sweep.sh runs the 45 cases of docs/uncertainty.md.
"""
import math
import os
import sys

import numpy as np


def flow(name, x, y, n):
    c = n / 2
    if name == "uniform":
        return 3.27 + 0 * x, -1.61 + 0 * y
    if name == "rot":
        return -0.02 * (y - c), 0.02 * (x - c)
    if name == "tg":
        k = 2 * np.pi / 256
        return 2.5 * np.sin(k * x) * np.cos(k * y), -2.5 * np.cos(k * x) * np.sin(k * y)
    if name == "oseen":
        dx, dy = x - c - 0.37, y - c + 0.21
        r = np.sqrt(dx * dx + dy * dy) + 1e-12
        ut = 5.0 * (1 - np.exp(-(r / 40.0) ** 2)) / (r / 40.0) / 0.6381726863
        return -ut * dy / r, ut * dx / r
    if name == "jet":
        return 1.0 + 3.0 / np.cosh((y - c) / 30.0) ** 2, 0 * y
    k = 2 * np.pi / 256  # profiles curved up to the edge (docs/uncertainty.md, "Session 15")
    if name == "cosx":
        return 0 * x, 2.5 * np.cos(k * x)
    if name == "sinx":
        return 2.5 * np.sin(k * x), 0 * y
    if name == "cosxy":
        return 0 * x, 2.5 * np.cos(k * x) * np.cos(k * y)
    raise SystemExit("othergen.py: unknown flow %r (uniform, rot, tg, oseen, jet, cosx, sinx, "
                     "cosxy)" % name)


_erf = np.vectorize(math.erf)


def render(px, py, sig, amp, n):
    img = np.zeros((n, n))
    for x, y, s, a in zip(px, py, sig, amp):
        r = int(math.ceil(4 * s + 1))
        i0, i1 = max(0, int(x) - r), min(n, int(x) + r + 2)
        j0, j1 = max(0, int(y) - r), min(n, int(y) + r + 2)
        if i0 >= i1 or j0 >= j1:
            continue
        gx = np.diff(_erf((np.arange(i0, i1 + 1) - 0.5 - x) / (math.sqrt(2) * s))) * 0.5
        gy = np.diff(_erf((np.arange(j0, j1 + 1) - 0.5 - y) / (math.sqrt(2) * s))) * 0.5
        img[j0:j1, i0:i1] += a * np.outer(gy, gx) * 2 * math.pi * s * s
    return img


def write_pgm(path, q, full):
    with open(path + ".tmp", "wb") as f:
        f.write(b"P5\n%d %d\n%d\n" % (q.shape[1], q.shape[0], full))
        f.write((q.astype(">u2") if full > 255 else q.astype(np.uint8)).tobytes())
    os.replace(path + ".tmp", path)


def make(name, n, dmean, noise, seed, prefix, bits=8):
    rng = np.random.default_rng(seed)
    count = int(0.04 * (n + 20) ** 2)
    xm = rng.uniform(-10, n + 10, count)
    ym = rng.uniform(-10, n + 10, count)
    u, v = flow(name, xm, ym, n)
    sig = dmean * np.exp(rng.normal(0, 0.2, count)) / 4.0
    amp = rng.uniform(0.4, 1.0, count)
    full = 2 ** bits - 1
    for tag, sgn in (("_a.pgm", -0.5), ("_b.pgm", 0.5)):
        im = 0.05 + 0.8 * render(xm + sgn * u, ym + sgn * v, sig, amp, n)
        if noise > 0:
            im = im + rng.normal(0, noise, im.shape)
        write_pgm(prefix + tag, np.clip(np.round(im * full), 0, full), full)


def read_field(path):
    hdr, rows = None, []
    for line in open(path):
        if line.startswith("#"):
            if "sigma_u" in line and " x " in " " + line[1:]:
                hdr = line[1:].split()
            continue
        rows.append([float(t) for t in line.split()])
    if hdr is None:
        raise SystemExit("othergen.py: %s: no column header with sigma_u (run rpiv piv "
                         "--uncertainty -o FILE.txt)" % path)
    return {h: np.array(rows)[:, i] for i, h in enumerate(hdr)}


def cover(name, n, paths):
    err, sig = [[], []], [[], []]
    for p in paths:
        f = read_field(p)
        ok = f["flag"] == 0
        u, v = flow(name, f["x"], f["y"], n)
        for c, (t, q) in enumerate(((u, "u"), (v, "v"))):
            err[c] += list(f[q][ok] - t[ok])
            sig[c] += list(f["sigma_" + q][ok])
    out = []
    for c in range(2):
        e, s = np.array(err[c]), np.array(sig[c])
        rms = math.sqrt(np.mean(e * e))
        out.append("%s cov %.3f rms %.4f medsig %.4f ratio %.2f"
                   % ("uv"[c], np.mean(np.abs(e) <= s), rms, np.median(s), np.median(s) / rms))
    print("n=%d  %s" % (len(err[0]), " | ".join(out)))


def where(name, n, paths):
    """Error and sigma by ring: the nodes' distance in grid steps from the grid's nearest edge."""
    rings = {}
    for p in paths:
        f = read_field(p)
        ok = f["flag"] == 0
        ix = np.searchsorted(np.unique(f["x"]), f["x"])
        iy = np.searchsorted(np.unique(f["y"]), f["y"])
        nx, ny = ix.max() + 1, iy.max() + 1
        ring = np.minimum(np.minimum(ix, nx - 1 - ix), np.minimum(iy, ny - 1 - iy))
        u, v = flow(name, f["x"], f["y"], n)
        for c, (t, q) in enumerate(((u, "u"), (v, "v"))):
            for r in np.unique(ring[ok]):
                m = ok & (ring == r)
                acc = rings.setdefault((c, int(r)), ([], []))
                acc[0].extend(f[q][m] - t[m])
                acc[1].extend(f["sigma_" + q][m])
    for c in range(2):
        total = sum(np.sum(np.array(e) ** 2) for (cc, _), (e, _) in rings.items() if cc == c)
        for (cc, r), (e, s) in sorted(rings.items()):
            if cc != c:
                continue
            e, s = np.array(e), np.array(s)
            print("%s ring %2d n %5d rms %.4f mean %+.4f rms-sigma %.4f cov %.2f share %.2f"
                  % ("uv"[c], r, len(e), math.sqrt(np.mean(e * e)), np.mean(e),
                     math.sqrt(np.mean(s * s)), np.mean(np.abs(e) <= s),
                     np.sum(e * e) / total if total > 0 else 0))


def main(argv):
    if len(argv) >= 7 and argv[0] == "make":
        make(argv[1], int(argv[2]), float(argv[3]), float(argv[4]), int(argv[5]), argv[6],
             int(argv[7]) if len(argv) > 7 else 8)
    elif len(argv) >= 4 and argv[0] == "cover":
        cover(argv[1], int(argv[2]), argv[3:])
    elif len(argv) >= 4 and argv[0] == "where":
        where(argv[1], int(argv[2]), argv[3:])
    else:
        raise SystemExit(__doc__)


if __name__ == "__main__":
    main(sys.argv[1:])
