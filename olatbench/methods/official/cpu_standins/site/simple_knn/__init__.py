"""Stand-in for simple_knn in an official job with device=cpu
(olatbench.methods.official.cpu_standins.knn)."""
