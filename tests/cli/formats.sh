#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# The vector files as users' tools read them: the .nc through xarray (pivpy's layout: dims
# (y, x, t), u v chc, units, delta_t, files) for one pair and a series, the .vtk through VTK's
# legacy reader with its default settings (every array loads), the same numbers as the .txt
# written by the same run, and --y-up (origin bottom-left, v up) in every format.
# Needs /usr/bin/python3 with python3-xarray, python3-netcdf4 and python3-vtk9
# (scripts/install-deps); skipped (77) without them.
set -u
bin=${RPIV_BIN:?RPIV_BIN not set}
data=${RPIV_TEST_DATA:?RPIV_TEST_DATA not set}
py=/usr/bin/python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0; pass=0
ok() { pass=$((pass + 1)); }
ko() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }
if ! "$py" -c 'import xarray, netCDF4, vtk' 2>/dev/null; then
    echo "formats: skipped: /usr/bin/python3 lacks xarray, netCDF4 or vtk (scripts/install-deps)"
    exit 77
fi
data=$(cd "$data" && pwd)
a="$data/Oseen_center_01.tif"
b="$data/Oseen_center_02.tif"
opts=(--quiet --window 32 --overlap 0.5 --scale 0.05 --dt 0.002)

for ext in txt nc vtk dat; do
    "$bin" piv "${opts[@]}" "$a" "$b" -o "$tmp/one.$ext" || ko "one pair -> .$ext"
    "$bin" piv "${opts[@]}" --y-up "$a" "$b" -o "$tmp/up.$ext" || ko "--y-up -> .$ext"
done
printf '%s %s\n%s %s\n%s %s\n' "$a" "$b" "$b" "$a" "$a" "$b" >"$tmp/pairs.txt"
"$bin" piv "${opts[@]}" "$tmp/pairs.txt" -o "$tmp/series.nc" || ko "series -> .nc"
"$bin" piv --quiet --window 32 --overlap 0.5 "$a" "$b" -o "$tmp/px.nc" || ko "pixels -> .nc"

"$py" - "$tmp" "$a" "$b" <<'PY' && ok || ko "python readers"
import sys
import numpy as np
import xarray as xr
import vtk
from vtk.util.numpy_support import vtk_to_numpy

tmp, fa, fb = sys.argv[1:4]
bad = []
def check(cond, what):
    if not cond:
        bad.append(what)

def load_txt(path):
    names = None
    units = None
    for line in open(path):
        if line.startswith("# units ="):
            units = line.split("=", 1)[1].split()
        elif line.startswith("# x y u v"):
            names = line[1:].split()
    d = np.loadtxt(path, comments="#")
    return {n: d[:, k] for k, n in enumerate(names)}, dict(zip(names, units))

txt, tunits = load_txt(f"{tmp}/one.txt")
check(tunits["x"] == "pix" and tunits["u"] == "pix/dt" and tunits["u_ms"] == "m/s"
      and tunits["x_mm"] == "mm", f"txt units {tunits}")
xs = np.unique(txt["x"]); ys = np.unique(txt["y"])
nx, ny = len(xs), len(ys)
grid = lambda a: a.reshape(ny, nx)

# ---- NetCDF through xarray, pivpy's layout -------------------------------------------
ds = xr.open_dataset(f"{tmp}/one.nc")
for v in ("u", "v", "chc", "flag", "peak_ratio", "correlation"):
    check(v in ds.data_vars and ds[v].dims == ("y", "x", "t"), f"{v} dims {ds[v].dims if v in ds else None}")
check(dict(ds.sizes) == {"y": ny, "x": nx, "t": 1}, f"sizes {dict(ds.sizes)}")
check(ds["x"].attrs["units"] == "mm" and ds["y"].attrs["units"] == "mm", "x, y units mm")
check(ds["u"].attrs["units"] == "m/s" and ds["v"].attrs["units"] == "m/s", "u, v units m/s")
check(ds["t"].attrs["units"] == "frame" and float(ds["t"][0]) == 0, "t frame 0")
check(ds.attrs["delta_t"] == 0.002, f"delta_t {ds.attrs.get('delta_t')}")
files = ds.attrs["files"]
files = [files] if isinstance(files, str) else list(files)
check(files == [f"{fa} {fb}"], f"files {files}")
check(ds.attrs["orientation"] == "image", "orientation image")
check("rpiv_version" in ds.attrs and ds.attrs["windows"] == "32x32", "rpiv parameters")
check(np.allclose(ds["x"].values, xs * 0.05, rtol=1e-12), "x mm values")
check(np.allclose(ds["y"].values, ys * 0.05, rtol=1e-12), "y mm values")
u = ds["u"].isel(t=0).values; v = ds["v"].isel(t=0).values
check(np.allclose(u, grid(txt["u_ms"]), rtol=1e-6, atol=1e-9), "u m/s = txt u_ms")
check(np.allclose(v, grid(txt["v_ms"]), rtol=1e-6, atol=1e-9), "v m/s = txt v_ms")
check(np.allclose(u, grid(txt["u"]) * 0.05e-3 / 0.002, rtol=1e-6, atol=1e-9), "u = u_px * scale / dt")
check(np.array_equal(ds["u_px"].isel(t=0).values, grid(txt["u"]).astype(np.float32)), "u_px = txt u")
chc = ds["chc"].isel(t=0).values; flag = grid(txt["flag"])
check(np.array_equal(chc == 1, flag == 0) and np.array_equal(ds["flag"].isel(t=0).values, flag), "chc, flag")
check(np.array_equal(ds["peak_ratio"].isel(t=0).values, grid(txt["peak_ratio"]).astype(np.float32)), "peak_ratio")
ds.close()

px = xr.open_dataset(f"{tmp}/px.nc")
check(px["x"].attrs["units"] == "pix" and px["u"].attrs["units"] == "pix/dt"
      and px.attrs["delta_t"] == 0 and "u_px" not in px, "pixel units without --scale/--dt")
check(np.array_equal(px["u"].isel(t=0).values, grid(txt["u"]).astype(np.float32)), "pixel u")
px.close()

se = xr.open_dataset(f"{tmp}/series.nc")
check(dict(se.sizes) == {"y": ny, "x": nx, "t": 3} and se["u"].dims == ("y", "x", "t"), f"series sizes {dict(se.sizes)}")
check(list(se["t"].values) == [0, 1, 2], f"series t {se['t'].values}")
sf = list(se.attrs["files"])
check(sf == [f"{fa} {fb}", f"{fb} {fa}", f"{fa} {fb}"], f"series files {sf}")
u0 = se["u"].isel(t=0).values; u1 = se["u"].isel(t=1).values; u2 = se["u"].isel(t=2).values
check(np.array_equal(u0, u2) and np.allclose(u0, grid(txt["u_ms"]), rtol=1e-6, atol=1e-9), "series pair 1 = 3 = one")
# the reversed pair measures about the opposite displacement where pair 1 is valid
m = (se["chc"].isel(t=0).values == 1) & (se["chc"].isel(t=1).values == 1)
check(np.median(np.abs(u1[m] + u0[m])) < 0.1 * np.median(np.abs(u0[m])), "reversed pair")
se.close()

# ---- VTK legacy reader, default settings ---------------------------------------------
r = vtk.vtkStructuredGridReader(); r.SetFileName(f"{tmp}/one.vtk"); r.Update()
pd = r.GetOutput().GetPointData()
names = sorted(pd.GetArrayName(k) for k in range(pd.GetNumberOfArrays()))
check(names == sorted(["velocity", "flag", "peak_ratio", "correlation", "coords_mm", "velocity_ms"]), f"vtk arrays {names}")
vel = vtk_to_numpy(pd.GetArray("velocity"))
check(np.array_equal(vel[:, 0], txt["u"].astype(np.float32)) and np.array_equal(vel[:, 1], txt["v"].astype(np.float32)), "vtk velocity")
check(np.array_equal(vtk_to_numpy(pd.GetArray("flag")), txt["flag"].astype(int)), "vtk flag")
check(np.array_equal(vtk_to_numpy(pd.GetArray("peak_ratio")), txt["peak_ratio"].astype(np.float32)), "vtk peak_ratio")
check(np.array_equal(vtk_to_numpy(pd.GetArray("correlation")), txt["correlation"].astype(np.float32)), "vtk correlation")
check(np.allclose(vtk_to_numpy(pd.GetArray("velocity_ms"))[:, 1], txt["v_ms"], rtol=1e-6, atol=1e-9), "vtk velocity_ms")
pts = vtk_to_numpy(r.GetOutput().GetPoints().GetData())
check(np.array_equal(pts[:, 0], txt["x"]) and np.array_equal(pts[:, 1], txt["y"]), "vtk points")

# ---- --y-up: y' = H - 1 - y, v' = -v, rows reordered; recorded everywhere ------------
H = 300
up, _ = load_txt(f"{tmp}/up.txt")
check(np.allclose(np.unique(up["y"]), np.sort(H - 1 - ys)), "y-up y")
key = lambda d: np.lexsort((d["x"], d["y"]))
i_img = np.lexsort((txt["x"], H - 1 - txt["y"])); i_up = key(up)
check(np.array_equal(up["u"][i_up], txt["u"][i_img]) and np.array_equal(up["v"][i_up], -txt["v"][i_img]), "y-up u, v")
check("# orientation = y-up" in open(f"{tmp}/up.txt").read() and "# orientation = y-up" in open(f"{tmp}/up.dat").read(), "y-up txt/dat header")
check("orientation y-up" in open(f"{tmp}/up.vtk").read().split("\n")[1], "y-up vtk title")
du = xr.open_dataset(f"{tmp}/up.nc")
check(du.attrs["orientation"] == "y-up" and np.all(np.diff(du["y"].values) > 0), "y-up nc")
check(np.allclose(du["v"].isel(t=0).values, -np.flipud(grid(txt["v_ms"])), rtol=1e-6, atol=1e-9), "y-up nc v")
du.close()
check("# orientation = image" in open(f"{tmp}/one.txt").read(), "image orientation recorded")

if bad:
    print("\n".join(bad), file=sys.stderr)
    sys.exit(1)
PY

echo "formats: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
