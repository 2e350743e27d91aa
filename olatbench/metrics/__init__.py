"""olatbench.metrics."""
