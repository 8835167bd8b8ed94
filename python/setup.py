# SPDX-License-Identifier: GPL-3.0-or-later
# The rpiv Python package (ctypes over librpiv). No pyproject.toml on purpose: without one, pip
# builds with the setuptools already installed (python3-setuptools) and needs no network.
# `make python` first copies build/librpiv.so into rpiv/, which is installed with the package.
#   /usr/bin/python3 -m venv --system-site-packages VENV && VENV/bin/pip install ./python
from setuptools import setup

setup(
    name="rpiv",
    version="0.1.0",
    description="Particle image velocimetry over librpiv: numpy in, xarray out",
    license="GPL-3.0-or-later",
    packages=["rpiv"],
    package_data={"rpiv": ["librpiv.so"]},
    python_requires=">=3.9",
    install_requires=["numpy", "xarray"],
    zip_safe=False,
)
