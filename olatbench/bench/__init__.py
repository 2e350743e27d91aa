"""olatbench.bench."""
