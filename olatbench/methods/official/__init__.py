"""Official implementations (the authors' code, run in its own environment) as methods of the
runner.

Torch-free: `code` (how to run one: data format, commands, renders), `specs` (the known ones and
their `MethodSpec`\\ s, pinned to a repository and commit), `settings` (where the code lives and how
it is launched: ``--code`` options > ``olatbench.toml`` > environment variables), `convert` (scene
in, renders back to frame ids), `process` (one command, logged, with timeout and interruption),
`runner` (one scene end to end), `doctor` (checks of the configured checkouts). The runner's job for
them is `olatbench.bench.official`; docs/official.md.
"""
