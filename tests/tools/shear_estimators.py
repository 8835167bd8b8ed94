#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Sub-pixel estimators on the depth-sheared ensembles' planes (docs/ccm.md, "Session 9: the
estimator on the engine's planes and on the CCM's").

Reads the dump of tests/test_peak_shear (SHEAR_PLANE=1 SHEAR_DUMP=file: one line a window,
"k up vp u_engine ideal_dx ideal_dy" then the engine's 7 x 7 summed samples about its
last predictor and the CCM's expected plane there (pair loss and mean-removal baseline),
rows y = -3..3, columns x = -3..3) and prints, per estimator, the mean over the windows of
what it finds on the engine's plane less what it finds on the CCM's (the gap the issue's second
target bounds, without the passes' fixed point), the engine's estimate less the continuous
ideal, and the CCM's less the ideal; for the spline, the gap split by the block the engine's
plane gives it (7 x 7, 5 x 5, 3-point fallback).

Estimators: the engine's (rpiv_peak_find through build/librpiv.so: spline, 3-point Gaussian);
"pedestal": the 5 x 5 spline where the engine falls back, its samples raised by a constant so
that the lowest is 1e-3 of the centre (continuous in the samples); "wls cubic": the weighted
least-squares cubic in x, y through ln C over 7 x 7 with weights C^2 (the inverse variance of
ln C), cubic terms damped by 1e-2 of the weights' sum.

Usage: cd build && SHEAR_PAIRS=300 SHEAR_CASE=small SHEAR_PLANE=1 SHEAR_DUMP=/tmp/d.txt \
       tests/test_peak_shear; /usr/bin/python3 ../tests/tools/shear_estimators.py /tmp/d.txt
"""
import ctypes
import os
import sys

import numpy as np

LIB = os.environ.get("RPIV_LIB", os.path.join(os.path.dirname(__file__), "../../build/librpiv.so"))


class Peak(ctypes.Structure):
    _fields_ = [("dx", ctypes.c_double), ("dy", ctypes.c_double), ("ix", ctypes.c_int),
                ("iy", ctypes.c_int), ("value", ctypes.c_float), ("second", ctypes.c_float),
                ("ratio", ctypes.c_float), ("fit_ok", ctypes.c_int)]


_lib = ctypes.CDLL(LIB)
GAUSS, SPLINE = 0, 3


def engine(b7, method):
    """The engine's estimator on the 7 x 7 block, placed as an 8 x 8 circular plane."""
    pl = np.zeros((8, 8), np.float32)
    for j in range(-3, 4):
        for i in range(-3, 4):
            pl[j % 8, i % 8] = b7[j + 3, i + 3]
    pk = Peak()
    _lib.rpiv_peak_find(pl.ctypes.data_as(ctypes.c_void_p), 8, 8, 1, method, ctypes.byref(pk))
    return pk.ix + pk.dx


def _nak(n):
    """M = A y: the not-a-knot spline's second derivatives through n nodes, unit spacing."""
    k, r = np.zeros((n, n)), np.zeros((n, n))
    k[0, :3] = k[-1, -3:] = (1, -2, 1)
    for i in range(1, n - 1):
        k[i, i - 1:i + 2] = (1, 4, 1)
        r[i, i - 1:i + 2] = (6, -12, 6)
    return np.linalg.solve(k, r)


_A5 = _nak(5)


def _w5(x):
    i = int(np.clip(np.floor(x), 0, 3))
    t = x - i
    w = np.zeros(5)
    w[i] += 1 - t
    w[i + 1] += t
    return w + ((1 - t) ** 3 - (1 - t)) / 6 * _A5[i] + (t ** 3 - t) / 6 * _A5[i + 1]


def pedestal(b7, floor=1e-3):
    """The 5 x 5 spline through ln(C + p), p the least constant making min C + p >= floor C0;
    its maximum by nested grid search (to 1e-4 px)."""
    b = b7[1:6, 1:6].astype(float)
    if (b7 > 0).all():
        return engine(b7, SPLINE)
    L = np.log(b + max(0.0, floor * b[2, 2] - b.min()))
    best = (-np.inf, 0.0, 0.0)
    for step, span, centred in ((0.05, 1.2, True), (0.002, 0.06, False), (1e-4, 0.003, False)):
        cx, cy = (0.0, 0.0) if centred else best[1:]
        g = np.arange(-span, span + step / 2, step)
        for y in g + cy:
            row = _w5(y + 2) @ L
            for x in g + cx:
                v = row @ _w5(x + 2)
                if v > best[0]:
                    best = (v, x, y)
    return best[1]


def wls_cubic(b7, damp=1e-2):
    y, x = (a.ravel().astype(float) for a in np.mgrid[-3:4, -3:4])
    v = (b7 / b7[3, 3]).ravel()
    w = np.where(v > 0, v * v, 0.0)
    lnv = np.log(np.where(v > 0, v, 1.0))
    terms = [(i, d - i) for d in range(4) for i in range(d + 1)]
    a = np.stack([x ** i * y ** j for i, j in terms], 1)
    m = a.T @ (w[:, None] * a)
    for t, (i, j) in enumerate(terms):
        if i + j == 3:
            m[t, t] += damp * w.sum()
    c = np.linalg.solve(m, a.T @ (w * lnv))
    p = np.zeros(2)
    for _ in range(60):
        g, h = np.zeros(2), np.zeros((2, 2))
        for t, (i, j) in enumerate(terms):
            if i:
                g[0] += c[t] * i * p[0] ** (i - 1) * p[1] ** j
            if j:
                g[1] += c[t] * j * p[0] ** i * p[1] ** (j - 1)
            if i > 1:
                h[0, 0] += c[t] * i * (i - 1) * p[0] ** (i - 2) * p[1] ** j
            if j > 1:
                h[1, 1] += c[t] * j * (j - 1) * p[0] ** i * p[1] ** (j - 2)
            if i and j:
                h[0, 1] += c[t] * i * j * p[0] ** (i - 1) * p[1] ** (j - 1)
        h[1, 0] = h[0, 1]
        s = np.clip(-np.linalg.solve(h, g), -0.25, 0.25)
        p += s
        if np.abs(s).max() < 1e-10:
            break
    return p[0]


def block(b7):
    return 7 if (b7 > 0).all() else 5 if (b7[1:6, 1:6] > 0).all() else 3


def main(paths):
    for path in paths:
        d = np.loadtxt(path, ndmin=2)
        up, ideal = d[:, 1], d[:, 4]
        eng, mod = d[:, 6:55].reshape(-1, 7, 7), d[:, 55:104].reshape(-1, 7, 7)
        print(f"{path}: {len(d)} windows")
        for name, f in (("spline", lambda b: engine(b, SPLINE)),
                        ("3-point Gaussian", lambda b: engine(b, GAUSS)),
                        ("pedestal", pedestal), ("wls cubic", wls_cubic)):
            ee = np.array([f(b) for b in eng])
            em = np.array([f(b) for b in mod])
            print(f"  {name:17s} engine - CCM {np.mean(ee - em):+.4f} px (std {np.std(ee - em):.4f}),"
                  f" engine - ideal {np.mean(up + ee - ideal):+.4f}, CCM - ideal"
                  f" {np.mean(up + em - ideal):+.4f}")
            if name == "spline":
                be = np.array([block(b) for b in eng])
                bm = np.array([block(b) for b in mod])
                for n in (7, 5, 3):
                    sel = be == n
                    if sel.any():
                        print(f"    engine's block {n}: {sel.sum()} windows, engine - CCM"
                              f" {np.mean((ee - em)[sel]):+.4f} px (the CCM's blocks there:"
                              f" {', '.join(str(k) for k in sorted(set(bm[sel])))})")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: shear_estimators.py DUMP...")
    main(sys.argv[1:])
