"""olatbench.reports."""
