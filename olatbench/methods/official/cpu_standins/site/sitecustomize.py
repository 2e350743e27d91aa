"""Runs at the start of every Python process of an official job with device=cpu (this folder is
first on its PYTHONPATH): installs olatbench's device shim, so CUDA requests of the authors' code
are served by the CPU."""

from olatbench.methods.official.cpu_standins.device import install

install()
