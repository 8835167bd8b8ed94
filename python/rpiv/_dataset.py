# SPDX-License-Identifier: GPL-3.0-or-later
"""Vector fields as xarray Datasets in pivpy's layout (docs/python.md, "The dataset"):
dims (y, x, t) for every per-vector variable, coordinates x(x), y(y), t(t); u, v (float32),
chc (int8: 1 valid, 0 replaced or masked), flag (rpiv's: 0 valid, 1 replaced, 2 masked),
peak_ratio, correlation; units pix, pix/dt, frame, or mm, m/s, s with a scale and a dt."""
import ctypes

import numpy as np
import xarray as xr

FLAG_VALID, FLAG_REPLACED, FLAG_MASKED = 0, 1, 2


def _units(scale, dt, physical):
    """(x/y unit, u/v unit, t unit, factor on coordinates, factor on u/v, delta_t)."""
    if physical and scale > 0 and dt > 0:
        return "mm", "m/s", "s", scale, scale * 1e-3 / dt, dt
    return "pix", "pix/dt", "frame", 1.0, 1.0, 0.0


def make_dataset(x_px, y_px, t, u_px, v_px, flag, peak_ratio, corr, scale, dt, attrs,
                 physical=True, t_units=None):
    """A Dataset from arrays on (y, x, t) in pixels; t in frames (pair index) or, with
    scale and dt, seconds as given."""
    xu, uu, tu, cfac, ufac, delta_t = _units(scale, dt, physical)
    tu = t_units or tu
    flag = np.asarray(flag, dtype=np.int8)
    chc = (flag == FLAG_VALID).astype(np.int8)
    dims = ("y", "x", "t")
    data = {
        "u": (dims, (np.asarray(u_px, np.float64) * ufac).astype(np.float32),
              {"units": uu, "long_name": "displacement along x" if uu == "pix/dt"
               else "velocity along x"}),
        "v": (dims, (np.asarray(v_px, np.float64) * ufac).astype(np.float32),
              {"units": uu, "long_name": ("displacement along y" if uu == "pix/dt"
                                          else "velocity along y") + " (image rows, downward)"}),
        "chc": (dims, chc, {"units": "1", "long_name": "choice: 1 valid, 0 replaced or masked",
                            "flag_values": np.array([0, 1], np.int8),
                            "flag_meanings": "replaced_or_masked valid"}),
        "flag": (dims, flag, {"units": "1",
                              "long_name": "rpiv vector status: 0 valid, 1 replaced, 2 masked",
                              "flag_values": np.array([0, 1, 2], np.int8),
                              "flag_meanings": "valid replaced masked"}),
        "peak_ratio": (dims, np.asarray(peak_ratio, np.float32),
                       {"units": "1", "long_name": "highest / second-highest correlation peak"}),
        "correlation": (dims, np.asarray(corr, np.float32),
                        {"units": "1", "long_name": "normalised correlation at the peak"}),
    }
    coords = {
        "x": ("x", np.asarray(x_px, np.float64) * cfac,
              {"units": xu, "long_name": "window centre x, image A columns"}),
        "y": ("y", np.asarray(y_px, np.float64) * cfac,
              {"units": xu, "long_name": "window centre y, image A rows (downward)"}),
        "t": ("t", np.asarray(t, np.float64),
              {"units": tu, "long_name": "time of the field" if tu == "s" else "pair index"}),
    }
    a = {"delta_t": float(delta_t), "orientation": "image", "Conventions": "CF-1.8",
         "title": "rpiv vector field", "scale_mm_per_px": float(scale), "dt_s": float(dt)}
    a.update(attrs)
    a.setdefault("files", [])
    return xr.Dataset(data, coords=coords, attrs=a)


UNIT_ODD_Y, UNIT_ONE = 0x100, 0  # RPIV_UNIT_ODD_Y, RPIV_UNIT_ONE


def field_to_dataset(f, attrs, physical=True):
    """A Dataset (t of length 1, t = 0) from a librpiv rpiv_field (ctypes structure), with
    the field's extra quantities (sigma_u, sigma_v, bias_u, u_corrected, ...) as variables of
    the same dims, in the units the NetCDF writer gives them (the library's rpiv_unit_name and
    rpiv_unit_factor: pixels, or with a scale and a dt physical units)."""
    from ._lib import lib  # the library is loaded by the package before any field exists
    nx, ny = f.nx, f.ny

    def grab(ptr, dtype):
        return np.ctypeslib.as_array(ptr, shape=(ny, nx)).astype(dtype)[:, :, None]

    x = f.x0 + f.dx * np.arange(nx)
    y = f.y0 + f.dy * np.arange(ny)
    ds = make_dataset(x, y, [0.0], grab(f.u, np.float32), grab(f.v, np.float32),
                      grab(f.flag, np.int8), grab(f.peak_ratio, np.float32),
                      grab(f.corr, np.float32), f.scale_mm_per_px, f.dt_s, attrs, physical)
    phys = physical and f.scale_mm_per_px > 0 and f.dt_s > 0
    for k in range(f.nq):
        q = f.q[k]
        name = q.name.decode("utf-8", "replace")
        scaled = phys and (q.unit & ~UNIT_ODD_Y) != UNIT_ONE
        factor = lib.rpiv_unit_factor(ctypes.byref(f), q.unit) if scaled else 1.0
        units = lib.rpiv_unit_name(q.unit, 1 if scaled else 0).decode()
        data = (grab(q.data, np.float64) * factor).astype(np.float32)
        ds[name] = (("y", "x", "t"), data,
                    {"units": units, "long_name": name,
                     "y_parity": "odd" if q.unit & UNIT_ODD_Y else "even"})
    return ds


def load_nc(path):
    """A NetCDF vector file as a Dataset of this layout: a file already in it (u on (y, x, t)
    with chc) is returned as read; rpiv's older layout (dims (t, y, x), `flag`, units pix and
    pix/dt, scale_mm_per_px and dt_s as global attributes) is converted."""
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    for name in ("u", "v"):
        if name not in ds:
            raise ValueError("not a vector field: no variable '%s'" % name)
    dims = ds["u"].dims
    if set(dims) != {"x", "y", "t"}:
        raise ValueError("variable u has dims %s, expected (y, x, t) or (t, y, x)" % (dims,))
    if dims == ("y", "x", "t") and "chc" in ds:
        files = ds.attrs.get("files", [])
        ds.attrs["files"] = [files] if isinstance(files, str) else [str(f) for f in files]
        return ds
    # the older layout (or a layout missing chc): rebuild it from pixels
    ds = ds.transpose("y", "x", "t")
    scale = float(ds.attrs.get("scale_mm_per_px", 0) or 0)
    dt = float(ds.attrs.get("dt_s", 0) or 0)
    xu = ds["x"].attrs.get("units", "pix")
    uu = ds["u"].attrs.get("units", "pix/dt")
    cfac = scale if xu == "mm" and scale > 0 else 1.0
    ufac = scale * 1e-3 / dt if uu == "m/s" and scale > 0 and dt > 0 else 1.0
    shape = ds["u"].shape
    if "flag" in ds:
        flag = ds["flag"].values.astype(np.int8)
    elif "chc" in ds:
        flag = np.where(ds["chc"].values > 0, FLAG_VALID, FLAG_REPLACED).astype(np.int8)
    else:
        flag = np.zeros(shape, np.int8)

    def get(name):
        return ds[name].values if name in ds else np.zeros(shape, np.float32)

    attrs = {k: v for k, v in ds.attrs.items()
             if k not in ("scale_mm_per_px", "dt_s", "delta_t", "orientation", "Conventions")}
    attrs["source_file"] = str(path)
    # the older layout's t is the pair index (its writer had no time between pairs)
    return make_dataset(ds["x"].values / cfac, ds["y"].values / cfac, ds["t"].values,
                        ds["u"].values / ufac, ds["v"].values / ufac, flag, get("peak_ratio"),
                        get("correlation"), scale, dt, attrs, t_units="frame")
