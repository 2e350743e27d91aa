"""Baselines on the shared Gaussian core (`3dgs`, `gs3`) and an adapter for official implementations
(`olatbench.methods.baselines.external`); see docs/baselines.md."""
