"""Baselines on the shared Gaussian core (`3dgs`, `gs3`); see docs/baselines.md. The authors' own
code runs as ``*-official`` methods (`olatbench.methods.official`, docs/official.md)."""
