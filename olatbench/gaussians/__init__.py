"""olatbench.gaussians."""
