# SPDX-License-Identifier: GPL-3.0-or-later
"""ctypes declarations of the parts of librpiv the package calls, and the library's loading.

The structures mirrored here are the plain-data ones of the public headers (include/rpiv/*.h):
rpiv_image, rpiv_field, rpiv_pairs, rpiv_synth_info, rpiv_ccm_peak, rpiv_optics_opts and the
leading members of rpiv_optics_result. The experiment (every [section] key) stays opaque: it is
made on the heap by rpiv_experiment_new and set key by key with rpiv_config_set, so that the
package never depends on its layout. ctypes releases the GIL for the length of every call.
"""
import ctypes
import ctypes.util
import os

c_int, c_double, c_size_t, c_char_p, c_void_p = (
    ctypes.c_int, ctypes.c_double, ctypes.c_size_t, ctypes.c_char_p, ctypes.c_void_p)
P = ctypes.POINTER


class Image(ctypes.Structure):
    _fields_ = [("w", c_int), ("h", c_int), ("bits", c_int), ("px", P(ctypes.c_float))]


QUANTITY_NAME_MAX = 32  # RPIV_QUANTITY_NAME_MAX


class Quantity(ctypes.Structure):  # rpiv_quantity: an extra per-vector quantity
    _fields_ = [("name", ctypes.c_char * QUANTITY_NAME_MAX), ("unit", c_int),
                ("data", P(ctypes.c_float))]


class Field(ctypes.Structure):
    _fields_ = [("nx", c_int), ("ny", c_int), ("x0", c_double), ("y0", c_double),
                ("dx", c_double), ("dy", c_double), ("u", P(ctypes.c_float)),
                ("v", P(ctypes.c_float)), ("flag", P(ctypes.c_ubyte)),
                ("peak_ratio", P(ctypes.c_float)), ("corr", P(ctypes.c_float)),
                ("scale_mm_per_px", c_double), ("dt_s", c_double),
                ("nq", c_size_t), ("q", P(Quantity)), ("y_up", c_int)]


class PairSrc(ctypes.Structure):
    _fields_ = [("path_a", c_char_p), ("path_b", c_char_p)]


class Pairs(ctypes.Structure):
    _fields_ = [("n", c_size_t), ("pair", P(PairSrc))]


class Flow(ctypes.Structure):
    _fields_ = [("kind", c_int), ("a", c_double), ("b", c_double), ("cx", c_double),
                ("cy", c_double), ("height_px", c_double), ("y0_star", c_double),
                ("ystar_per_px", c_double)]


class SynthInfo(ctypes.Structure):
    _fields_ = [("width_px", c_int), ("height_px", c_int), ("pixel_m", c_double),
                ("star_per_px", c_double), ("x0_star", c_double), ("y0_star", c_double),
                ("region", c_double * 4), ("nparticles", c_size_t), ("bulk_px", c_double),
                ("de_focus_px", c_double), ("sigma_focus_px", c_double), ("flow", Flow)]


class CcmPeak(ctypes.Structure):
    _fields_ = [("dx", c_double), ("dy", c_double), ("dx_sub", c_double),
                ("dy_sub", c_double), ("mx", c_int), ("my", c_int), ("value", c_double)]


class OpticsOpts(ctypes.Structure):
    _fields_ = [("dz_star", c_double), ("smooth_star", c_double), ("threads", c_int)]


class OpticsStats(ctypes.Structure):
    _fields_ = [("incident", c_double), ("refl_face", c_double), ("refl_floor", c_double),
                ("tir", c_double), ("missed", c_double), ("transmitted", c_double),
                ("n_rays", ctypes.c_long), ("n_tir", ctypes.c_long),
                ("n_missed", ctypes.c_long), ("n_transmitted", ctypes.c_long)]


class OpticsResult(ctypes.Structure):  # the leading members only: read through a pointer
    _fields_ = [("nx", c_size_t), ("nz", c_size_t), ("xstar", P(c_double)),
                ("zstar", P(c_double)), ("inten", P(c_double)), ("dz_star", c_double),
                ("smooth_star", c_double), ("stats", OpticsStats)]


PROGRESS_FN = ctypes.CFUNCTYPE(c_int, c_void_p, c_size_t, c_size_t)


class Progress(ctypes.Structure):
    _fields_ = [("fn", PROGRESS_FN), ("user", c_void_p)]


def _candidates():
    env = os.environ.get("RPIV_LIB")
    if env:
        yield env
    here = os.path.dirname(os.path.abspath(__file__))
    yield os.path.join(here, "librpiv.so")  # the copy `make python` / pip install puts here
    yield os.path.join(here, "..", "..", "build", "librpiv.so")  # the source tree's build
    found = ctypes.util.find_library("rpiv")  # an installed library
    if found:
        yield found


def _load():
    tried = []
    for path in _candidates():
        if os.path.sep in path and not os.path.exists(path):
            tried.append(path + " (missing)")
            continue
        try:
            return ctypes.CDLL(path)
        except OSError as exc:
            tried.append("%s (%s)" % (path, exc))
    raise ImportError("rpiv: cannot find librpiv.so; build it with `make python` or set RPIV_LIB "
                      "to its path. Tried: " + "; ".join(tried or ["nothing"]))


lib = _load()

_SIGS = {
    "rpiv_init": (None, []),
    "rpiv_errmsg": (c_char_p, []),
    "rpiv_strerror": (c_char_p, [c_int]),
    "rpiv_errclear": (None, []),
    "rpiv_version_string": (c_char_p, []),
    "rpiv_image_new": (c_int, [c_int, c_int, P(P(Image))]),
    "rpiv_image_free": (None, [P(Image)]),
    "rpiv_image_load": (c_int, [c_char_p, c_int, P(P(Image)), P(c_int)]),
    "rpiv_image_count_pages": (c_int, [c_char_p, P(c_int)]),
    "rpiv_field_free": (None, [P(Field)]),
    "rpiv_field_load_txt": (c_int, [c_char_p, P(P(Field))]),
    "rpiv_unit_name": (c_char_p, [c_int, c_int]),
    "rpiv_unit_factor": (c_double, [P(Field), c_int]),
    "rpiv_experiment_new": (c_int, [P(c_void_p)]),
    "rpiv_experiment_free": (None, [c_void_p]),
    "rpiv_experiment_piv": (c_void_p, [c_void_p]),
    "rpiv_experiment_check": (c_int, [c_void_p]),
    "rpiv_config_load": (c_int, [c_char_p, c_void_p]),
    "rpiv_config_set": (c_int, [c_void_p, c_char_p, c_char_p, c_char_p, c_char_p]),
    "rpiv_piv_params_check": (c_int, [c_void_p]),
    "rpiv_piv_new": (c_int, [c_void_p, c_int, c_int, P(Image), P(c_void_p)]),
    "rpiv_piv_free": (None, [c_void_p]),
    "rpiv_piv_npass": (c_int, [c_void_p]),
    "rpiv_piv_threads": (c_int, [c_void_p]),
    "rpiv_piv_grid": (c_int, [c_void_p, c_int, P(P(Field))]),
    "rpiv_piv_set_background": (c_int, [c_void_p, P(Image), P(Image)]),
    "rpiv_piv_run": (c_int, [c_void_p, P(Image), P(Image), P(P(Field))]),
    "rpiv_pairs_from_args": (c_int, [c_int, P(c_char_p), c_int, P(P(Pairs))]),
    "rpiv_pairs_free": (None, [P(Pairs)]),
    "rpiv_pairs_load": (c_int, [P(Pairs), c_size_t, P(P(Image)), P(P(Image))]),
    "rpiv_series_background": (c_int, [P(Pairs), c_int, P(Progress), P(P(Image)),
                                       P(P(Image))]),
    "rpiv_series_ensemble": (c_int, [c_void_p, P(Pairs), P(Progress), P(P(Field))]),
    "rpiv_config_synth_new": (c_int, [c_void_p, c_void_p, P(c_void_p)]),
    "rpiv_synth_free": (None, [c_void_p]),
    "rpiv_synth_get_info": (None, [c_void_p, P(SynthInfo)]),
    "rpiv_synth_pair": (c_int, [c_void_p, ctypes.c_ulong, P(Image), P(Image)]),
    "rpiv_synth_truth": (None, [c_void_p, P(Field)]),
    "rpiv_config_raytrace": (c_int, [c_void_p, P(c_double), c_size_t, P(OpticsOpts),
                                     P(Progress), P(P(OpticsResult))]),
    "rpiv_optics_result_free": (None, [P(OpticsResult)]),
    "rpiv_config_sheet_bias": (c_int, [c_void_p, P(Field), c_size_t, c_int, P(Progress)]),
    "rpiv_config_ccm_predict": (c_int, [c_void_p, c_double, c_double, c_double, c_double,
                                        P(CcmPeak), P(c_double)]),
}

for _name, (_res, _args) in _SIGS.items():
    _f = getattr(lib, _name)
    _f.restype = _res
    _f.argtypes = _args

lib.rpiv_init()
