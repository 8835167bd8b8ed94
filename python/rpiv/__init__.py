# SPDX-License-Identifier: GPL-3.0-or-later
"""rpiv: particle image velocimetry over librpiv (ctypes): numpy in, xarray out.

    import rpiv
    a = rpiv.read_image("A.tif"); b = rpiv.read_image("B.tif")
    ds = rpiv.piv(a, b, windows=(64, 32, 32), overlap=0.5)   # pivpy's layout, dims (y, x, t)

See docs/python.md for the layout of the datasets, the options and the errors.
"""
import collections
import ctypes
import os
import tempfile
import threading

import numpy as np

from . import _lib
from ._lib import lib
from ._dataset import field_to_dataset, load_nc

__all__ = ["Error", "InputError", "FileError", "read_image", "piv", "ensemble", "load",
           "synth", "raytrace", "ccm", "__version__"]

__version__ = lib.rpiv_version_string().decode()

# rpiv_status codes (rpiv/error.h)
OK, ENOMEM, EINVAL, EIO, EFORMAT, ESIZE, ECONFIG, ENUMERIC, EINTR, ELIMIT = range(10)


class Error(Exception):
    """A failure reported by librpiv: .status is the rpiv_status code, str() the library's
    one-line message (naming the file, key or value at fault)."""

    def __init__(self, message, status=EINVAL):
        super().__init__(message)
        self.status = status


class InputError(Error, ValueError):
    """The input is wrong: a parameter out of range, an unknown key, sizes that do not match,
    a corrupt file, an array of the wrong shape or type, NaN pixels."""


class FileError(Error, OSError):
    """A file could not be opened, read or written (rpiv's RPIV_EIO)."""


_INPUT = (EINVAL, EFORMAT, ESIZE, ECONFIG)

# FFTW's planner (rpiv_piv_new) must not run in two threads at once.
_plan_lock = threading.Lock()


def _raise(status, what=None):
    msg = lib.rpiv_errmsg().decode(errors="replace")
    if not msg:
        msg = lib.rpiv_strerror(status).decode()
    if what:
        msg = "%s: %s" % (what, msg)
    if status in _INPUT:
        raise InputError(msg, status)
    if status == EIO:
        raise FileError(msg, status)
    if status == ENOMEM:
        raise MemoryError(msg)
    raise Error(msg, status)


def _check(status, what=None):
    if status != OK:
        _raise(status, what)


def _path(p, what="path"):
    if isinstance(p, bytes):
        return p
    if isinstance(p, (str, os.PathLike)):
        s = os.fsencode(p)
        if b"\0" in s:
            raise InputError("%s: NUL byte in %r" % (what, p))
        return s
    raise InputError("%s: expected a file name, got %s" % (what, type(p).__name__))


# ---- images ----------------------------------------------------------------------------------

def read_image(path, page=0):
    """Read page `page` of a grey image (TIFF, PNG, PGM, BMP, JPEG) into a float32 array of
    shape (height, width), the file's grey levels (RGB becomes luminance)."""
    if not isinstance(page, (int, np.integer)) or isinstance(page, bool) or page < 0:
        raise InputError("read_image: page must be an integer >= 0, got %r" % (page,))
    im = ctypes.POINTER(_lib.Image)()
    _check(lib.rpiv_image_load(_path(path, "read_image"), int(page), ctypes.byref(im), None))
    try:
        w, h = im.contents.w, im.contents.h
        return np.ctypeslib.as_array(im.contents.px, shape=(h, w)).copy()
    finally:
        lib.rpiv_image_free(im)


def _as_frame(x, what):
    """A C-contiguous float32 copy of a 2-D array of any real numeric dtype and strides (or the
    image file it names), checked finite. Returns (array, rpiv_image viewing it, path or None)."""
    path = None
    if isinstance(x, (str, bytes, os.PathLike)):
        path = os.fsdecode(x)
        x = read_image(x)
    try:
        arr = np.asarray(x)
    except Exception as exc:  # ragged lists and the like
        raise InputError("%s: not an array: %s" % (what, exc)) from None
    if arr.dtype.kind not in "biuf":
        raise InputError("%s: expected a real numeric array, got dtype %s" % (what, arr.dtype))
    if arr.ndim != 2:
        raise InputError("%s: expected a 2-D image (rows, columns), got shape %s"
                         % (what, arr.shape))
    if arr.shape[0] < 1 or arr.shape[1] < 1 or arr.shape[0] > 2**31 - 1 \
            or arr.shape[1] > 2**31 - 1:
        raise InputError("%s: empty or too large image, shape %s" % (what, arr.shape))
    with np.errstate(over="ignore", invalid="ignore"):
        arr = np.ascontiguousarray(arr, dtype=np.float32)
    if not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise InputError("%s: non-finite pixel (NaN or out of float32 range) at row %d, "
                         "column %d" % (what, bad[0], bad[1]))
    im = _lib.Image(arr.shape[1], arr.shape[0], 32,
                    arr.ctypes.data_as(ctypes.POINTER(ctypes.c_float)))
    return arr, im, path


# ---- the experiment: config keys -------------------------------------------------------------

class _Experiment:
    """The opaque rpiv_experiment, set from an INI file and key = value pairs."""

    def __init__(self, config=None):
        self.ptr = ctypes.c_void_p()
        _check(lib.rpiv_experiment_new(ctypes.byref(self.ptr)))
        if config is not None:
            _check(lib.rpiv_config_load(_path(config, "config"), self.ptr))

    def __del__(self):
        if getattr(self, "ptr", None):
            lib.rpiv_experiment_free(self.ptr)
            self.ptr = None

    @staticmethod
    def _text(key, value):
        if isinstance(value, bool):
            return b"1" if value else b"0"
        if isinstance(value, (list, tuple, np.ndarray)):
            return ",".join(str(v) for v in value).encode()
        if isinstance(value, (str, os.PathLike)):
            return os.fsencode(value)
        if isinstance(value, (int, float, np.integer, np.floating)):
            return repr(value).encode() if isinstance(value, float) else str(value).encode()
        raise InputError("%s: unsupported value %r" % (key, value))

    def set(self, section, key, value, origin):
        st = lib.rpiv_config_set(self.ptr, section.encode(), key.encode(),
                                 self._text(key, value), origin.encode())
        return st

    def set_any(self, sections, key, value, origin):
        """Set `key` in the first of `sections` that has it; section.key names one."""
        if "." in key:
            sec, k = key.split(".", 1)
            _check(self.set(sec, k, value, origin))
            return
        for sec in sections:
            st = self.set(sec, key, value, origin)
            if st == OK:
                return
            if "unknown key" not in lib.rpiv_errmsg().decode(errors="replace"):
                _raise(st)
        raise InputError("%s: unknown option '%s' (keys of [%s]; 'section.key' via set=)"
                         % (origin, key, "], [".join(sections)))

    def apply(self, sections, options, overrides, origin):
        for k, v in (overrides or {}).items():
            if "." not in k:
                raise InputError("%s: set= keys are 'section.key', got '%s'" % (origin, k))
            self.set_any(sections, k, v, origin)
        for k, v in options.items():
            self.set_any(sections, k, v, origin)


def _windows_text(windows):
    if isinstance(windows, str):
        return windows
    if isinstance(windows, (int, np.integer)):
        return str(int(windows))
    try:
        parts = []
        for w in windows:
            if isinstance(w, (tuple, list)):
                if len(w) != 2:
                    raise TypeError
                parts.append("%dx%d" % (int(w[0]), int(w[1])))
            else:
                parts.append(str(int(w)))
        return ",".join(parts)
    except (TypeError, ValueError):
        raise InputError("windows: expected sizes such as (64, 32, 32) or ((64, 48), 32), got %r"
                         % (windows,)) from None


def _piv_setup(windows, overlap, options, origin):
    options = dict(options)
    config = options.pop("config", None)
    overrides = options.pop("set", None)
    exp = _Experiment(config)
    if windows is not None:
        exp.set_any(["piv"], "windows", _windows_text(windows), origin)
    if overlap is not None:
        exp.set_any(["piv"], "overlap", overlap, origin)
    mask = options.pop("mask", None)
    mask_arr = mask_im = None
    if mask is not None and not isinstance(mask, (str, bytes, os.PathLike)):
        mask_arr, mask_im, _ = _as_frame(mask, origin + ": mask")
    elif mask is not None:
        exp.set_any(["piv"], "mask", os.fsdecode(mask), origin)
    exp.apply(["piv"], options, overrides, origin)
    params = lib.rpiv_experiment_piv(exp.ptr)
    _check(lib.rpiv_piv_params_check(params))
    return exp, params, (mask_arr, mask_im)


def _piv_params_attrs(exp, pv):
    """rpiv's parameters as global attributes (the keys of [piv])."""
    attrs = {}
    keys = ["windows", "overlap", "step_px", "subpixel", "median_threshold", "median_eps_px",
            "search_radius_px", "cbc", "ensemble_refine", "ensemble_refine_tol_px",
            "ensemble_denoise",
            "background", "roi", "mask", "deform", "scale_mm_per_px", "dt_s"]
    text = _config_text(exp)
    for k in keys:
        if ("piv", k) in text:
            attrs[k] = text[("piv", k)]
    if pv:
        attrs["threads"] = lib.rpiv_piv_threads(pv)
    return attrs


def _config_text(exp):
    """The effective [section] key = value pairs of an experiment, read back from the INI text
    the library writes (rpiv_config_write)."""
    libc = ctypes.CDLL(None)
    libc.tmpfile.restype = ctypes.c_void_p
    libc.fclose.argtypes = [ctypes.c_void_p]
    libc.rewind.argtypes = [ctypes.c_void_p]
    libc.fread.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_size_t, ctypes.c_void_p]
    libc.fread.restype = ctypes.c_size_t
    fp = libc.tmpfile()
    if not fp:
        return {}
    try:
        lib.rpiv_config_write.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
        lib.rpiv_config_write.restype = ctypes.c_int
        if lib.rpiv_config_write(exp.ptr, fp) != OK:
            return {}
        libc.rewind(fp)
        chunks = []
        buf = ctypes.create_string_buffer(65536)
        while True:
            n = libc.fread(buf, 1, 65536, fp)
            if not n:
                break
            chunks.append(buf.raw[:n])
    finally:
        libc.fclose(fp)
    out, sec = {}, None
    for line in b"".join(chunks).decode(errors="replace").splitlines():
        line = line.split("#", 1)[0].split(";", 1)[0].strip()
        if line.startswith("[") and line.endswith("]"):
            sec = line[1:-1]
        elif "=" in line and sec:
            k, v = line.split("=", 1)
            out[(sec, k.strip())] = v.strip()
    return out


def _mask_image(exp, params, mask):
    """(keep-alive array, pointer to the mask image or None, image to free or None)."""
    arr, im = mask
    if im is not None:
        return arr, ctypes.pointer(im), None
    path = _config_text(exp).get(("piv", "mask"), "")
    if not path:
        return None, None, None
    mim = ctypes.POINTER(_lib.Image)()
    _check(lib.rpiv_image_load(_path(path, "mask"), 0, ctypes.byref(mim), None))
    return None, mim, mim


def _new_plan(params, w, h, mask_ptr):
    pv = ctypes.c_void_p()
    with _plan_lock:
        st = lib.rpiv_piv_new(params, w, h, mask_ptr, ctypes.byref(pv))
    _check(st)
    return pv


def _take_field(fptr, attrs, physical=True):
    try:
        return field_to_dataset(fptr.contents, attrs, physical)
    finally:
        lib.rpiv_field_free(fptr)


def _base_attrs(exp, pv, files, mode):
    attrs = {"rpiv_version": __version__, "mode": mode, "files": files}
    attrs.update(_piv_params_attrs(exp, pv))
    return attrs


# ---- one pair ----------------------------------------------------------------------------------

def piv(a, b, windows=(64, 32, 32), overlap=0.5, **options):
    """Multi-pass deforming FFT PIV of one pair (the numbers of `rpiv piv A B`).

    a, b: 2-D arrays (any real dtype and strides; converted once to float32) or image files.
    windows, overlap and **options take the names of the [piv] keys (docs/config.md): step_px,
    subpixel, median_threshold, median_eps_px, roi, mask (a file or a 2-D array, 0 = masked),
    threads, scale_mm_per_px, dt_s, deform, max_mem_mb; config=INI file, set={"piv.key": v}.
    Returns an xarray.Dataset in pivpy's layout (dims (y, x, t), t of length 1)."""
    options = dict(options)
    if options.get("ensemble"):
        raise InputError("piv: ensemble is a series mode: use rpiv.ensemble(pairs)")
    if options.get("background", "none") not in ("none", None):
        raise InputError("piv: background is the series' min or mean image: use "
                         "rpiv.ensemble(pairs, background=...) or subtract it from a and b")
    exp, params, mask = _piv_setup(windows, overlap, options, "piv")
    arr_a, im_a, path_a = _as_frame(a, "piv: frame A")
    arr_b, im_b, path_b = _as_frame(b, "piv: frame B")
    if arr_a.shape != arr_b.shape:
        raise InputError("piv: frames A and B differ in size: %s and %s (rows, columns)"
                         % (arr_a.shape, arr_b.shape))
    keep, mptr, mfree = _mask_image(exp, params, mask)
    pv = ctypes.c_void_p()
    try:
        h, w = arr_a.shape
        pv = _new_plan(params, w, h, mptr)
        f = ctypes.POINTER(_lib.Field)()
        _check(lib.rpiv_piv_run(pv, ctypes.byref(im_a), ctypes.byref(im_b), ctypes.byref(f)))
        files = [path_a or "", path_b or ""] if (path_a or path_b) else []
        return _take_field(f, _base_attrs(exp, pv, files, "instantaneous"))
    finally:
        lib.rpiv_piv_free(pv)
        if mfree:
            lib.rpiv_image_free(mfree)
        del keep


# ---- a series: ensemble ----------------------------------------------------------------------

class _ProgressHook:
    """progress(done, total) from the library's calling thread; a true return or an exception
    stops the run (the exception is raised again afterwards)."""

    def __init__(self, fn):
        self.fn, self.exc = fn, None

        def call(user, done, total):
            try:
                return 1 if self.fn(int(done), int(total)) else 0
            except BaseException as exc:  # noqa: B036 - handed back to the caller below
                self.exc = exc
                return 1

        self.cfn = _lib.PROGRESS_FN(call)
        self.struct = _lib.Progress(self.cfn, None)

    def ptr(self):
        return ctypes.byref(self.struct)

    def reraise(self):
        if self.exc is not None:
            exc, self.exc = self.exc, None
            raise exc


def _pairs_words(pairs):
    """The words of rpiv_pairs_from_args, and a temporary list file to remove (or None)."""
    if isinstance(pairs, (str, bytes, os.PathLike)):
        return [_path(pairs, "ensemble")], None
    try:
        items = list(pairs)
    except TypeError:
        raise InputError("ensemble: pairs must be a list of (A, B) files, a list file or a "
                         "glob, got %s" % type(pairs).__name__) from None
    if not items:
        raise InputError("ensemble: no pairs given")
    if all(isinstance(p, (str, bytes, os.PathLike)) for p in items):
        return [_path(p, "ensemble") for p in items], None
    lines = []
    for k, p in enumerate(items):
        if isinstance(p, (str, bytes, os.PathLike)):
            p = (p,)
        if not isinstance(p, (tuple, list)) or len(p) not in (1, 2):
            raise InputError("ensemble: pair %d: expected (A, B) or a double-frame file, got %r"
                             % (k + 1, p))
        names = []
        for q in p:
            s = os.path.abspath(os.fsdecode(_path(q, "ensemble: pair %d" % (k + 1))))
            if '"' in s or "\n" in s or "\r" in s:
                raise InputError("ensemble: pair %d: a quote or line break in %r" % (k + 1, s))
            names.append('"%s"' % s)
        lines.append(" ".join(names))
    fd, tmp = tempfile.mkstemp(prefix="rpiv-pairs-", suffix=".txt")
    with os.fdopen(fd, "w") as fp:
        fp.write("# pairs of rpiv.ensemble\n" + "\n".join(lines) + "\n")
    return [os.fsencode(tmp)], tmp


_PAIRING = {"ab": 0, "consecutive": 1, "time-resolved": 2}
_BACKGROUND = {"none": 0, "min": 1, "mean": 2}


def ensemble(pairs, windows=(64, 32, 32), overlap=0.5, progress=None, pairing="ab",
             sheet_bias=False, **options):
    """Ensemble (sum-of-correlation) PIV over a series streamed from files (the numbers of
    `rpiv piv --ensemble`): pairs is a list of (A, B) file pairs (or double-frame files), a
    .txt/.lst list file, a glob, or the words `rpiv piv` takes. progress(done, total) is
    called between pairs (counting over all passes); returning True stops the run
    (rpiv.Error, status EINTR). Options as for piv(), plus background = none/min/mean.
    sheet_bias=True adds the refracted sheet's bias of every vector by the CCM (`rpiv piv
    --sheet-bias`, docs/bias.md: bias_u, bias_v, their _std, u_corrected, v_corrected, z_ref)
    with the experiment of config= and set= ([sheet], [camera], [bias], ...)."""
    if pairing not in _PAIRING:
        raise InputError("ensemble: pairing must be ab, consecutive or time-resolved, got %r"
                         % (pairing,))
    options = dict(options)
    options.pop("ensemble", None)
    exp, params, mask = _piv_setup(windows, overlap, options, "ensemble")
    words, tmp = _pairs_words(pairs)
    hook = _ProgressHook(progress) if progress else None
    prog = hook.ptr() if hook else None
    argv = (ctypes.c_char_p * len(words))(*words)
    pl = ctypes.POINTER(_lib.Pairs)()
    pv = ctypes.c_void_p()
    ia, ib = ctypes.POINTER(_lib.Image)(), ctypes.POINTER(_lib.Image)()
    bga, bgb = ctypes.POINTER(_lib.Image)(), ctypes.POINTER(_lib.Image)()
    keep = mfree = None
    try:
        _check(lib.rpiv_pairs_from_args(len(words), argv, _PAIRING[pairing], ctypes.byref(pl)))
        n = pl.contents.n
        _check(lib.rpiv_pairs_load(pl, 0, ctypes.byref(ia), ctypes.byref(ib)))
        w, h = ia.contents.w, ia.contents.h
        lib.rpiv_image_free(ia)
        lib.rpiv_image_free(ib)
        ia = ib = None
        keep, mptr, mfree = _mask_image(exp, params, mask)
        bg = _BACKGROUND.get(_config_text(exp).get(("piv", "background"), "none"), 0)
        if bg:
            st = lib.rpiv_series_background(pl, bg, prog, ctypes.byref(bga), ctypes.byref(bgb))
            if hook:
                hook.reraise()
            _check(st)
        pv = _new_plan(params, w, h, mptr)
        if bg:
            _check(lib.rpiv_piv_set_background(pv, bga, bgb))
        f = ctypes.POINTER(_lib.Field)()
        st = lib.rpiv_series_ensemble(pv, pl, prog, ctypes.byref(f))
        if hook:
            hook.reraise()
        _check(st)
        if sheet_bias:
            st = lib.rpiv_experiment_check(exp.ptr)
            if not st:
                st = lib.rpiv_config_sheet_bias(exp.ptr, f, n, lib.rpiv_piv_threads(pv), prog)
            if hook:
                hook.reraise()
            if st:
                lib.rpiv_field_free(f)
                _check(st)
        files = []
        for k in range(n):
            src = pl.contents.pair[k]
            files += [os.fsdecode(src.path_a), os.fsdecode(src.path_b) if src.path_b else ""]
        attrs = _base_attrs(exp, pv, files, "ensemble")
        attrs["pairs"] = int(n)
        return _take_field(f, attrs)
    finally:
        lib.rpiv_piv_free(pv)
        lib.rpiv_image_free(bga)
        lib.rpiv_image_free(bgb)
        if mfree:
            lib.rpiv_image_free(mfree)
        if pl:
            lib.rpiv_pairs_free(pl)
        if tmp:
            os.unlink(tmp)
        del keep


# ---- files -------------------------------------------------------------------------------------

def load(path):
    """A vector field file as a Dataset in pivpy's layout: .txt through rpiv's reader (rpiv's
    own files and any x y u v [flag] columns), .nc through xarray (this layout, or the older
    rpiv layout with dims (t, y, x) and `flag`, converted)."""
    p = _path(path, "load")
    ext = os.path.splitext(os.fsdecode(p))[1].lower()
    if ext == ".nc":
        if not os.path.exists(p):
            raise FileError("%s: cannot open: no such file" % os.fsdecode(p), EIO)
        try:
            return load_nc(os.fsdecode(p))
        except (ValueError, KeyError) as exc:
            raise InputError("%s: %s" % (os.fsdecode(p), exc)) from None
        except OSError as exc:
            raise FileError("%s: %s" % (os.fsdecode(p), exc), EIO) from None
    if ext not in (".txt", ".dat", ".csv", ""):
        raise InputError("load: %s: the extension must be .txt or .nc" % os.fsdecode(p))
    f = ctypes.POINTER(_lib.Field)()
    _check(lib.rpiv_field_load_txt(p, ctypes.byref(f)))
    return _take_field(f, {"rpiv_version": __version__, "files": [],
                           "source_file": os.fsdecode(p)})


# ---- synthetic images ------------------------------------------------------------------------

Synth = collections.namedtuple("Synth", "a b truth info")


def synth(index=0, config=None, set=None, piv=None, **keys):
    """Synthetic pair `index` (0-based; `rpiv synth`'s pair_00001 is index 0) of the model of
    docs/model.md, and its ground truth on the final pass grid of the [piv] section.

    **keys are [synth] keys (width_px, height_px, seed, flow, dt_s, bits, ...); config = an INI
    file; set = {"section.key": value} for any other key; piv = {[piv] key: value} for the grid
    of the truth. Returns Synth(a, b, truth, info): float32 frames (grey levels), the truth as
    a Dataset (u, v in pix/dt; flag 2 where there is no fluid) and the generator's figures."""
    if not isinstance(index, (int, np.integer)) or isinstance(index, bool) or index < 0:
        raise InputError("synth: index must be an integer >= 0, got %r" % (index,))
    exp = _Experiment(config)
    exp.apply(["synth"], keys, set, "synth")
    for k, v in (piv or {}).items():
        if k == "windows":
            v = _windows_text(v)
        exp.set_any(["piv"], k, v, "synth")
    _check(lib.rpiv_experiment_check(exp.ptr))
    s = ctypes.c_void_p()
    pv = ctypes.c_void_p()
    ia, ib = ctypes.POINTER(_lib.Image)(), ctypes.POINTER(_lib.Image)()
    g = ctypes.POINTER(_lib.Field)()
    try:
        _check(lib.rpiv_config_synth_new(exp.ptr, None, ctypes.byref(s)))
        info = _lib.SynthInfo()
        lib.rpiv_synth_get_info(s, ctypes.byref(info))
        w, h = info.width_px, info.height_px
        _check(lib.rpiv_image_new(w, h, ctypes.byref(ia)))
        _check(lib.rpiv_image_new(w, h, ctypes.byref(ib)))
        _check(lib.rpiv_synth_pair(s, int(index), ia, ib))
        a = np.ctypeslib.as_array(ia.contents.px, shape=(h, w)).copy()
        b = np.ctypeslib.as_array(ib.contents.px, shape=(h, w)).copy()
        params = lib.rpiv_experiment_piv(exp.ptr)
        pv = _new_plan(params, w, h, None)
        _check(lib.rpiv_piv_grid(pv, lib.rpiv_piv_npass(pv) - 1, ctypes.byref(g)))
        lib.rpiv_synth_truth(s, g)
        attrs = {"rpiv_version": __version__, "mode": "synth ground truth", "files": [],
                 "synth_index": int(index)}
        attrs.update(_piv_params_attrs(exp, None))
        text = _config_text(exp)
        attrs.update({"synth_" + k: v for (sec, k), v in text.items() if sec == "synth"})
        truth = field_to_dataset(g.contents, attrs, physical=False)
        figures = {k: getattr(info, k) for k in ("width_px", "height_px", "pixel_m",
                                                  "star_per_px", "x0_star", "y0_star",
                                                  "nparticles", "bulk_px", "de_focus_px",
                                                  "sigma_focus_px")}
        figures["region"] = tuple(info.region)
        return Synth(a, b, truth, figures)
    finally:
        lib.rpiv_field_free(g)
        lib.rpiv_piv_free(pv)
        lib.rpiv_image_free(ia)
        lib.rpiv_image_free(ib)
        lib.rpiv_synth_free(s)


# ---- optics ------------------------------------------------------------------------------------

def raytrace(xstar, dz_star=0.005, smooth_star=0.0, threads=0, config=None, set=None,
             progress=None, **keys):
    """The light sheet traced through the prism (as `rpiv raytrace`): the fluence rate at the
    stations xstar (x*, any finite values) on bins of dz_star over z* in [0, 1].

    **keys are [laser] and [prism] keys (or 'section.key' through set=). Returns a Dataset
    with `intensity` (x_star, z_star) in units of Ig / h and `intensity_norm` (each station
    divided by its maximum), the power balance as attributes."""
    import xarray as xr

    exp = _Experiment(config)
    exp.apply(["laser", "prism", "channel"], keys, set, "raytrace")
    xs = np.atleast_1d(np.asarray(xstar, dtype=np.float64))
    if xs.ndim != 1 or xs.size < 1 or not np.isfinite(xs).all():
        raise InputError("raytrace: xstar must be finite numbers, got %r" % (xstar,))
    xs = np.ascontiguousarray(xs)
    opts = _lib.OpticsOpts(float(dz_star), float(smooth_star), int(threads))
    hook = _ProgressHook(progress) if progress else None
    r = ctypes.POINTER(_lib.OpticsResult)()
    try:
        st = lib.rpiv_config_raytrace(exp.ptr, xs.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                                      xs.size, ctypes.byref(opts), hook.ptr() if hook else None,
                                      ctypes.byref(r))
        if hook:
            hook.reraise()
        _check(st)
        res = r.contents
        nx, nz = res.nx, res.nz
        x = np.ctypeslib.as_array(res.xstar, shape=(nx,)).copy()
        z = np.ctypeslib.as_array(res.zstar, shape=(nz,)).copy()
        inten = np.ctypeslib.as_array(res.inten, shape=(nx, nz)).copy()
        stats = {k: getattr(res.stats, k) for k, _ in _lib.OpticsStats._fields_}
    finally:
        if r:
            lib.rpiv_optics_result_free(r)
    peak = inten.max(axis=1, keepdims=True)
    norm = np.divide(inten, peak, out=np.zeros_like(inten), where=peak > 0)
    attrs = {"rpiv_version": __version__, "dz_star": float(dz_star),
             "smooth_star": float(smooth_star)}
    attrs.update({"power_" + k: v for k, v in stats.items()})
    return xr.Dataset(
        {"intensity": (("x_star", "z_star"), inten,
                       {"units": "Ig/h", "long_name": "fluence rate of the sheet"}),
         "intensity_norm": (("x_star", "z_star"), norm,
                            {"units": "1", "long_name": "I0*(z*): each station over its maximum"})},
        coords={"x_star": ("x_star", x, {"units": "h", "long_name": "station x*"}),
                "z_star": ("z_star", z, {"units": "h", "long_name": "height z* (bin centre)"})},
        attrs=attrs)


from . import ccm  # noqa: E402  (uses the names above)
