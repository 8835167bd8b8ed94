# SPDX-License-Identifier: GPL-3.0-or-later
"""Shared fixtures: the rpiv program (RPIV_BIN, set by CTest; else build/rpiv) and a small
synthetic series made by `rpiv synth` once per session."""
import os
import subprocess

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))


def rpiv_bin():
    b = os.environ.get("RPIV_BIN") or os.path.join(ROOT, "build", "rpiv")
    if not os.path.exists(b):
        pytest.fail("the rpiv program is not built (%s): run `make python` first" % b)
    return b


def run_cli(*args, cwd=None):
    r = subprocess.run([rpiv_bin(), *map(str, args)], cwd=cwd, capture_output=True, text=True)
    assert r.returncode == 0, "rpiv %s: exit %d: %s" % (" ".join(map(str, args)),
                                                        r.returncode, r.stderr)
    return r


@pytest.fixture(scope="session")
def series(tmp_path_factory):
    """Three synthetic pairs (320 x 256 px, a Lamb-Oseen vortex) written by `rpiv synth`."""
    d = tmp_path_factory.mktemp("synth")
    run_cli("synth", "-q", "--size", "320x256", "--flow", "oseen:4,40", "--pairs", "3",
            "--seed", "7", "--out", d)
    return d
