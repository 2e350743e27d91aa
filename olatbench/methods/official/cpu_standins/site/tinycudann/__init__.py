"""Stand-in for tinycudann in an official job with device=cpu
(olatbench.methods.official.cpu_standins.tcnn)."""

from olatbench.methods.official.cpu_standins.tcnn import Encoding, Network

__all__ = ["Encoding", "Network"]
