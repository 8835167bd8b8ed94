# SPDX-License-Identifier: GPL-3.0-or-later
"""The cross-correlation model (CCM) of the paper: what an R-PIV window measures."""
import collections
import ctypes
import math

from . import _Experiment, _check, _lib, lib, InputError

Prediction = collections.namedtuple(
    "Prediction", "u_star u_star_sub dx_px dx_sub_px dy_px value scale_px")


def predict(xstar, ystar=0.5, zop_star=-1.0, dt_s=0.0, config=None, set=None, **keys):
    """The displacement Eq. "statform" predicts for the R-PIV window at section x* (as the
    integral value of `rpiv ccm convergence`): the sheet of [sheet] at xstar, the duct's
    U*(z*) at y* = ystar, the object plane zop_star (< 0: [camera]'s), dt_s (<= 0: [synth]
    dt_s). **keys are keys of [camera], [particles], [channel], [sheet] (first that has it);
    set = {"section.key": value}. Returns Prediction: U* of the continuous peak and of the
    sub-pixel estimator, the peak in px, R at the peak and the px per unit U*."""
    for name, v in (("xstar", xstar), ("ystar", ystar), ("zop_star", zop_star), ("dt_s", dt_s)):
        try:
            ok = not isinstance(v, bool) and math.isfinite(float(v))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise InputError("ccm.predict: %s must be a finite number, got %r" % (name, v))
    exp = _Experiment(config)
    exp.apply(["camera", "particles", "channel", "sheet"], keys, set, "ccm.predict")
    pk = _lib.CcmPeak()
    scale = ctypes.c_double()
    _check(lib.rpiv_config_ccm_predict(exp.ptr, float(dt_s), float(xstar), float(ystar),
                                       float(zop_star), ctypes.byref(pk), ctypes.byref(scale)))
    s = scale.value
    return Prediction(pk.dx / s, pk.dx_sub / s, pk.dx, pk.dx_sub, pk.dy, pk.value, s)
