"""Runs at the start of every Python process of a nrhints-official job with device=cpu (this folder
is first on its PYTHONPATH): a device move under no_grad drops the autograd graph also on the CPU,
as the GPU copy does (olatbench.methods.official.cpu_standins.device_copy)."""

from olatbench.methods.official.cpu_standins.device_copy import install

install()
