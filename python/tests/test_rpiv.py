# SPDX-License-Identifier: GPL-3.0-or-later
"""The rpiv Python package against the CLI, the ground truth of synthetic pairs and its own
contract (layout, units, errors)."""
import threading

import numpy as np
import pytest
import xarray as xr

import rpiv
from conftest import run_cli


def pair(series, i=1):
    return (str(series / ("pair_%05d_a.tif" % i)), str(series / ("pair_%05d_b.tif" % i)))


# ---- the same numbers as the CLI ---------------------------------------------------------------

@pytest.mark.parametrize("ext", [".txt", ".nc"])
def test_piv_matches_cli(series, tmp_path, ext):
    a, b = pair(series)
    out = tmp_path / ("cli" + ext)
    run_cli("piv", "-q", a, b, "-o", out)
    cli = rpiv.load(out)
    py = rpiv.piv(rpiv.read_image(a), rpiv.read_image(b))
    assert py.u.shape == cli.u.shape and py.u.dims == ("y", "x", "t")
    assert float(abs(py.u - cli.u).max()) <= 1e-6
    assert float(abs(py.v - cli.v).max()) <= 1e-6
    assert np.array_equal(py.flag.values, cli.flag.values)
    assert np.allclose(py.x.values, cli.x.values, atol=1e-9)
    assert np.allclose(py.y.values, cli.y.values, atol=1e-9)
    assert (py.flag == 1).sum() > 0 or (py.flag == 0).all()


def test_piv_uncertainty_matches_cli(series, tmp_path):
    """--uncertainty's sigma_u, sigma_v reach the Dataset as the CLI writes them, in its units."""
    a, b = pair(series)
    out = tmp_path / "unc.nc"
    run_cli("piv", "-q", "--uncertainty", a, b, "-o", out)
    cli = rpiv.load(out)
    py = rpiv.piv(a, b, uncertainty=1)
    valid = py.flag.values == 0
    for name in ("sigma_u", "sigma_v"):
        assert py[name].dims == ("y", "x", "t") and py[name].attrs["units"] == "pix/dt"
        assert float(abs(py[name] - cli[name]).max()) <= 1e-6
        assert (py[name].values[valid] > 0).all()
    phys = rpiv.piv(a, b, uncertainty=1, scale_mm_per_px=0.05, dt_s=0.002)
    assert phys.sigma_u.attrs["units"] == "m/s"
    np.testing.assert_allclose(phys.sigma_u.values, py.sigma_u.values * 0.05e-3 / 0.002,
                               rtol=1e-6)
    assert "sigma_u" not in rpiv.piv(a, b)


def test_ensemble_matches_cli(series, tmp_path):
    out = tmp_path / "ens.txt"
    run_cli("piv", "-q", "--ensemble", "--window", "48,32", str(series / "*.tif"), "-o", out)
    cli = rpiv.load(out)
    calls = []
    ens = rpiv.ensemble([pair(series, i) for i in (1, 2, 3)], windows=(48, 32),
                        progress=lambda d, t: calls.append((d, t)))
    assert float(abs(ens.u - cli.u).max()) <= 1e-6
    assert float(abs(ens.v - cli.v).max()) <= 1e-6
    assert ens.attrs["pairs"] == 3 and len(ens.attrs["files"]) == 6
    assert calls and calls[-1] == (6, 6)  # 3 pairs x 2 passes
    # the glob form gives the same field
    glob = rpiv.ensemble(str(series / "*.tif"), windows="48,32")
    assert np.array_equal(glob.u.values, ens.u.values)


def test_ensemble_refine_matches_cli(series, tmp_path):
    """[piv] ensemble_refine and ensemble_denoise as keyword options: the CLI's field, recorded
    in the attributes; the progress counts the repeats' passes too."""
    out = tmp_path / "ensr.txt"
    run_cli("piv", "-q", "--ensemble", "-S", "piv.ensemble_refine=2", "-S",
            "piv.ensemble_refine_tol_px=0", "-S", "piv.ensemble_denoise=0",
            str(series / "*.tif"), "-o", out)
    cli = rpiv.load(out)
    calls = []
    ens = rpiv.ensemble(str(series / "*.tif"), ensemble_refine=2, ensemble_refine_tol_px=0,
                        ensemble_denoise=0, progress=lambda d, t: calls.append((d, t)))
    assert float(abs(ens.u - cli.u).max()) <= 1e-6
    assert float(abs(ens.v - cli.v).max()) <= 1e-6
    assert str(ens.attrs["ensemble_refine"]) == "2" and str(ens.attrs["ensemble_denoise"]) == "0"
    assert calls[-1] == (15, 15)  # 3 pairs x (3 passes + 2 repeats)
    plain = rpiv.ensemble(str(series / "*.tif"))
    assert float(abs(plain.u - ens.u).max()) > 1e-4


def test_ensemble_sheet_bias_matches_cli(tmp_path):
    """sheet_bias=True: the CCM's bias of every vector, as `rpiv piv --sheet-bias` writes it,
    on a duct flow (its velocity varies across the sheet's depth: a bias that is not 0)."""
    d = tmp_path / "duct"
    run_cli("synth", "-q", "--size", "256x192", "--flow", "duct", "--pairs", "2", "--seed", "3",
            "--out", d)
    out = tmp_path / "sb.nc"
    ini = d / "synth.ini"  # the experiment the images were made with
    run_cli("piv", "-q", "--config", ini, "--ensemble", "--window", "48,32", "--sheet-bias",
            str(d / "*.tif"), "-o", out)
    cli = rpiv.load(out)
    py = rpiv.ensemble(str(d / "*.tif"), windows=(48, 32), sheet_bias=True, config=str(ini))
    for name in ("bias_u", "bias_v", "u_corrected", "v_corrected", "z_ref"):
        assert float(abs(py[name] - cli[name]).max()) <= 1e-6, name
    assert float(abs(py.bias_u).max()) > 1e-3  # the duct's shear across the depth
    np.testing.assert_allclose(py.u_corrected.values, py.u.values - py.bias_u.values,
                               atol=1e-5)
    assert "bias_u" not in rpiv.ensemble(str(d / "*.tif"), windows=(48, 32), config=str(ini))


def test_ensemble_progress_stops_and_raises(series):
    with pytest.raises(rpiv.Error) as e:
        rpiv.ensemble(str(series / "*.tif"), progress=lambda d, t: True)
    assert e.value.status == rpiv.EINTR

    def boom(d, t):
        raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        rpiv.ensemble(str(series / "*.tif"), progress=boom)


# ---- against the ground truth --------------------------------------------------------------

def test_synth_uniform_flow_truth():
    s = rpiv.synth(0, width_px=256, height_px=256, flow="uniform:3.3,-1.7", pairs=1, seed=3)
    assert s.a.shape == (256, 256) and s.a.dtype == np.float32
    assert s.truth.u.shape == (15, 15, 1)
    assert np.allclose(s.truth.u, 3.3) and np.allclose(s.truth.v, -1.7)
    ds = rpiv.piv(s.a, s.b)
    valid = ds.chc.values == 1
    err_u = ds.u.values[valid] - s.truth.u.values[valid]
    err_v = ds.v.values[valid] - s.truth.v.values[valid]
    assert valid.mean() > 0.8
    assert abs(err_u.mean()) < 0.05 and abs(err_v.mean()) < 0.05
    assert np.sqrt((err_u ** 2).mean()) < 0.15 and np.sqrt((err_v ** 2).mean()) < 0.15
    # the same pair as `rpiv synth` writes (index 0 = pair_00001)
    s2 = rpiv.synth(0, width_px=256, height_px=256, flow="uniform:3.3,-1.7", pairs=1, seed=3)
    assert np.array_equal(s.a, s2.a) and np.array_equal(s.b, s2.b)


def test_synth_matches_cli_files(series):
    s = rpiv.synth(0, width_px=320, height_px=256, flow="oseen:4,40", pairs=3, seed=7)
    a, b = pair(series)
    assert np.array_equal(s.a, rpiv.read_image(a))
    assert np.array_equal(s.b, rpiv.read_image(b))
    truth = rpiv.load(str(series / "truth.txt"))  # has scale and dt: mm and m/s
    assert truth.u.attrs["units"] == "m/s" and s.truth.u.attrs["units"] == "pix/dt"
    f = truth.attrs["scale_mm_per_px"] * 1e-3 / truth.attrs["dt_s"]
    assert np.allclose(truth.u.values / f, s.truth.u.values, rtol=0, atol=1e-5)
    assert np.allclose(truth.v.values / f, s.truth.v.values, rtol=0, atol=1e-5)


# ---- inputs: dtypes, strides, masks -----------------------------------------------------------

def test_any_dtype_and_strides_give_the_same_field(series):
    a, b = (rpiv.read_image(p) for p in pair(series))
    ref = rpiv.piv(a, b, windows=(32, 32))
    u16 = rpiv.piv(a.astype(np.uint16), b.astype(np.uint16), windows=(32, 32))
    f64 = rpiv.piv(a.astype(np.float64), b.astype(np.float64), windows=(32, 32))
    ta, tb = np.asfortranarray(a), np.asfortranarray(b)  # column-major strides
    strided = rpiv.piv(np.repeat(a, 2, axis=1)[:, ::2], tb, windows=[32, 32])
    for ds in (u16, f64, strided, rpiv.piv(ta, tb, windows=(32, 32))):
        assert np.array_equal(ds.u.values, ref.u.values)
        assert np.array_equal(ds.v.values, ref.v.values)


def test_mask_array_flags_masked(series):
    a, b = (rpiv.read_image(p) for p in pair(series))
    mask = np.ones_like(a, dtype=np.uint8)
    mask[:, :128] = 0
    ds = rpiv.piv(a, b, mask=mask)
    left = ds.flag.values[:, ds.x.values < 100, 0]
    right = ds.flag.values[:, ds.x.values > 160, 0]
    assert (left == 2).all() and (ds.u.values[:, ds.x.values < 100] == 0).all()
    assert (right != 2).all()
    assert (ds.chc.values[ds.flag.values == 2] == 0).all()


def test_options_take_config_keys(series):
    a, b = pair(series)
    ds = rpiv.piv(a, b, windows=((48, 32), 32), overlap=0.25, subpixel="parabola",
                  median_threshold=0, threads=1, search_radius_px=0)
    assert ds.attrs["windows"] == "48x32,32" and ds.attrs["search_radius_px"] == "0"
    assert ds.attrs["subpixel"] == "parabola" and ds.attrs["threads"] == 1
    assert (ds.flag.values == 0).all()  # validation off: nothing replaced
    assert float(ds.x[1] - ds.x[0]) == 24.0  # 32 px windows at 25 % overlap


def test_cbc_option_and_its_errors(series):
    a, b = pair(series)
    ds = rpiv.piv(a, b, cbc=2, threads=1)
    assert ds.attrs["cbc"] == "2"
    with pytest.raises(rpiv.InputError, match="cbc"):
        rpiv.piv(a, b, cbc=3)
    with pytest.raises(rpiv.InputError, match="cbc"):
        rpiv.ensemble([pair(series)], cbc=1)


def test_threads_give_identical_fields_and_run_concurrently(series):
    a, b = (rpiv.read_image(p) for p in pair(series))
    ref = rpiv.piv(a, b, threads=1)
    out = [None] * 4

    def job(k):
        out[k] = rpiv.piv(a, b, threads=2)

    ts = [threading.Thread(target=job, args=(k,)) for k in range(4)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    for ds in out:
        assert np.array_equal(ds.u.values, ref.u.values)


# ---- layout and units ----------------------------------------------------------------------------

def test_layout_and_units(series):
    a, b = pair(series)
    px = rpiv.piv(a, b)
    assert px.u.dims == px.v.dims == px.chc.dims == px.flag.dims == ("y", "x", "t")
    assert px.u.dtype == np.float32 and px.chc.dtype == np.int8
    assert px.x.attrs["units"] == "pix" and px.u.attrs["units"] == "pix/dt"
    assert px.t.attrs["units"] == "frame" and px.attrs["delta_t"] == 0.0
    assert px.attrs["orientation"] == "image" and px.attrs["files"] == [a, b]
    for name in ("u", "v", "chc", "flag", "peak_ratio", "correlation"):
        assert "units" in px[name].attrs and "long_name" in px[name].attrs
    assert np.array_equal(px.chc.values == 1, px.flag.values == 0)
    si = rpiv.piv(a, b, scale_mm_per_px=0.05, dt_s=2e-3)
    assert si.x.attrs["units"] == "mm" and si.u.attrs["units"] == "m/s"
    assert si.t.attrs["units"] == "s" and si.attrs["delta_t"] == 2e-3
    assert np.allclose(si.x.values, px.x.values * 0.05)
    assert np.allclose(si.u.values, px.u.values * 0.05e-3 / 2e-3, rtol=1e-6)


def test_netcdf_round_trip_and_old_layout(series, tmp_path):
    a, b = pair(series)
    ds = rpiv.piv(a, b)
    ds.to_netcdf(tmp_path / "py.nc")
    back = rpiv.load(tmp_path / "py.nc")
    assert back.u.dims == ("y", "x", "t") and back.attrs["files"] == [a, b]
    assert np.array_equal(back.u.values, ds.u.values)
    # the older rpiv layout: dims (t, y, x), flag and no chc, scale and dt as attributes
    old = xr.Dataset(
        {"u": (("t", "y", "x"), ds.u.values.transpose(2, 0, 1), {"units": "pix/dt"}),
         "v": (("t", "y", "x"), ds.v.values.transpose(2, 0, 1), {"units": "pix/dt"}),
         "flag": (("t", "y", "x"), ds.flag.values.transpose(2, 0, 1))},
        coords={"x": ("x", ds.x.values, {"units": "pix"}), "y": ("y", ds.y.values),
                "t": ("t", [0.0])},
        attrs={"scale_mm_per_px": 0.1, "dt_s": 1e-3})
    old.to_netcdf(tmp_path / "old.nc")
    conv = rpiv.load(tmp_path / "old.nc")
    assert conv.u.dims == ("y", "x", "t") and conv.u.attrs["units"] == "m/s"
    assert np.allclose(conv.u.values, ds.u.values * 0.1e-3 / 1e-3, rtol=1e-6)
    assert np.array_equal(conv.chc.values == 1, ds.flag.values == 0)
    assert conv.x.attrs["units"] == "mm" and np.allclose(conv.x.values, ds.x.values * 0.1)
    assert conv.t.attrs["units"] == "frame" and conv.attrs["delta_t"] == 1e-3


# ---- errors: raise, never crash ----------------------------------------------------------------

def test_errors(series, tmp_path):
    a = rpiv.read_image(pair(series)[0])
    with pytest.raises(rpiv.InputError, match="differ in size"):
        rpiv.piv(a, a[:-1])
    bad = a.copy()
    bad[10, 20] = np.nan
    with pytest.raises(ValueError, match="row 10, column 20"):
        rpiv.piv(bad, a)
    with pytest.raises(rpiv.InputError, match="2-D"):
        rpiv.piv(a[None], a[None])
    with pytest.raises(rpiv.InputError, match="dtype"):
        rpiv.piv(a.astype(str), a)
    with pytest.raises(rpiv.InputError, match="dtype"):
        rpiv.piv(a.astype(np.complex64), a)
    with pytest.raises(rpiv.InputError):
        rpiv.piv(object(), a)
    with pytest.raises(rpiv.FileError, match="nosuch.tif") as e:
        rpiv.read_image(tmp_path / "nosuch.tif")
    assert isinstance(e.value, OSError) and e.value.status == rpiv.EIO
    with pytest.raises(rpiv.FileError):
        rpiv.load(tmp_path / "nosuch.nc")
    with pytest.raises(rpiv.InputError, match="overlap"):
        rpiv.piv(a, a, overlap=0.99)
    with pytest.raises(rpiv.InputError, match="unknown option 'windowz'"):
        rpiv.piv(a, a, windowz=32)
    with pytest.raises(rpiv.InputError):
        rpiv.piv(a[:40, :40], a[:40, :40])  # a 64 px window larger than the image
    with pytest.raises(rpiv.InputError, match="windows"):
        rpiv.piv(a, a, windows=("x", None))
    with pytest.raises(rpiv.InputError):
        rpiv.read_image(42)
    notimg = tmp_path / "notimage.tif"
    notimg.write_bytes(b"not an image at all")
    with pytest.raises(rpiv.InputError, match="notimage.tif"):
        rpiv.read_image(notimg)
    with pytest.raises(rpiv.InputError):
        rpiv.ensemble([("only-one",) * 3])
    with pytest.raises(rpiv.FileError):
        rpiv.ensemble([(tmp_path / "x_a.tif", tmp_path / "x_b.tif")])
    with pytest.raises(rpiv.InputError):
        rpiv.synth(0, width_px=-3)
    with pytest.raises(rpiv.InputError):
        rpiv.raytrace([float("nan")])
    assert issubclass(rpiv.InputError, rpiv.Error) and issubclass(rpiv.InputError, ValueError)


# ---- optics and the CCM ------------------------------------------------------------------------

def test_raytrace_power_balance():
    r = rpiv.raytrace([0.5, 1.0, 2.0])
    at = r.attrs
    total = (at["power_refl_face"] + at["power_refl_floor"] + at["power_tir"]
             + at["power_missed"] + at["power_transmitted"])
    assert abs(total - at["power_incident"]) < 1e-9 and abs(at["power_incident"] - 1) < 1e-9
    assert r.intensity.shape == (3, 200) and (r.intensity.values >= 0).all()
    assert np.allclose(r.intensity_norm.max(axis=1), 1.0)
    assert np.allclose(r.z_star.values, (np.arange(200) + 0.5) * 0.005)


def test_ccm_predict():
    p = rpiv.ccm.predict(0.5)
    # dt = 1 ms at Re = 465: 3.50 px per U_b (rpiv/ccm.h)
    assert abs(p.scale_px - 3.50) < 0.01
    assert abs(p.u_star * p.scale_px - p.dx_px) < 1e-12
    assert 0 < p.u_star < 1.6 and p.value > 0
    assert p == rpiv.ccm.predict(0.5)  # deterministic
    with pytest.raises(rpiv.InputError):
        rpiv.ccm.predict(0.5, nosuchkey=1)
    with pytest.raises(rpiv.InputError, match="xstar"):
        rpiv.ccm.predict(float("nan"))
