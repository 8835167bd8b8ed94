#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the error of an uncertainty case is (docs/uncertainty.md, "Where the error is").

Reads the per-vector dump of tests/test_uncertainty (RPIV_UNC_DUMP="kind flow noise d_tau
[count]": lines "field i j x y err_u err_v sigma_u sigma_v", valid vectors only) and prints,
for u and v:

- the issue's figures: coverage (|error| <= sigma), RMS error, median sigma and their ratio;
- how concentrated the squared error is: the share of the sum of squared errors carried by the
  10 % of the vectors with the largest |error|;
- the class oracle: each vector's class is its grid node (pooled over the fields: the
  realisations of one case) or, with --vortex, the grid's edge or its distance from the vortex's
  centre in 32 px bins; a sigma equal to its class's RMS error (the best a sigma can do that
  knows where the vector is, not its particular error) has the median / RMS-error ratio printed
  as "oracle". Where it is below 1/1.5 no honest sigma of that kind meets the median criterion;
- the classes carrying most of the squared error, with their RMS error, RMS sigma, coverage;
- the sigma deciles: RMS error / RMS sigma / coverage of the vectors binned by their own sigma.

Usage: RPIV_UNC_DUMP="0 2 0.05 2" build/tests/test_uncertainty > d.txt
       /usr/bin/python3 tests/tools/unc_where.py d.txt [--vortex]
"""
import math
import sys


def load(path):
    rows = []
    with open(path) as f:
        for line in f:
            p = line.split()
            if len(p) == 9 and p[0].isdigit():
                rows.append([int(p[0]), int(p[1]), int(p[2])] + [float(x) for x in p[3:]])
    return rows


def rms(xs):
    return math.sqrt(sum(x * x for x in xs) / len(xs)) if xs else 0.0


def median(xs):
    s = sorted(xs)
    n = len(s)
    return 0.0 if not n else (s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2]))


def classes(rows, vortex):
    ni = max(r[1] for r in rows)
    nj = max(r[2] for r in rows)
    out = []
    for r in rows:
        edge = r[1] in (0, ni) or r[2] in (0, nj)
        if vortex:
            d = math.hypot(r[3] - 128.37, r[4] - 127.81)
            out.append("edge" if edge else "r %3d-%3d" % (32 * int(d // 32), 32 * int(d // 32) + 32))
        else:
            out.append("node %d,%d%s" % (r[1], r[2], " (edge)" if edge else ""))
    return out


def report(rows, vortex):
    cls = classes(rows, vortex)
    for c, name in ((0, "u"), (1, "v")):
        e = [r[5 + c] for r in rows]
        s = [r[7 + c] for r in rows]
        n = len(e)
        re = rms(e)
        cov = sum(abs(a) <= b for a, b in zip(e, s)) / n
        e2 = sorted((a * a for a in e), reverse=True)
        top = sum(e2[: n // 10]) / sum(e2)
        groups = {}
        for k in range(n):
            groups.setdefault(cls[k], []).append(k)
        orc = [0.0] * n
        tab = []
        for g, ks in groups.items():
            ge = rms([e[k] for k in ks])
            for k in ks:
                orc[k] = ge
            tab.append((sum(e[k] ** 2 for k in ks) / sum(e2), g, len(ks), ge,
                        rms([s[k] for k in ks]),
                        sum(abs(e[k]) <= s[k] for k in ks) / len(ks)))
        print("%s: n %d, coverage %.3f, RMS error %.4f, median sigma %.4f, ratio %.2f, RMS sigma "
              "%.4f" % (name, n, cov, re, median(s), median(s) / re, rms(s)))
        print("   10 %% of the vectors (largest |error|) carry %.0f %% of the squared error; class "
              "oracle ratio %.2f (%d classes)" % (100 * top, median(orc) / re, len(groups)))
        tab.sort(reverse=True)
        for t in tab[: (6 if vortex else 4)]:
            print("   %-16s n %4d: %4.0f %% of the squared error, RMS error %.4f, RMS sigma %.4f, "
                  "coverage %.2f" % (t[1], t[2], 100 * t[0], t[3], t[4], t[5]))
        o = sorted(range(n), key=lambda k: s[k])
        dec = []
        for b in range(10):
            ks = o[b * n // 10:(b + 1) * n // 10]
            dec.append("%.4f/%.4f/%.2f" % (rms([e[k] for k in ks]), rms([s[k] for k in ks]),
                                           sum(abs(e[k]) <= s[k] for k in ks) / len(ks)))
        print("   by sigma decile (RMS error/RMS sigma/coverage):")
        print("     " + " ".join(dec[:5]))
        print("     " + " ".join(dec[5:]))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    report(load(sys.argv[1]), "--vortex" in sys.argv[2:])
